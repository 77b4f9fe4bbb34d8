"""Exceptions for mistakes in user input.

Anything deriving from :class:`StraylightError` is a user's mistake (a bad config key, a time
outside the ephemeris, a NaN coordinate).  The CLI prints its message and exits with status 2,
without a traceback.  Any other exception is a bug and keeps its traceback.
"""

__all__ = ["StraylightError", "ConfigError", "InputError", "EphemerisRangeError", "OutputError"]


class StraylightError(Exception):
    """A user-facing error: the message names the file, field and value at fault."""


class ConfigError(StraylightError):
    """A campaign or instrument config that does not match its schema or is inconsistent."""


class InputError(StraylightError):
    """A bad argument or input value (time, coordinate, file)."""


class EphemerisRangeError(InputError):
    """A time outside the range the ephemeris covers."""


class OutputError(StraylightError):
    """Writing a product failed (disk full, no permission): the message names the store and the
    region; finished parts are kept and a re-run completes the rest."""
