"""What can go wrong in a command, and the exit status each gives (``python -m sim``)."""

__all__ = ["CliError", "InternalError", "RtlFailure", "EXIT_BIT_EXACT", "EXIT_MISMATCH",
           "EXIT_USER_ERROR", "EXIT_INTERNAL"]

EXIT_BIT_EXACT = 0      #: the RTL matched golden bit for bit
EXIT_MISMATCH = 1       #: the RTL differed from golden (records, pixels, statistics) or hung
EXIT_USER_ERROR = 2     #: bad input: one ``error:`` line on stderr, caught before simulating
EXIT_INTERNAL = 3       #: a tool failed (simulator missing, build failed) or a bug of ours


class CliError(Exception):
    """A user error: printed as one ``error:`` line, exit status 2."""


class InternalError(Exception):
    """A failure that is not the user's: a simulator is missing or its build failed."""


class RtlFailure(Exception):
    """The design under test did not deliver its output (deadlock or timeout): not bit-exact."""
