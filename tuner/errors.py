"""Errors that the command line reports as one line with exit code 2 (bad input)."""

from __future__ import annotations

__all__ = ["UserError", "EXIT_OK", "EXIT_INTERNAL", "EXIT_USAGE", "EXIT_SYSTEM"]

EXIT_OK = 0         # the command did what was asked
EXIT_INTERNAL = 1   # a bug or an environment failure: report it
EXIT_USAGE = 2      # bad input: a file, a name or a value; the message says which
EXIT_SYSTEM = 3     # the system refused a file: disk full, quota, read-only, permission


class UserError(Exception):
    """Bad input from the user (file, name, value); printed without a traceback."""
