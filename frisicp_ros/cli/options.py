"""Command-line options generated from the settings table (``frisicp_ros.stream.settings``).

Every table option of a surface becomes a flag (``--name-with-dashes`` unless the row names its
spellings; booleans get a ``--no-`` form). Parsed defaults are None, so a command can tell
what was given from what was not: only given values are passed on, and everything else takes
the table's default, the same one the node and the YAML file use.
"""

from __future__ import annotations

import argparse
from typing import Any

from frisicp_core import InitialGuess
from frisicp_ros.cli.command import CommandError
from frisicp_ros.stream.guess import POSE_FORMAT, SIGMA_FORMAT, parse_initial
from frisicp_ros.stream.settings import OPTIONS_BY_NAME, Group, Option, Surface, Value, options_for


def add_options(parser: argparse.ArgumentParser, surface: Surface) -> None:
    """One flag per table option of ``surface``, in one argument group per table group."""
    for group in Group:
        rows = options_for(surface, [group])
        if not rows:
            continue
        arguments = parser.add_argument_group(f"{group.value} options")
        for row in rows:
            arguments.add_argument(
                *row.cli_flags, dest=row.name, default=None, help=_help(row), **_parsing(row)
            )


def _parsing(row: Option) -> dict[str, Any]:
    if row.kind is bool:
        return {"action": argparse.BooleanOptionalAction}
    if row.choices is not None:
        return {"type": row.kind, "choices": row.choices}
    return {"type": row.kind, "metavar": row.kind.__name__.upper()}


def _help(row: Option) -> str:
    default = row.default if row.default != "" else '""'
    if row.kind is bool:
        default = "on" if row.default else "off"
    rule = f"; {row.rule.text}" if row.rule is not None else ""
    return f"{row.description} (default: {default}{rule})".replace("%", "%%")


def given_values(args: argparse.Namespace, surface: Surface) -> dict[str, Value]:
    """The table options given on the command line, by option name; refuses conflicts.

    An option that only means something together with another option's value (the row's
    ``needs``) is an error when given without it: nothing is silently ignored.
    """
    given: dict[str, Value] = {
        row.name: getattr(args, row.name)
        for row in options_for(surface)
        if getattr(args, row.name) is not None
    }
    for row in options_for(surface):
        if row.name not in given or row.needs is None:
            continue
        other, wanted = row.needs
        actual = given.get(other, OPTIONS_BY_NAME[other].default)
        if actual != wanted:
            raise CommandError(
                f"{flag(row)} applies only with {flag_of(other, surface)} {wanted} (it is {actual})"
            )
    return given


def flag(row: Option) -> str:
    return row.cli_flags[0]


def flag_of(name: str, surface: Surface) -> str:
    """The flag of a table option (``surface``: where it is asked for; every option it names has one)."""
    assert surface & OPTIONS_BY_NAME[name].surfaces, (name, surface)
    return flag(OPTIONS_BY_NAME[name])


def add_guess_options(parser: argparse.ArgumentParser, what_it_does: str) -> None:
    """``--initial`` and ``--initial-sigma`` (frisicp_ros.stream.guess has the format)."""
    group = parser.add_argument_group("initial guess")
    group.add_argument(
        "--initial",
        metavar=f'"{POSE_FORMAT}"',
        help="a rough pose of the data in the model frame (model = s R data + t: t = x y z, R the"
        f" quaternion, s the scale if known, then taken within 1 %%): {what_it_does}",
    )
    group.add_argument(
        "--initial-sigma",
        metavar=SIGMA_FORMAT,
        help="how far off --initial may be, 1-sigma: degrees, model units, and optionally the"
        " scale's relative sigma (default 0.01); answers beyond 3 sigmas are not reliable",
    )


def guess_from_args(args: argparse.Namespace, dims: int) -> InitialGuess | None:
    """The guess of ``--initial``/``--initial-sigma`` for ``dims``-D points, or None."""
    if args.initial is None:
        if args.initial_sigma is not None:
            raise CommandError("--initial-sigma applies only with --initial")
        return None
    try:
        return parse_initial(args.initial, args.initial_sigma, dims)
    except ValueError as err:
        raise CommandError(str(err)) from None
