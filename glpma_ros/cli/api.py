"""The plug-in API of ``glpma-fk``: what a command's module (the tools' and the built-in ones) imports.

A command is an entry point of the group :data:`COMMANDS` naming a :class:`Command` (setup.py:
``"NAME = module:COMMAND [extra]"``, the built-in commands too): its ``--help`` line and its
``main(argv) -> exit status``, which parses its own arguments with a :class:`OneLineParser` (a usage error is one
line, exit 2) and is wrapped in :func:`command_main` (the one place where its outcomes become exit
statuses); the argument types :data:`seed_type`, :data:`count_type` and :data:`positive_float` refuse a
bad number in one line; :func:`manipulator_parser` starts the parser of a command on one manipulator."""
from __future__ import annotations

import argparse
import functools
import importlib
import importlib.util
import math
import sys

from ..errors import GlpmaError

#: exit status of bad input (a usage error, an unreadable file, a value out of range)
EXIT_BAD_INPUT = 2
#: exit status when stdout was closed early (``glpma-fk ... | head -1``): 128 + SIGPIPE, as a shell tool
EXIT_BROKEN_PIPE = 141
#: the entry-point group of glpma-fk's plug-in subcommands (see :mod:`glpma_ros.cli.main`)
COMMANDS = "glpma_fk.commands"
#: the distribution whose extras the plug-ins name
DISTRIBUTION = "glpma_ros"


#: the help of a command's manipulator argument
CONFIG_HELP = "manipulator YAML (or the name of a shipped one)"
#: the help of ``--legs``, the sensor readings a command solves for
LEGS_HELP = ("leg lengths, in the config's unit (an actuated family, e.g. delta: the actuator positions, radians for "
             "revolute actuators)")


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit status 2."""

    def error(self, message):
        raise SystemExit(fail(f"{self.prog}: {message}"))


def manipulator_parser(prog: str, description: str, *, legs: bool = False, metavar: str | None = None,
                       **kwargs) -> OneLineParser:
    """The parser of a command on one manipulator: the positional ``config`` (a YAML path or the name of a
    shipped config, shown as ``metavar``), with ``legs`` also the required ``--legs`` (floats, the config's
    unit); ``kwargs`` go to :class:`OneLineParser`."""
    p = OneLineParser(prog=prog, description=description, **kwargs)
    p.add_argument("config", metavar=metavar, help=CONFIG_HELP)
    if legs:
        p.add_argument("--legs", type=float, nargs="+", required=True, help=LEGS_HELP)
    return p


def fail(message: str) -> int:
    """``message`` as one line on stderr; returns the exit status of bad input."""
    print(f"error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def command_main(main=None, *, prog: str | None = None):
    """Decorator of a command's ``main(argv) -> exit status``, the one place where its outcomes
    become exit statuses: argparse's exit (``--help``: 0; a :class:`OneLineParser` usage error,
    already printed: 2), a :class:`~glpma_ros.errors.GlpmaError` (one line on stderr, named ``prog``
    where given -- ``error: PROG: message``; status 2, or the error's own ``exit_status`` where its class
    has one, e.g. a failed worker's 1: not the user's input) and Ctrl-C (130).  ``@command_main`` or
    ``@command_main(prog="glpma-fk bag")``."""
    if main is None:
        return functools.partial(command_main, prog=prog)
    prefix = f"{prog}: " if prog else ""

    @functools.wraps(main)
    def run(argv=None) -> int:
        try:
            return int(main(argv) or 0)
        except SystemExit as exc:
            return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else fail(str(exc.code)))
        except GlpmaError as exc:
            status = fail(prefix + str(exc))
            return getattr(exc, "exit_status", status)
        except KeyboardInterrupt:
            return 130
    return run


def _number(kind, test, what):
    """An argparse type: ``kind`` (int or float) that passes ``test``, else a one-line usage error."""
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if kind is int else 'a number'}") from None
        if not test(value):
            raise argparse.ArgumentTypeError(f"{text!r} must be {what}")
        return value
    parse.__name__ = kind.__name__      # argparse names the type in "invalid ... value"
    return parse


seed_type = _number(int, lambda v: 0 <= v < 2**63, "a non-negative integer")
count_type = _number(int, lambda v: v >= 1, "at least 1")
positive_float = _number(float, lambda v: math.isfinite(v) and v > 0, "a positive number")


class Command:
    """A ``glpma-fk`` command as its entry point gives it (the group :data:`COMMANDS`): its line in
    ``glpma-fk --help`` and where its ``main(argv) -> exit status`` is (``"module:function"``), imported
    only when the command runs, so that ``--help`` loads none of the commands' code."""

    def __init__(self, help: str, main: str):
        self.help = help
        self.main = main

    def load(self):
        """The command's ``main``."""
        module, _, function = self.main.partition(":")
        return getattr(importlib.import_module(module), function)


class MissingExtra(GlpmaError):
    """An optional dependency of a command is not installed."""


def require(extra: str, command: str, modules) -> None:
    """Raise :class:`MissingExtra` (one line naming the pip command of setup.py's ``extra``) when one of
    ``modules`` cannot be imported."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise MissingExtra(f"{command} needs {', '.join(missing)}: pip install '{DISTRIBUTION}[{extra}]' "
                           f"(in a checkout: pip install -e '.[{extra}]')")
