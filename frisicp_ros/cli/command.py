"""The error a subcommand raises for a user mistake.

A leaf module (no frisicp imports), so subcommands and ``main`` depend on it and not on each other.
"""

from __future__ import annotations


class CommandError(Exception):
    """A failure to report to the user as one line on stderr, with exit code ``code``."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code
