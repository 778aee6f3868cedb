"""Drake: the mechanism as a ``MultibodyPlant`` (a tree of revolute and
prismatic joints on the world body) whose loops are closed by ball
constraints, stepped by Drake's discrete SAP solver in free motion
(:mod:`.free`) and driven by PD-controlled joint actuators (:mod:`.dynamic`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, Tolerance

__all__ = ["Drake"]

_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: the driven joints held by SAP's implicit PD controller (Kp = 1e6 M / dt^2, "
    "Kd = Kp dt), 25, 50, 100 steps per sample; observed orders over models/ 1.96-2.00 in positions and "
    "angles (3.2e-7 .. 3.8e-6 m at the finest step: the loops' opening, 1.3e-7 .. 1.4e-6 m, and what it "
    "moves), 1.00-1.03 in rates; the PD's lag behind the law is reported, not judged (order 2, at most "
    "2.3e-7 rad at the finest step); "
    "Drake's accelerations are not compared" + CONVERGENCE_NOTE,
)


#: Worked around in xcheck's model (a body welded to the world holds the ground's cut points).
_BALL_TO_WORLD = Finding(
    "pydrake crashes on a ball constraint to the world body",
    "MultibodyPlant.AddBallConstraint between the world body and a body, either way round, kills the "
    "process with a segmentation fault in the first discrete SAP step (a four-bar's coupler tip held to a "
    "fixed point; pydrake 1.51.1); the same constraint on a body welded to the world runs, the tip within "
    "1.8e-8 m of the point after 0.1 s. xcheck's Drake model closes a cut at the ground that way",
    ("position", "angle"),
    kinds=(),
    closed_loops=True,
    reproducer="reproducers/drake_ball_constraint_world.py",
)


class Drake(Engine):
    """Drake (MultibodyPlant, discrete SAP solver): driven dynamics, free motion, and its
    SDFormat file.

    Drake has no constraint that prescribes a joint coordinate as a function of time (its
    coupler constraint has a constant offset), so the driven joints are PD-controlled
    actuators, which SAP treats implicitly. Measured with pydrake 1.51.1
    (``benchmarks/drake_pd_gain.py``), the gain is not what the mode measures: with
    ``Kp = kappa M / dt^2`` (M the total mass times size^2 on a revolute, the total mass
    on a prismatic driver) the lag behind the law is the same to four digits for every
    kappa from 1e4 to 1e10 (fourbar 5.24e-9, 1.36e-9, 3.45e-10 rad at dt = 1.64, 0.82,
    0.41 ms; slider-crank 6.85e-9 .. 4.28e-10 rad; two-body-arm 3.6e-6 .. 2.3e-7 rad),
    as if SAP bounded the stiffness it applies by the step (not traced in Drake's
    source). The lag is then a truncation of order 2 (the comparison is at the inputs
    Drake realised, so it is reported, not judged), on the four-bars far below the
    position error, which is the loops' opening and the same for every kappa from 1 to
    1e10 (fourbar 7.18e-6, 1.82e-6, 4.58e-7 m). At kappa = 1 the lag is the gain's
    (4.0e-6 rad on fourbar), still falling at order 2. ``drake-dynamic`` runs at kappa
    = 1e6 (:mod:`.dynamic`).
    """

    name = "drake"
    title = "Drake"
    requires = ("pydrake",)
    implementation = "xcheck.engines.drake.modes"
    distributions = ("drake",)
    install = "pip install xcheck[drake]"
    modes = (
        Mode(
            "drake-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 2.0, "angle": 2.0, "velocity": 1.0, "omega": 1.0, "acceleration": None, "alpha": None},
            style=dict(color="tab:pink", lw=1, ls="--"),
            cost=2.5,
        ),
        Mode("drake-free", "free", FREE_MOTION, style=dict(color="tab:pink", lw=1, ls="--"), cost=0.16),
    )
    export_format, export_directory = "sdf", "sdf"
    findings = (_BALL_TO_WORLD,)
    color = "tab:pink"
    notes = (
        "Revolute and prismatic joints: a MultibodyPlant tree (RevoluteJoint about z, PrismaticJoint in the "
        "plane, xcheck's body frames as Drake's) with each loop cut at a revolute closed by a ball constraint "
        "(AddBallConstraint), stepped by the discrete SAP solver (first order, the constraints near-rigid). "
        "Gravity, constant and time-law loads (applied spatial forces), linear spring-dampers "
        "(LinearSpringDamper) and rotational spring-dampers on tree revolutes (RevoluteSpring and joint "
        "damping). Not converted (not applicable): pin-in-slot joints, loops cut at a prismatic joint, "
        "rotational springs across a cut joint, springs of rest length 0 (Drake's LinearSpringDamper needs a "
        "positive free length). Driven dynamics: the driven joints (tree joints) held on the motion laws by "
        "PD-controlled joint actuators (SAP's implicit PD, Kp = 1e6 M / dt^2, Kd = Kp dt; the lag is the same "
        "for Kp dt^2 / M from 1e4 to 1e10 and falls at order 2 with the step); positions and velocities "
        "(accelerations not compared). Its model file: "
        "SDFormat with the loop cuts as drake:ball_constraint elements (one file holds the whole mechanism)."
    )

    def export_files(self, kinematics) -> dict[str, str]:
        """``{NAME.sdf: text}`` (:func:`xcheck.engines.drake.sdf.export_files`; needs no pydrake)."""
        from .sdf import export_files

        return export_files(kinematics)
