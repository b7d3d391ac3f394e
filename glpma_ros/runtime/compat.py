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

try:
    from numba import __version__ as INSTALLED_NUMBA
except ImportError:            # check_numba() says so in one line
    INSTALLED_NUMBA = None

#: oldest Numba the kernels compile with (also in setup.py and package.xml)
NUMBA_FLOOR = (0, 58)
#: how to get a newer Numba where the distribution's is too old (PEP 668: no plain pip)
NUMBA_HOWTO = ("python3 -m pip install --user --break-system-packages 'numba>=0.58' 'numpy<2', or the same "
               "in a venv made with --system-site-packages (README, Usage with ROS 2 Jazzy)")


def version_tuple(text: str) -> tuple[int, ...]:
    """``"0.56.4+dfsg"`` -> ``(0, 56, 4)``."""
    return tuple(int(part) for part in re.findall(r"\d+", str(text))[:3])


#: first Numba whose IR inliner copies a callee once per call site: before it, ``InlineInlineable``
#: deep-copied the callee's IR (and every ``Loc`` in it) again at each nested site (numba#8989, fixed by
#: numba#8990 and numba#9245 in 0.59.0), so the residual dispatch over every kind, inlined through
#: ``population_fitness`` into each solver's generation loop, takes tens of minutes to compile
NUMBA_INLINER_FIXED = (0, 59)
#: ``inline=`` of the small compiled kernels the solvers' loops call (the residuals, the fitness, the
#: operators): Numba-IR inlining lets LLVM keep the geometry in registers across the population loop
#: (the CPU per evaluation with and without it: BENCHMARKS.md, "Design measurements"); where the inliner is
#: slow, the calls stay calls and LLVM inlines what it judges worth it
def inline_for(version: str) -> str:
    """The ``inline=`` option of the small kernels for Numba ``version``."""
    return "always" if version_tuple(version)[:2] >= NUMBA_INLINER_FIXED else "never"


NUMBA_INLINE = inline_for(INSTALLED_NUMBA or "0")


def check_numba(version: str | None = None) -> None:
    """:class:`GlpmaError` (one line) when Numba is missing or older than :data:`NUMBA_FLOOR`.
    ``version``: the version to judge (default: the installed one)."""
    if version is None:
        if INSTALLED_NUMBA is None:
            raise GlpmaError(f"numba is not installed; glpma_ros needs numba >= "
                             f"{'.'.join(map(str, NUMBA_FLOOR))}: {NUMBA_HOWTO}")
        version = INSTALLED_NUMBA
    if version_tuple(version)[:2] < NUMBA_FLOOR:
        raise GlpmaError(f"numba {version} is too old; glpma_ros needs numba >= "
                         f"{'.'.join(map(str, NUMBA_FLOOR))}: {NUMBA_HOWTO}")
