"""What the installed libraries must be for the compiled kernels to work, checked before use.

The solvers draw from a ``numpy.random.Generator`` inside Numba-compiled code
(``rng.integers``, ``rng.standard_normal``, ...).  Numba 0.58.1 with NumPy 1.26 (Ubuntu
24.04's pairing: no Numba before 0.58.1 supports NumPy 1.26, so the distribution's
``python3-numba`` passes) compiles every solver and gives the same results as current
releases; Debian 12's 0.56.4 fails to compile with ``Unknown attribute 'integers' of type
NumPyRandomGeneratorType``.  The node and ``glpma-fk`` refuse a Numba older than the floor
with one line saying how to get a newer one, rather than failing later on every solve.
"""
from __future__ import annotations

import re

from ..errors import GlpmaError

#: oldest Numba the kernels compile with (also in setup.py and package.xml)
NUMBA_FLOOR = (0, 58)
#: how to get a newer Numba where the distribution's is too old (PEP 668: no plain pip)
NUMBA_HOWTO = ("python3 -m pip install --user --break-system-packages 'numba>=0.58' 'numpy<2', or the same "
               "in a venv made with --system-site-packages (README, Usage with ROS 2 Jazzy)")


def version_tuple(text: str) -> tuple[int, ...]:
    """``"0.56.4+dfsg"`` -> ``(0, 56, 4)``."""
    return tuple(int(part) for part in re.findall(r"\d+", str(text))[:3])


def check_numba(version: str | None = None) -> None:
    """:class:`GlpmaError` (one line) when Numba is missing or older than :data:`NUMBA_FLOOR`.
    ``version``: the version to judge (default: the installed one)."""
    if version is None:
        try:
            import numba  # whether it imports is what is checked
        except ImportError:
            raise GlpmaError(f"numba is not installed; glpma_ros needs numba >= "
                             f"{'.'.join(map(str, NUMBA_FLOOR))}: {NUMBA_HOWTO}") from None
        version = numba.__version__
    if version_tuple(version)[:2] < NUMBA_FLOOR:
        raise GlpmaError(f"numba {version} is too old; glpma_ros needs numba >= "
                         f"{'.'.join(map(str, NUMBA_FLOOR))}: {NUMBA_HOWTO}")
