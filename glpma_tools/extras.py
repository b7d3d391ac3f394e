"""Optional dependencies of the tools: a missing one is a one-line error naming the pip command."""
from __future__ import annotations

from glpma_ros.cli.api import MissingExtra
from glpma_ros.cli.api import require as require_modules

#: what each extra of setup.py installs (import names)
EXTRAS = {"bag": ("rosbags", "tqdm"), "map": ("matplotlib", "dask", "distributed", "tqdm")}

__all__ = ["EXTRAS", "MissingExtra", "require"]


def require(extra: str, command: str, modules=None) -> None:
    """Raise :class:`MissingExtra` when a module of ``extra`` (or just ``modules``) cannot be imported."""
    require_modules(extra, command, modules or EXTRAS[extra])
