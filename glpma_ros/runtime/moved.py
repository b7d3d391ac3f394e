"""The module names of 0.3, importable for one release more (they go in 0.5.0).

0.4.0 put the modules into one folder per layer (README, "Architecture").  A script that imports a
module by its 0.3 name (``from glpma_ros.estimator import Estimator``), or a pickle that names one,
gets the module at its new name, with a :class:`DeprecationWarning` naming it.  :func:`install` (run
by ``glpma_ros/__init__.py``) puts the finder on ``sys.meta_path``; it serves these names only.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

#: 0.3 name -> 0.4 name
MOVED = {
    "glpma_ros.compat": "glpma_ros.runtime.compat",
    "glpma_ros.covariance": "glpma_ros.estimation.covariance",
    "glpma_ros.estimator": "glpma_ros.estimation.estimator",
    "glpma_ros.exact": "glpma_ros.modes.exact",
    "glpma_ros.linalg": "glpma_ros.models.linalg",
    "glpma_ros.node.security": "glpma_ros.node.dds.security",
    "glpma_ros.numba_cache": "glpma_ros.runtime.numba_cache",
    "glpma_ros.precompile": "glpma_ros.runtime.precompile",
    "glpma_ros.redundancy": "glpma_ros.estimation.redundancy",
    "glpma_ros.solve_all": "glpma_ros.modes.multistart",
    "glpma_ros.velocity": "glpma_ros.estimation.velocity",
}


class MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds a 0.3 name of :data:`MOVED` and loads it as the module at its new name (one object)."""

    def __init__(self, moved: dict):
        self.moved = moved

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in self.moved:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = self.moved[spec.name]
        warnings.warn(f"{spec.name} is {new} since glpma_ros 0.4.0; the old name goes in 0.5.0",
                      DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module):
        """The module at its new name is already executed."""


def install(moved: dict = MOVED) -> None:
    """Put the finder of ``moved``'s names on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, MovedModules) and f.moved is moved for f in sys.meta_path):
        sys.meta_path.append(MovedModules(moved))
