"""Joint types: each one class that carries its behaviour.

A joint type is a subclass of :class:`Joint` (``_base.py``) with its geometry
as fields and its behaviour in small hooks: its constraint terms (made of the
kinds of row in ``_terms.py``, whose equations ``_equations.py`` holds once for
the NumPy and the compiled paths), its driver term, its reactions, and what an
engine's kinematic tree makes of it. :data:`JOINT_TYPES` maps a mechanism file's
``type`` to the class.
"""

from ._base import Action, Joint, converter
from ._gear import GearPair
from ._line import LineJoint, PinInSlot, Prismatic
from ._revolute import Revolute

__all__ = ["Action", "Joint", "converter", "GearPair", "LineJoint", "PinInSlot", "Prismatic", "Revolute", "JOINT_TYPES"]

#: every joint type by its ``type`` in a mechanism file
JOINT_TYPES: dict[str, type[Joint]] = {cls.kind: cls for cls in (Revolute, Prismatic, PinInSlot, GearPair)}
