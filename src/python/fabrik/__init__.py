"""fabrik: prioritized FABRIK inverse kinematics for motion capture (docs/python.md)."""
from ._fabrik import *  # noqa: F401,F403
from ._fabrik import __version__  # noqa: F401
