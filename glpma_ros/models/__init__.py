"""Manipulator models: geometry, residuals, inverse kinematics, poses."""
from .. import numba_cache
from . import kernels
from .base import Manipulator, Pose
from .hexapod_66 import Hexapod66
from .planar_3rpr import Planar3RPR

numba_cache.install()      # before anything is compiled: processes compiling at once share the cache safely

MODELS = {Planar3RPR.kind: Planar3RPR, Hexapod66.kind: Hexapod66}

__all__ = ["Manipulator", "Pose", "Planar3RPR", "Hexapod66", "MODELS", "kernels"]
