"""The seeds' formulations I and II as an engine of the registry: independent
exact methods, run at the native sweep's own inputs and judged at round-off."""

from __future__ import annotations

from typing import TYPE_CHECKING

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import EXACT

if TYPE_CHECKING:
    from xcheck.kinematics import Kinematics, Solution
    from xcheck.results import ModeResult

__all__ = ["Formulations"]


class Formulations(Engine):
    """Seed 000's formulation I (direct substitution) and II (vector loops)."""

    name = "formulations"
    title = "the seeds' formulations"
    modes = (
        Mode(
            "formulation-I",
            "kinematic",
            EXACT,
            style=dict(color="tab:gray", lw=0, marker="o", ms=3, mfc="none"),
            cost=0.04,
        ),
        Mode("formulation-II", "kinematic", EXACT, style=dict(color="tab:brown", lw=0, marker="x", ms=3), cost=0.04),
    )
    notes = (
        "Formulation I: a four-bar or an offset slider-crank driven at its crank; formulation II: every "
        "mechanism that can be solved two unknowns at a time (dyadic)."
    )

    def run(
        self,
        mode: str,
        kinematics: Kinematics,
        *,
        native: Solution,
        samples: int,
        branch: str | None = None,
    ) -> ModeResult:
        from xcheck.formulations import formulation
        from xcheck.results import ModeResult

        trajectory = formulation(mode)(
            kinematics, native.inputs, native.input_rates, native.input_accelerations, branch=branch
        )
        return ModeResult(mode, kinematics.mechanism.name, True, trajectories=[trajectory])
