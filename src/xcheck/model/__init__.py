"""The canonical mechanism model and its file format."""

from ._free_motion import FreeMotionSpec, RotationalSpring, Spring
from ._load import MAX_BODIES, MAX_FILE_BYTES, MAX_INSTANTS, load_mechanism, parse_mechanism
from ._mechanism import (
    GROUND,
    LOAD_LAWS,
    Assembly,
    Body,
    Driver,
    Instant,
    Joint,
    Load,
    LoadLaw,
    Mechanism,
    MotionLaw,
    PinInSlot,
    Prismatic,
    Revolute,
)

__all__ = [
    "GROUND",
    "FreeMotionSpec",
    "RotationalSpring",
    "Spring",
    "MAX_BODIES",
    "MAX_FILE_BYTES",
    "MAX_INSTANTS",
    "Assembly",
    "Body",
    "Driver",
    "Instant",
    "Joint",
    "Load",
    "LoadLaw",
    "LOAD_LAWS",
    "Mechanism",
    "MotionLaw",
    "PinInSlot",
    "Prismatic",
    "Revolute",
    "load_mechanism",
    "parse_mechanism",
]
