"""The ``glpma-fk`` command line: :mod:`.main` (the entry point and the built-in commands), :mod:`.api` (what
a command's module imports: the parser, the exit statuses, the argument types).

``OneLineParser`` and ``command_main`` are importable from here, as in 0.3, for one release more."""
from .api import OneLineParser, command_main

__all__ = ["OneLineParser", "command_main"]
