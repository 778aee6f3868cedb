# %% [markdown]
# # xcheck from Python: load → sweep → DataFrame → plot → compare
#
# A script in cells (`# %%`: VS Code, Spyder and Jupytext open it as a notebook).
# Every number is SI; the plots use the mechanism file's display units.
# tests/test_api_example.py runs it.

# %%
import xcheck

mech = xcheck.load("fourbar")  # a bundled mechanism by name, or a path to a .toml file
sweep = mech.sweep(samples=91)  # its feasible range; rates from the file's drivers (crank at 1 rad/s)
frame = sweep.to_frame()  # one row per sample and point or body: x_m, vx_m_s, angle_rad, ...
print(frame[(frame.kind == "point") & (frame.name == "C")][["crank_rad", "x_m", "y_m", "vx_m_s", "vy_m_s"]].head())

# %%
sweep.plot().savefig("fourbar-sweep.png")  # a matplotlib Figure: shown inline in a notebook
mech.draw(at=60).savefig("fourbar-at-60.png")

# %%
run = xcheck.run("fourbar", engines="formulations")  # every mode named against the exact solution
print(run.verdict, run.summary.to_string(), sep="\n")  # per mode: verdict, error, tolerance
