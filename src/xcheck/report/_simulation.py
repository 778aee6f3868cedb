"""The report of a free-motion run: the native reference and each engine's ladder.

Figures: ``drawing`` (the mechanism at release and the paths of its points),
``errors`` (each free mode's best run: position error against time, log
scale, singular passes marked), ``energy`` (the reference's energy balance
and loop closure) and ``work-precision`` (error against CPU time, one line per
engine and setting). SI units throughout.
"""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import engines  # noqa: E402
from ..drawing import Pose, draw_pose, guide_extents  # noqa: E402
from ..ladder import LADDER_COLUMNS, ladder_verdicts, point_gaps  # noqa: E402
from ..runner import versions  # noqa: E402
from ..simulation import SimulationResult  # noqa: E402
from . import _figures  # noqa: E402
from ._evidence import Evidence  # noqa: E402
from ._markdown import _g, _image, _provenance, _table, left_out_markdown  # noqa: E402

__all__ = ["REFERENCE_FIGURES", "figures", "figure_modes", "mode_parts", "markdown"]


def _png(figure, fit: bool = False) -> bytes:
    """The figure as a run report's figures are written (:func:`xcheck.report._figures._png`):
    log axes labelled in plain text, RGB pixels, no metadata but the resolution; laid out
    by ``tight_layout``, and with ``fit`` the figure made the size of what it draws."""
    for ax in figure.axes:
        _figures._plain_log_labels(ax)
    figure.tight_layout()
    return _figures._png(figure, dpi=110, fit=0.1 if fit else None)


def _passes(ax, result: SimulationResult) -> None:
    for t in result.reference.motion.singular_passes:
        ax.axvline(t, color="0.8", lw=0.8, zorder=0)


#: the figures that show the native reference alone: they can be drawn while the free modes run
REFERENCE_FIGURES = ("drawing", "energy")


def figures(result: SimulationResult, keys=None) -> dict[str, bytes]:
    """The report's PNG figures by key (see the module's docstring): those of ``keys``
    (default: all), but a mode's figure where no mode has what it shows."""
    drawers = {"drawing": _drawing, "energy": _energy, "errors": _errors, "work-precision": _work_precision}
    out = {}
    for key in drawers if keys is None else keys:
        with _figures.old_objects_frozen():
            figure = drawers[key](result)
        if figure is not None:
            out[key] = figure
    return out


def _drawing(result: SimulationResult) -> bytes:
    """The mechanism at release and the paths of its points."""
    solution = result.reference.motion.solution()
    mech = result.kinematics.mechanism
    figure, ax = plt.subplots(figsize=(5.5, 4.5))
    for label, owner in mech.point_owners.items():
        if owner != mech.ground.name:
            path = solution.point(label)["position"]
            ax.plot(path[:, 0], path[:, 1], lw=0.8, alpha=0.7)
    # at release: links between the joints, blocks, slots, hatched ground, labels
    draw_pose(ax, Pose.of(solution, 0), guide_extents(solution), scale=1.0)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{mech.name}: at release and the paths of its points", fontsize=9)
    ax.grid(alpha=0.3)
    return _png(figure)


def _energy(result: SimulationResult) -> bytes:
    """The reference's energy balance and loop closure against time."""
    motion = result.reference.motion
    figure, (ax_energy, ax_loop) = plt.subplots(1, 2, figsize=(10, 3.6))
    ax_energy.semilogy(motion.times, np.maximum(np.abs(motion.energy_error), 1e-18), lw=1)
    ax_energy.set_ylabel("|E(t) - E(0) - W(t)| [J]")
    ax_loop.semilogy(motion.times[1:], np.maximum(motion.residual[1:], 1e-18), lw=1)
    ax_loop.set_ylabel("loop closure before each projection [m]")
    for ax in (ax_energy, ax_loop):
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3, which="both")
        _passes(ax, result)
    figure.suptitle(
        f"{result.kinematics.mechanism.name}: the native reference (grey lines: singular positions passed)",
        fontsize=10,
    )
    return _png(figure)


def _errors(result: SimulationResult) -> bytes | None:
    """Each free mode's best run: position error against time (None where no mode ran)."""
    runs = [(m, o) for m, o in result.outcomes.items() if o.ok and o.trajectories]
    if not runs:
        return None
    motion = result.reference.motion
    native = motion.solution()
    figure, ax = plt.subplots(figsize=(7, 4))
    for mode, outcome in runs:
        best = outcome.trajectories[0]
        gap = point_gaps(best, native, motion.times)
        style = dict(engines.mode(mode).style)
        ax.semilogy(
            best.times, np.maximum(gap, 1e-18), label=f"{mode} ({_setting(best)})", color=style.get("color"), lw=1
        )
    _passes(ax, result)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("largest point position error [m]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title(
        f"{result.kinematics.mechanism.name}: each engine's most accurate run against the reference", fontsize=9
    )
    return _png(figure)


def _work_precision(result: SimulationResult) -> bytes | None:
    """Error against CPU time, one line per engine and setting (None where no mode ran)."""
    if not any(o.ok and o.trajectories for o in result.outcomes.values()):
        return None
    figure, ax = plt.subplots(figsize=(10.5, 4.5))
    for mode, outcome in result.outcomes.items():
        summary = outcome.summary
        if summary is None or summary.empty or "cpu_seconds" not in summary:
            continue
        color = engines.mode(mode).style.get("color")
        keys = [k for k in ("setting", "integrator") if k in summary]
        for series, part in summary.groupby(keys, sort=False) if keys else [("", summary)]:
            part = part[part["status"] == "ok"]
            if part.empty:
                continue
            name = " ".join(str(s) for s in (series if isinstance(series, tuple) else (series,)))
            ax.loglog(
                part["cpu_seconds"],
                part["position_error"],
                "o-",
                ms=4,
                lw=1,
                color=color,
                label=f"{mode}: {name}",
                alpha=0.8,
            )
    ax.loglog(
        [result.reference.motion.seconds],
        [max(result.reference.estimate.max(), 1e-18)],
        "k*",
        ms=10,
        label="native reference (its stated error)",
    )
    ax.set_xlabel("CPU time [s]")
    ax.set_ylabel("largest point position error [m]")
    ax.grid(alpha=0.3, which="both")
    # beside the axes: with seven engines' settings a legend inside hides their points
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    ax.set_title(
        f"{result.kinematics.mechanism.name}: work-precision (one line per engine and setting, step falling)",
        fontsize=9,
    )
    return _png(figure, fit=True)  # the legend beside the axes


def _setting(trajectory) -> str:
    settings = trajectory.settings
    parts = [str(settings[k]) for k in ("setting", "integrator") if k in settings]
    if "timestep" in settings:
        parts.append(f"dt = {float(settings['timestep']):.3g} s")
    return ", ".join(parts)


def _reference_section(reference) -> list[str]:
    """The native reference's paragraphs and ladder tables: how it was run and stopped, its
    stated error, and the second method's check."""
    motion = reference.motion
    at = ", ".join(f"{t:.4g}" for t in motion.singular_passes)
    passes = f"Singular positions passed at {at} s." if at else "No singular position passed."
    lines = [
        f"{reference.method}: {reference.basis}. The run kept has a mean step of {motion.step:g} s; stated "
        f"error {_g(float(reference.estimate.max()), 3)} m ({_g(reference.relative, 3)} of the size; "
        f"{'converged' if reference.converged else '**not converged**'}). {passes} "
        f"Loop closure before each projection at most {_g(float(motion.residual.max()), 2)} m; energy balance "
        f"at most {_g(float(np.abs(motion.energy_error).max()), 2)} J.",
        _ladder_table(reference),
    ]
    check = reference.check
    if check is not None:
        other = check.reference
        verdict = {
            True: "within the sum of their stated errors",
            False: "**beyond the sum of their stated errors: one of them is wrong**",
            None: "inconclusive: one of them did not reach its tolerance, so their stated errors bound nothing",
        }[check.consistent]
        lines += [
            f"Checked by {other.method} ({other.basis}; stated error {_g(float(other.estimate.max()), 3)} m, "
            f"{'converged' if other.converged else '**not converged**'}): the two agree to "
            f"{_g(float(check.agreement.max(initial=0.0)), 3)} m ({_g(check.relative, 3)} of the size) over "
            f"{len(check.times)} outputs, {verdict}.",
            _ladder_table(other),
        ]
    return lines


def _ladder_table(reference) -> str:
    """A native ladder as a table: the setting, steps, CPU, difference and the stated error."""
    setting = "local tolerance" if reference.method == "DOP853" else "step [s]"
    rows = [
        [
            _g(e["setting"], 4),
            f"{int(e['steps'])}",
            _g(e["seconds"], 3),
            _g(e["difference"], 3),
            _g(e.get("error", float("nan")), 3),
            "ok" if e.get("status", "ok") == "ok" else e["status"],
        ]
        for e in reference.ladder
    ]
    headers = [setting, "steps", "CPU [s]", "difference from the previous run [m]", "stated error [m]", "status"]
    return _table(headers, rows, "rrrrrl")


def mode_parts(result: SimulationResult, made: dict) -> dict[str, dict]:
    """What the report shows of each free mode of the run (JSON: its section,
    or why it did not run), with ``made``, where it comes from."""
    parts = {}
    for mode, outcome in result.outcomes.items():
        lines = [f"**`{mode}`**" + ("" if outcome.ok else f" — failed: {outcome.reason}")]
        summary = outcome.summary
        if summary is not None and not summary.empty:
            shown = [c for c in LADDER_COLUMNS if c in summary]
            rows = [[_cell(row[c]) for c in shown] for _, row in summary.iterrows()]
            lines.append(_table([c.replace("_", " ") for c in shown], rows))
        if outcome.study is not None and not outcome.study.empty:
            lines.append(
                "Convergence (the position error as the step halves): "
                + "; ".join(f"{series} {verdict}" for series, verdict in ladder_verdicts(outcome.study).items())
                + "."
            )
        parts[mode] = {"section": "\n\n".join(lines), "ran": bool(outcome.ok), "produced": made}
    for mode, reason in result.not_applicable.items():
        parts[mode] = {"not_run": reason, "produced": made}
    return parts


def figure_modes(result: SimulationResult) -> dict[str, list[str]]:
    """The free modes each figure of :func:`figures` shows (by key)."""
    drawn = [m for m, o in result.outcomes.items() if o.ok and o.trajectories]
    timed = [m for m, o in result.outcomes.items() if o.summary is not None and "cpu_seconds" in o.summary]
    return {"drawing": [], "energy": [], "errors": drawn, "work-precision": timed}


def markdown(result: SimulationResult, evidence: Evidence, images: dict[str, str], command: str) -> str:
    """The report's Markdown: ``result``'s reference and the free modes of
    ``evidence`` (the run's, and those kept from earlier runs, marked);
    ``images`` maps figure keys to paths relative to it."""
    mech = result.kinematics.mechanism
    reference = result.reference
    motion = reference.motion
    spec = mech.free_motion
    marks, provenance = _provenance(evidence)
    lines = [
        f"# {mech.name}: {mech.title} — free motion",
        f"Source: {mech.source or '—'}. Released for {motion.times[-1]:g} s"
        + (f" (outputs every {spec.output_step:g} s)" if spec is not None else "")
        + ".",
        provenance,
        mech.notes.strip(),
        f"![the mechanism]({images['drawing']})",
        "## The native reference",
        *_reference_section(reference),
        f"![energy balance and loop closure]({images['energy']})",
        "## Engines in free motion",
    ]
    if "errors" in images:
        lines.append(_image("error against time", images["errors"], marks.get("errors.png", "")))
    if "work-precision" in images:
        lines.append(_image("work-precision", images["work-precision"], marks.get("work-precision.png", "")))
    ran = {m: p for m, p in evidence.modes.items() if "section" in p}
    for mode, part in ran.items():
        head = f"**`{mode}`**"
        section = part["section"]
        lines.append(section.replace(head, head + marks.get(mode, ""), 1) if section.startswith(head) else section)
    for mode, part in evidence.modes.items():
        if "not_run" in part:
            lines.append(f"`{mode}`{marks.get(mode, '')}: not run ({part['not_run']}).")
    if result.left_out:
        lines.append(left_out_markdown(result.left_out))
    if not evidence.modes:
        lines.append("No free-motion mode ran (none registered, or `--engines native`).")
    lines += [
        "## Versions\n\n" + _table(["package", "version"], [[k, v] for k, v in versions().items()]),
        f"Reproduce: `{command}`",
    ]
    return "\n\n".join(line for line in lines if line) + "\n"


def _cell(value) -> str:
    if isinstance(value, float):
        return "—" if not math.isfinite(value) else f"{value:.3g}"
    return str(value)
