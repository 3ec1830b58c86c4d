"""Command-line options generated from the settings table (``frisicp_ros.stream.settings``).

Every table option of a surface becomes a flag (``--name-with-dashes`` unless the row names its
spellings; booleans get a ``--no-`` form). Parsed defaults are None, so a command can tell
what was given from what was not: only given values are passed on, and everything else takes
the table's default, the same one the node and the YAML file use.
"""

from __future__ import annotations

import argparse
from typing import Any

from frisicp_ros.cli.command import CommandError
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
