"""``frisicp register DATA MODEL``: register two point cloud files and print the similarity."""

from __future__ import annotations

import argparse
import json

import numpy as np

from frisicp_core import Initialization, Method, RegistrationConfig, RegistrationResult, register
from frisicp_core.io import CloudFileError, read_points
from frisicp_ros.cli.errors import CommandError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "register",
        help="register DATA onto MODEL (files: .ply .pcd .xyz .csv .txt .npy)",
        description="Find s, R, t with MODEL ≈ s·R·DATA + t and print them.",
    )
    parser.add_argument("data", help="point cloud to move")
    parser.add_argument("model", help="point cloud that stays fixed")
    parser.add_argument("--method", choices=[m.value for m in Method], default=Method.FRISICP.value)
    parser.add_argument(
        "--overlap",
        type=float,
        default=1.0,
        help="fraction of each cloud expected to have a counterpart (trimming); 1 = all",
    )
    parser.add_argument("--robust", action="store_true", help="preset for partial overlap: --overlap 0.8")
    parser.add_argument(
        "--init",
        choices=[i.value for i in Initialization],
        default=Initialization.PRINCIPAL_AXES.value,
        help="starting guess",
    )
    parser.add_argument(
        "--paper",
        action="store_true",
        help="run the published algorithm exactly (identity start, no trimming)",
    )
    parser.add_argument("--levels", type=int, default=3, help="sparse-to-dense levels")
    parser.add_argument(
        "--drop-nonfinite", action="store_true", help="drop NaN/Inf points instead of failing"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> RegistrationConfig:
    settings = {"levels": args.levels, "drop_nonfinite": args.drop_nonfinite}
    if args.paper:
        return RegistrationConfig.paper(args.method, **settings)
    overlap = 0.8 if args.robust and args.overlap == 1.0 else args.overlap
    return RegistrationConfig(
        method=Method(args.method), overlap=overlap, initialization=Initialization(args.init), **settings
    )


def result_summary(result: RegistrationResult) -> dict[str, object]:
    """The result as JSON-ready values (shared by --json and the bag mode)."""
    sim = result.similarity
    summary: dict[str, object] = {
        "scale": sim.scale,
        "rotation": sim.rotation.tolist(),
        "translation": sim.translation.tolist(),
        "rms": result.rms,
        "iterations": sum(result.iterations),
        "converged": result.converged,
        "seconds": result.seconds,
    }
    if sim.dim == 3:
        summary["quaternion_xyzw"] = sim.quaternion().tolist()
    return summary


def run(args: argparse.Namespace) -> int:
    try:
        config = config_from_args(args)
        data = read_points(args.data)
        model = read_points(args.model)
        result = register(data, model, config)
    except (CloudFileError, ValueError) as err:
        raise CommandError(str(err)) from None
    summary = result_summary(result)
    if args.json:
        print(json.dumps(summary))
        return 0
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
    print(f"iterations   {sum(result.iterations)}  per level {list(result.iterations)}")
    print(f"converged    {result.converged}")
    print(f"seconds      {result.seconds:.4f}")
    return 0 if result.converged else 1
