"""The ``frisicp`` command: one argparse front end, one module per subcommand.

Each subcommand module exposes ``NAME``, ``SUMMARY`` (for ``frisicp --help``), ``DESCRIPTION``,
``configure(parser)`` (its arguments) and ``run(args)`` (returns the exit code). Errors meant for the user
are raised as :class:`CommandError` and printed without a traceback. Subcommands import their
heavy dependencies (rosbags, the benchmark) inside ``run``, so ``frisicp --help`` stays light.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from frisicp_ros.cli import bag, bag_info, bench, register
from frisicp_ros.cli.command import CommandError

# In the order `frisicp --help` lists them.
SUBCOMMANDS = (register, bag, bag_info, bench)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="frisicp", description="Scale-aware point cloud registration (FRISICP)."
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for subcommand in SUBCOMMANDS:
        parser_of = subparsers.add_parser(
            subcommand.NAME, help=subcommand.SUMMARY, description=subcommand.DESCRIPTION
        )
        subcommand.configure(parser_of)
        parser_of.set_defaults(func=subcommand.run)
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
    except BrokenPipeError:
        # The reader of stdout left (`frisicp register ... | head -3`): nothing more to say to it,
        # and Python's own flush at exit must not fail again (it would print a traceback).
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


if __name__ == "__main__":
    sys.exit(main())
