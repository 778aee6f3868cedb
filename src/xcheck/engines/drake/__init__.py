"""Drake: the mechanism as a ``MultibodyPlant`` (a tree of revolute and
prismatic joints on the world body) whose loops are closed by ball
constraints, stepped by Drake's discrete SAP solver in free motion
(:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["Drake"]


class Drake(Engine):
    """Drake (MultibodyPlant, discrete SAP solver): free motion, and its SDFormat file.

    No driven mode: Drake has no constraint that prescribes a joint coordinate as a
    function of time (its coupler constraint has a constant offset), so the driven
    mechanism would need a PD actuator (SAP's implicit PD controller) whose error is its
    gain's lag, not a time step's truncation: efforts compared through it would measure
    the chosen gain, which is not an honest driven-dynamics verdict.
    """

    name = "drake"
    title = "Drake"
    requires = ("pydrake",)
    implementation = "xcheck.engines.drake.free"
    distributions = ("drake",)
    install = "pip install xcheck[drake]"
    modes = (Mode("drake-free", "free", FREE_MOTION, style=dict(color="tab:pink", lw=1, ls="--")),)
    export_format, export_directory = "sdf", "sdf"
    color = "tab:pink"
    notes = (
        "Revolute and prismatic joints: a MultibodyPlant tree (RevoluteJoint about z, PrismaticJoint in the "
        "plane, xcheck's body frames as Drake's) with each loop cut at a revolute closed by a ball constraint "
        "(AddBallConstraint), stepped by the discrete SAP solver (first order, the constraints near-rigid). "
        "Gravity, constant and time-law loads (applied spatial forces), linear spring-dampers "
        "(LinearSpringDamper) and rotational spring-dampers on tree revolutes (RevoluteSpring and joint "
        "damping). Not converted (not applicable): pin-in-slot joints, loops cut at a prismatic joint, "
        "rotational springs across a cut joint, springs of rest length 0 (Drake's LinearSpringDamper needs a "
        "positive free length). Free motion only: no driven mode (Drake has no time-prescribed joint "
        "constraint; a stiff PD actuator would measure its gain, not the time step). Its model file: "
        "SDFormat with the loop cuts as drake:ball_constraint elements (one file holds the whole mechanism)."
    )

    def export_files(self, kinematics) -> dict[str, str]:
        """``{NAME.sdf: text}`` (:func:`xcheck.engines.drake.sdf.export_files`; needs no pydrake)."""
        from .sdf import export_files

        return export_files(kinematics)
