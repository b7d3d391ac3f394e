"""``glpma-fk``: the entry point that finds the commands and runs one (the command line of record:
doc/interface.md).

Every command -- the built-in ``solve``, ``solve-all``, ``precompile``, ``modes``, ``node`` and the tools'
``bench``, ``demo``, ``stress``, ``bag``, ``map``, ``calibrate`` -- is an entry point of the group
:data:`~.api.COMMANDS` naming a :class:`~.api.Command` (as ros2cli's commands are): setup.py's
``"NAME = module:COMMAND [extra]"``, ``extra`` being the setup.py extra it needs.  ``glpma-fk --help`` lists
them from their :class:`~.api.Command` lines without importing their code; ``glpma-fk NAME ...`` imports the
command's ``main`` and hands it the rest of the arguments.  A command whose extra is not installed is listed,
and refused, with the pip command that installs it.  This module names no command."""
from __future__ import annotations

import argparse
import importlib.metadata
import os
import re
import sys

from .. import __version__
from .api import COMMANDS, DISTRIBUTION, EXIT_BROKEN_PIPE, OneLineParser, command_main, fail


def commands() -> dict:
    """name -> ``importlib.metadata.EntryPoint`` of every installed command, by name."""
    return {ep.name: ep for ep in sorted(importlib.metadata.entry_points(group=COMMANDS), key=lambda e: e.name)}


def missing_requirements(extra: str) -> list[str]:
    """The distributions the setup.py ``extra`` requires that are not installed."""
    try:
        requires = importlib.metadata.requires(DISTRIBUTION) or []
    except importlib.metadata.PackageNotFoundError:
        return []
    marker = re.compile(rf"""extra\s*==\s*["']{re.escape(extra)}["']""")
    missing = []
    for requirement in requires:
        name = re.match(r"[A-Za-z0-9._-]+", requirement).group(0)
        if marker.search(requirement) and name not in missing:
            try:
                importlib.metadata.version(name)
            except importlib.metadata.PackageNotFoundError:
                missing.append(name)
    return missing


def missing_extra(ep) -> tuple[str, list] | None:
    """``(extra, its distributions not installed)`` of command ``ep``, or None when it can run here."""
    for extra in ep.extras:
        missing = missing_requirements(extra)
        if missing:
            return extra, missing
    return None


def help_line(ep) -> str:
    """The command's line in ``glpma-fk --help``, with the pip command of its extra when that is missing."""
    missing = missing_extra(ep)
    return ep.load().help + (f" (not installed: pip install '{DISTRIBUTION}[{missing[0]}]')" if missing else "")


def build_parser() -> argparse.ArgumentParser:
    """``glpma-fk [--version] COMMAND ...``: lists the commands; each parses its own arguments."""
    p = OneLineParser(prog="glpma-fk", description="Forward kinematics of parallel manipulators "
                      "by G3-PCX, RCGA and GLPMA, with a real-time ROS 2 node.")
    p.add_argument("--version", action="version", version=f"glpma-fk {__version__}",
                   help="print the version and exit")
    sub = p.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    for name, ep in commands().items():
        q = sub.add_parser(name, help=help_line(ep), add_help=False)
        q.add_argument("rest", nargs=argparse.REMAINDER)
    return p


def run_command(ep, argv) -> int:
    """Command ``ep`` on its arguments ``argv``, or the one-line refusal when its extra is not installed."""
    missing = missing_extra(ep)
    if missing is not None:
        extra, names = missing
        return fail(f"glpma-fk {ep.name} needs {', '.join(names)}: pip install '{DISTRIBUTION}[{extra}]' "
                    f"(in a checkout: pip install -e '.[{extra}]')")
    return int(ep.load().load()(argv) or 0)


@command_main
def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        command = commands().get(argv[0]) if argv else None
        code = run_command(command, argv[1:]) if command is not None else build_parser().parse_args(argv) and 0
        sys.stdout.flush()          # a closed pipe shows here, not at interpreter exit
        return code
    except BrokenPipeError:
        # the reader went away (| head -1): stop quietly; stdout goes nowhere from now on
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
