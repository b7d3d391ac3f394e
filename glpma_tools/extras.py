"""Optional dependencies of the tools: a missing one is a one-line error naming the pip command."""
from __future__ import annotations

import importlib.util

from glpma_ros.errors import GlpmaError

#: what each extra of setup.py installs (import names)
EXTRAS = {"bag": ("rosbags", "tqdm"), "map": ("matplotlib", "dask", "distributed", "tqdm")}


class MissingExtra(GlpmaError):
    """An optional dependency of a command is not installed."""


def require(extra: str, command: str, modules=None) -> None:
    """Raise :class:`MissingExtra` when a module of ``extra`` (or just ``modules``) cannot be imported."""
    missing = [m for m in (modules or EXTRAS[extra]) if importlib.util.find_spec(m) is None]
    if missing:
        raise MissingExtra(f"{command} needs {', '.join(missing)}: pip install 'glpma_ros[{extra}]' "
                           f"(in a checkout: pip install -e '.[{extra}]')")
