"""The errors maskless reports to a user: one family, so a caller can tell a bad input from a bug.

The caller may be the CLI or a script.

Every error here names what was wrong (the file, the field, the flag or the argument) and what was
expected. Each also subclasses the built-in error a Python caller would expect (ValueError,
FileNotFoundError), so ``except ValueError`` keeps working. Anything else that escapes the library
is a bug and keeps its traceback.

And its one warning: a recording cut off, read up to the cut (``TruncatedRecordingWarning``).
"""


class MasklessError(Exception):
    """Base of every error maskless reports to a user."""


class ConfigError(MasklessError, ValueError):
    """A configuration file, field, flag or argument is invalid."""


class RecordError(MasklessError, ValueError):
    """A recorded signal (CSV or MCAP) cannot be read or used as asked."""


class ModelError(MasklessError, ValueError):
    """A model cannot serve what it was asked for (say, a design on an integrating model)."""


class MissingFileError(MasklessError, FileNotFoundError):
    """A file the user named does not exist."""


class SweepError(MasklessError, RuntimeError):
    """A population sweep could not finish (a worker died); what it finished is kept."""


class TruncatedRecordingWarning(RuntimeWarning):
    """A recording ended or broke before its footer; only a prefix of it was read."""
