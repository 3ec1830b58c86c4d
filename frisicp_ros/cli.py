"""The ``frisicp`` command: one argparse front end, one module per subcommand.

Each subcommand module exposes ``add_parser(subparsers)``, which registers its parser and sets
``func`` (called with the parsed arguments, returns the exit code). Errors meant for the user
are raised as ``CommandError`` and printed without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

# Modules providing subcommands, in the order `frisicp --help` lists them.
SUBCOMMANDS = (
    "frisicp_ros.register_command",
    "frisicp_ros.bag_command",
    "frisicp_ros.bag_info_command",
    "frisicp_ros.bench_command",
)


class CommandError(Exception):
    """A failure to report to the user as one line on stderr, with exit code ``code``."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="frisicp", description="Scale-aware point cloud registration (FRISICP)."
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMANDS:
        importlib.import_module(name).add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CommandError as err:
        print(f"frisicp {args.command}: error: {err}", file=sys.stderr)
        return err.code
    except KeyboardInterrupt:
        print(f"frisicp {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
