"""The user-error family: every error a user can fix (a bad argument, file, recording, bench or wire byte)
derives from :class:`UserError`. The CLI prints one such error as one line naming the place and the fix, and
exits with code 2; it never prints a traceback for one. Raise them at the boundary where the bad value enters.
"""

from __future__ import annotations


class UserError(Exception):
    """A user error: the message names the place (file:line, argument, dataset, byte offset) and the fix."""

    exit_code: int = 2


class UsageError(UserError):
    """Bad command-line arguments or combinations."""


class OutputError(UserError, OSError):
    """An output file or folder cannot be created or written (the path names it)."""
