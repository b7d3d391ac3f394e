"""Errors users see: each carries a one-line message that names the problem."""


class GlpmaError(Exception):
    """Base class of the package's expected errors (never a traceback for these)."""


class ConfigError(GlpmaError):
    """A manipulator YAML that cannot be read or is inconsistent."""


class InputError(GlpmaError):
    """Leg lengths, variables or parameters that cannot be used."""
