"""One convergence study for every engine: the time-step ladder, run and judged
by one rule whichever engine produced the runs.

A dynamic or free mode is judged by how its error falls as its time step falls.
The ladder's policy lives here, once: which runs make a ladder (the engine's
:class:`Series`, each at halving time steps), which outputs are compared, when
a run has come apart, left the branch or only fallen out of phase, which
errors count for the order and which are round-off, the observed order (one
name, ``order``, computed once), the energy and loop-closure columns, whether
a ladder converges, and which of an engine's stated :class:`Finding` s apply.
An engine supplies only what only it knows: its series, what every run shares
(its model, built once: ``prepare``) and one run at a given series and step
(``run_once``), returning a :class:`Run`: a trajectory, or a stated failure.

:func:`run_rungs` is the one place that runs a ladder's rungs (independent
calls). :func:`free_study` makes a free mode's
:class:`~xcheck.results.ModeResult`, against the native reference;
:class:`DrivenLadder` a driven mode's, against the native solution at the
inputs each run realised, and refines it a rung at a time.
"""

from ._core import (
    APART,
    FAILURE,
    FORCE_QUANTITIES,
    ORDER_MARGIN,
    REACTIONS,
    Finding,
    Run,
    Rung,
    Series,
    applicable_findings,
    came_apart,
    conservative,
    one_line,
    run_rungs,
)
from ._driven import DRIVEN_SAMPLES, DYNAMIC_COLUMNS, DrivenLadder, DrivenProblem, driven_floor, off_branch
from ._free import (
    COMPARED,
    FREE_ROUND_OFF,
    FREE_STEPS,
    LADDER_COLUMNS,
    FreeProblem,
    free_errors,
    free_floor,
    free_study,
    left_branch,
    out_of_phase,
    path_distance,
    point_gaps,
)
from ._study import STUDY_COLUMNS, convergence_study, empty_study, ladder_result, ladder_verdicts, observed_order

__all__ = [
    "APART",
    "COMPARED",
    "FAILURE",
    "FORCE_QUANTITIES",
    "DRIVEN_SAMPLES",
    "DYNAMIC_COLUMNS",
    "FREE_ROUND_OFF",
    "FREE_STEPS",
    "LADDER_COLUMNS",
    "ORDER_MARGIN",
    "REACTIONS",
    "STUDY_COLUMNS",
    "DrivenLadder",
    "DrivenProblem",
    "Finding",
    "FreeProblem",
    "Run",
    "Rung",
    "Series",
    "applicable_findings",
    "came_apart",
    "conservative",
    "convergence_study",
    "driven_floor",
    "empty_study",
    "free_errors",
    "free_floor",
    "free_study",
    "ladder_result",
    "ladder_verdicts",
    "left_branch",
    "observed_order",
    "off_branch",
    "one_line",
    "out_of_phase",
    "path_distance",
    "point_gaps",
    "run_rungs",
]
