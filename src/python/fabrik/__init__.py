"""fabrik: prioritized FABRIK inverse kinematics for motion capture (docs/python.md).

Lengths are millimetres at this edge (as on fabrikd's wire and in TRC files), angles degrees
(as on the wire and in `fabrik solve --angles`), times seconds. Positions are in the lab
(world) frame the markers were measured in.
"""
from ._fabrik import (  # noqa: F401
    CalibrationError,
    Config,
    ConfigError,
    FormatError,
    Pose,
    Tracker,
    __version__,
    synthetic_frames,
)
from .config import calibrate, load_config  # noqa: F401
from .recordings import MarkerData, Table, read_markers, read_table  # noqa: F401
from .solution import Solution, solve  # noqa: F401
