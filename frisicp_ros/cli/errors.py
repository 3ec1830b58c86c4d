"""The one exception a subcommand raises for a user mistake (leaf module: no imports)."""

from __future__ import annotations


class CommandError(Exception):
    """A failure to report to the user as one line on stderr, with exit code ``code``."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code
