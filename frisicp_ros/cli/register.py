"""``frisicp register DATA MODEL``: register two point cloud files and print the similarity."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from frisicp_core import CloudFileError, RegistrationConfig, read_points, register
from frisicp_ros.cli.command import CommandError
from frisicp_ros.cli.options import add_guess_options, add_options, flag_of, given_values, guess_from_args
from frisicp_ros.stream.outputs import result_summary
from frisicp_ros.stream.settings import Surface, Value, algorithm_values, registration_config

NAME = "register"
SUMMARY = "register DATA onto MODEL (files: .ply .pcd .xyz .csv .txt .npy)"
DESCRIPTION = (
    "Find s, R, t with MODEL ≈ s·R·DATA + t and print them. Exit code 1 when the result did not"
    " converge or failed the plausibility verdict (printed with the reason), 2 for unusable input."
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("data", help="point cloud to move")
    parser.add_argument("model", help="point cloud that stays fixed")
    parser.add_argument(
        "--paper",
        action="store_true",
        help="run the published algorithm exactly (RegistrationConfig.paper(): identity start, no "
        "trimming or acceleration, one level for the baselines)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--plot",
        metavar="PNG",
        help="also draw the data and model before and after (three views) and the aligned data's"
        " distances to the model into this PNG",
    )
    add_guess_options(parser, "the registration searches around it instead of blind")
    add_options(parser, Surface.REGISTER)


def config_from_args(args: argparse.Namespace) -> RegistrationConfig:
    """The given options on top of the chosen preset (or the defaults).

    An option the preset sets, given with another value, is an error: a preset is never
    silently changed, nor an option silently ignored.
    """
    given = given_values(args, Surface.REGISTER)
    if not args.paper:
        return registration_config(given)
    base = RegistrationConfig.paper(str(given.get("method", RegistrationConfig().method.value)))
    check_preset("--paper", base, given)
    return registration_config(given, base)


def check_preset(preset: str, base: RegistrationConfig, given: dict[str, Value]) -> None:
    preset_values = algorithm_values(base, Surface.REGISTER)
    defaults = algorithm_values(RegistrationConfig(), Surface.REGISTER)
    for name, value in given.items():
        if name != "method" and preset_values[name] != defaults[name] and value != preset_values[name]:
            raise CommandError(
                f"{flag_of(name, Surface.REGISTER)} {value} conflicts with {preset}, which sets"
                f" {name} {preset_values[name]}"
            )


def run(args: argparse.Namespace) -> int:
    try:
        config = config_from_args(args)
        data = read_points(args.data)
        model = read_points(args.model)
        guess = guess_from_args(args, data.shape[1])
        if guess is not None:
            config = dataclasses.replace(config, guess=guess)
        result = register(data, model, config)
    except (CloudFileError, ValueError) as err:
        raise CommandError(str(err)) from None
    if args.plot:
        from frisicp_ros.stream.pictures import alignment_picture

        verdict = "reliable" if result.reliable else f"NOT reliable: {result.reason}"
        title = f"{Path(args.data).name} onto {Path(args.model).name} ({verdict})"
        alignment_picture(data, model, result.similarity, args.plot, title)
    summary = result_summary(result)
    usable = result.converged and result.reliable
    if args.json:
        print(json.dumps(summary))
        return 0 if usable else 1
    with np.printoptions(precision=6, suppress=True):
        print(f"method       {result.method.value}")
        print(f"scale        {result.similarity.scale:.9g}")
        print("rotation\n" + "\n".join("  " + str(row) for row in result.similarity.rotation))
        if "quaternion_xyzw" in summary:
            print(f"quaternion   {np.array(summary['quaternion_xyzw'])}  (x, y, z, w)")
        print(f"translation  {result.similarity.translation}")
    print(
        f"rms          {result.rms:.6g}  (forward {result.forward_rms:.6g}, backward {result.backward_rms:.6g})"
    )
    print(
        f"overlap      {result.overlap_forward:.1%} of the data, {result.overlap_backward:.1%} of the model"
    )
    print(f"iterations   {sum(result.iterations)}  per level {list(result.iterations)}")
    print(f"converged    {result.converged}")
    print(f"reliable     {result.reliable}" + (f"  ({result.reason})" if result.reason else ""))
    print(f"seconds      {result.seconds:.4f}")
    return 0 if usable else 1
