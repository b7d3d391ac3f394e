"""The ``glpma-fk`` command line: :mod:`.main` (the entry point, the built-in commands)."""
