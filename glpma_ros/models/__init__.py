"""Manipulator models: geometry, residuals, inverse kinematics, poses."""
from ..runtime import numba_cache

# before anything is defined or compiled: processes compiling at once share the cache safely, and a
# change to any kernel recompiles the functions that carry its code
numba_cache.install()

from . import kernels  # noqa: E402
from .base import Manipulator, Pose  # noqa: E402
from .hexapod_66 import Hexapod66  # noqa: E402
from .planar_3rpr import Planar3RPR  # noqa: E402

MODELS = {Planar3RPR.kind: Planar3RPR, Hexapod66.kind: Hexapod66}

__all__ = ["Manipulator", "Pose", "Planar3RPR", "Hexapod66", "MODELS", "kernels"]
