"""``glpma-fk precompile``: compile (first time) or load every solver ahead of time."""
from __future__ import annotations

from ..errors import GlpmaError
from ..runtime.compat import check_numba
from ..runtime.precompile import precompile
from ..solvers import SOLVERS
from .api import OneLineParser, command_main

#: the command's --help text
DESCRIPTION = ("Compile (first run) or load the machine code of every solver for both manipulator kinds, so that the "
               "first solve and the node's first start do not wait for it. One progress line per solver on stderr.")


def build_parser() -> OneLineParser:
    q = OneLineParser(prog="glpma-fk precompile", description=DESCRIPTION)
    q.add_argument("--solvers", nargs="+", metavar="NAME", default=None,
                   help="only these solvers (default: every registered one)")
    return q



@command_main
def main(argv=None) -> int:
    check_numba()
    args = build_parser().parse_args(argv)
    unknown = [n for n in args.solvers or () if n not in SOLVERS]
    if unknown:
        raise GlpmaError(f"unknown solver {unknown[0]!r}; choose among {', '.join(SOLVERS)}")
    precompile(solver_names=args.solvers)
    return 0
