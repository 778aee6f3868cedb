"""OpenSim (Simbody inside): the mechanism as an ``osim.Model`` of pin and slider
joints whose loops are closed by point constraints (:mod:`.model`), integrated
in free motion by Simbody's integrators with projection onto the constraints
(:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, ROUND_OFF, Tolerance

__all__ = ["OpenSim"]


_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: the driven coordinates prescribed by their laws (Simbody's prescribed "
    "motion), Runge-Kutta-Merson at 4, 8, 16 fixed steps per sample with projection onto the constraints; "
    "observed order 4.0 in every quantity over models/ (fourbar positions 2.1e-8, 1.4e-9, 8.7e-11 m, "
    "accelerations 4.6e-7 .. 1.9e-9 relative; task-2-1 7.9e-7 .. 3.4e-9 m), loops closed to 3e-7 m or less"
    + CONVERGENCE_NOTE,
)


#: Shown as failed runs on the double four-bar; stated for its reproducer.
_SINGULAR_PASS = Finding(
    "Simbody's Merson runs break down at a double four-bar's third or fourth singular pass",
    "On the IFToMM double four-bar (A02, cut at the second and third cranks' tips by PointConstraints) "
    "Runge-Kutta-Merson at fixed steps of 1, 0.5, 0.25 ms with projection onto the constraints keeps the "
    "energy to 1.4e-6, 2.4e-4, 2.1e-2 J until it breaks down at the third or fourth singular pass "
    "(2.66, 3.18, 3.17 s: the energy off by joules, or non-finite; opensim 4.6). On xcheck's model of A02 "
    "its fixed-step runs turn non-finite at 6.4, 3.75, 3.2 s and its error-controlled ones leave the "
    "parallelogram branch at 2.7 s, where xcheck's native reference, Exudyn and DART pass every singular "
    "pass of the 10 s",
    ("position", "angle"),
    kinds=(),
    closed_loops=True,
    reproducer="reproducers/opensim_singular_pass.py",
)

#: Worked around (xcheck names OpenSim's components within its rules); stated for its reproducer.
_REFUSED_COMPONENT = Finding(
    "OpenSim keeps a component its Model refuses, and the process crashes at exit",
    "Model.addForce raises on a PointToPointSpring named 'spring 1' (a space: OpenSim refuses it) but keeps "
    "the spring: initSystem raises on it again, and the process dies with a segmentation fault when it ends "
    "(opensim 4.6; named 'spring_1', the model assembles and the process ends normally). xcheck's models "
    "of the elliptic trammel ('slide A') and of a spring's default name crashed so until xcheck named "
    "OpenSim's components within its rules",
    ("position",),
    kinds=(),
    reproducer="reproducers/opensim_refused_component.py",
)

#: Worked around (the kinematic oracle cuts its loops as PointOnLineConstraints); stated for its reproducer.
_REDUNDANT_ROW = Finding(
    "OpenSim's assembler leaves a loop closed by a PointConstraint open when a coordinate is prescribed",
    "A planar four-bar closed by a PointConstraint (its z row redundant), its crank's coordinate prescribed "
    "as 45 deg + t: Model.assemble at t = 0.1, 0.3, 0.5, 1.0 s returns without an error and leaves the loop "
    "open by 9.9e-3, 2.3e-2, 2.8e-2, 5.7e-2 m; closed by a PointOnLineConstraint along z (the same two planar "
    "rows) it closes to 1e-11 m (opensim 4.6). Silently wrong: xcheck's kinematic oracle cuts its loops as "
    "PointOnLineConstraints",
    ("position", "angle"),
    kinds=(),
    closed_loops=True,
    reproducer="reproducers/opensim_assembler_redundant_row.py",
)

#: Worked around (the kinematic oracle and the inverse dynamics push the drivers by their efforts);
#: stated for its reproducer.
_PRESCRIBED_ROUND_OFF = Finding(
    "Simbody solves a prescribed motion's constraint forces with the round-off of its rate",
    "Simbody forms G M^-1 G^T column by column as the constraints' velocity errors at M^-1 G^T less their "
    "bias, and a prescribed motion's bias is its rate: each entry of its row (M^-1 is 3e-10 per kg m^2 for "
    "a 10 t bar 1 km long) is added to the rate and taken off again, keeping only the bits above a unit in "
    "the rate's last place. The multipliers are solved with that error, and the prescribed coordinate's "
    "acceleration misses its law by up to the multipliers times ulp(rate) / 2, a product of SI values: "
    "heavy, large mechanisms lose the most digits. Such a bar pinned at one end, prescribed to turn "
    "uniformly at 1 or 2 rad/s under gravity, has 1.07e-9 rad/s^2 where 0 is exact (round-off 3e-18; "
    "1.9e-7 at 1000 t; exact at 0 rad/s, and for 1 kg and 1 m; opensim 4.6). With its crank prescribed, "
    "xcheck's crank-rocker at 1 km (tests/data/km-fourbar.toml, bodies of 3 to 9 t, crank at 2 rad/s) had "
    "its accelerations 4.6e-8 of the largest off and its reactions 4.8e-8; solving again with the first "
    "solve's torque applied by an actuator left 2.3e-10, the loops' multipliers reaching the same row. "
    "xcheck's kinematic oracle and inverse dynamics realise the accelerations with the drivers free, each "
    "pushed by the effort that gives its law's acceleration: 7e-13 and 2.8e-13 there. OpenSim's driven "
    "dynamics prescribes its drivers, and its inputs are compared as realised, which hides the miss",
    ("acceleration", "alpha"),
    kinds=(),
    reproducer="reproducers/opensim_prescribed_motion_round_off.py",
)


#: Worked around (where xcheck's continuation walks, it assembles from default values at its
#: guess); stated for its reproducer.
_OTHER_BRANCH = Finding(
    "OpenSim's assembler moves an assembled slider-crank to its other branch",
    "An offset slider-crank near its dead centre (crank 418.6 m, rod 656.9 m, its slider's line 238.3 m "
    "above the crank's pin), its crank prescribed, its other coordinates set to the exact pose (closed to "
    "round-off): Model.assemble leaves it there where the model's default coordinate values are that pose, "
    "but where they are the pose at crank 2.494 rad it moves the slider to the other branch at crank 4.7702 "
    "and 4.7802 rad (60.6 and 71.1 m away, the loop closed there too; opensim 4.6). xcheck's kinematic "
    "oracle (its model built at the reference inputs) left the branch so on "
    "tests/data/fuzz-slider-crank-near-dead-centre.toml; where an assembly leaves the branch, it walks "
    "there by xcheck's continuation and assembles with the default values at its guess",
    ("position", "angle"),
    kinds=(),
    closed_loops=True,
    reproducer="reproducers/opensim_assembler_other_branch.py",
)


class OpenSim(Engine):
    """OpenSim (Simbody): a kinematic oracle through its assembler, driven dynamics with the
    drivers prescribed, and free motion with error-controlled or fixed-step integration and
    projection onto the constraints."""

    name = "opensim"
    title = "OpenSim"
    requires = ("opensim",)
    implementation = "xcheck.engines.opensim.modes"
    distributions = ("opensim",)
    install = "pip install xcheck[opensim]"
    modes = (
        Mode(
            "opensim-kinematic", "kinematic", ROUND_OFF, style=dict(color="tab:olive", lw=0, marker="x", ms=5), cost=2.6
        ),
        Mode(
            "opensim-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 4.0, "angle": 4.0, "velocity": 4.0, "omega": 4.0, "acceleration": 4.0, "alpha": 4.0},
            style=dict(color="tab:olive", lw=1, ls="-"),
        ),
        Mode("opensim-free", "free", FREE_MOTION, style=dict(color="tab:olive", lw=1, ls="-"), cost=0.23),
    )
    force_tolerance = 1e-12
    force_basis = (
        "Simbody's constrained accelerations at the native states, the drivers prescribed: round-off "
        "(measured at most 4.1e-15 of the largest reaction or effort on fourbar and fourbar-dynamics)"
    )
    findings = (_SINGULAR_PASS, _REFUSED_COMPONENT, _REDUNDANT_ROW, _PRESCRIBED_ROUND_OFF, _OTHER_BRANCH)
    color = "tab:olive"
    notes = (
        "Revolute and prismatic joints: an OpenSim Model of PinJoint and SliderJoint (xcheck's body frames as "
        "OpenSim's bodies, every coordinate 0 at the start) with each loop cut at a revolute closed by a "
        "PointConstraint (Simbody's ball constraint; its z row is redundant and accepted); gravity and linear "
        "springs without damping (PointToPointSpring). Kinematic oracle: at each input the driven coordinates "
        "prescribed (one driver by time itself, at the time of its input's value, its speeds scaled by the "
        "input's rate; several by the quadratic in time with each input's value, rate and acceleration), the "
        "model assembled "
        "by OpenSim's assembler from the neighbouring input's coordinates, its loops cut as PointOnLineConstraints "
        "(the planar pin's two rows: with a PointConstraint's redundant row the assembler leaves the loops open), "
        "its speeds projected by Simbody and its accelerations realised with the drivers free, each pushed by an "
        "actuator with the effort that gives its law's acceleration (Simbody's prescribed motion solves its "
        "constraint forces with the round-off of its rate); reactions and efforts (revolute joints) "
        "from Simbody's constrained accelerations there. Driven: each driven coordinate "
        "prescribed by its law (PolynomialFunction, Sine), integrated by fixed-step Runge-Kutta-Merson; "
        "springs and loads left out there (they change the drivers' efforts, not the motion). Free motion: "
        "integrated by Simbody through OpenSim's Manager, which projects the state onto the constraints after "
        "each step: Runge-Kutta-Merson and explicit Euler at fixed steps, and Runge-Kutta-Merson with its error "
        "control (accuracy 1e-5 at a 1 ms step, divided by 16 at each halving). Not converted (not applicable): "
        "pin-in-slot joints, loops cut at a prismatic joint, dampers, rotational springs and loads (free)."
    )
