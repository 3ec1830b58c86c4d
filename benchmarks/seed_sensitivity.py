"""Does a frisicp bench case's outcome depend on the random thinning? Register it with several seeds.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/seed_sensitivity.py [--scan bun270.ply] [--scale 0.5] [--seeds 6]
    .venv/bin/python benchmarks/seed_sensitivity.py --quick    # seed 0 only

``RegistrationConfig.seed`` draws the random subsets of the sparse-to-dense levels, the
hypothesis screening's level included. A case whose success changes with the seed sits on the
edge of the search's reach: its pass or failure in one bench run is luck, and a change that only
reorders points (the spatial order) can flip it. This registers the bench's case of a scan in its
map (`frisicp bench`'s "scan/4→zipper_res2" families, the same perturbation, bench seed 0) with
``seed`` = 0 .. N-1, with and without Anderson acceleration, and prints each result's errors
against the truth (strict success: rotation < 1 deg, scale < 1 %). Exits 0 without measuring
when the data folder is absent, saying so.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from frisicp_bench import script
from frisicp_bench.cases import make_cases
from frisicp_bench.families import MAP_FILE, SCAN_EVERY, scan_to_map_family
from frisicp_core import RegistrationConfig, register, rotation_angle


def main(argv: list[str] | None = None) -> int:
    parser = script.parser(__file__, __doc__, "seed 0 only", data=True)
    parser.add_argument("--scan", default="bun270.ply", help="the scan registered onto the map")
    parser.add_argument("--scale", type=float, default=0.5, help="one of the paper's scales")
    parser.add_argument("--seeds", type=int, default=6)
    args = script.parse(parser, argv)
    seeds = 1 if args.quick else args.seeds
    family = script.load_data(args, lambda data: scan_to_map_family(data, args.scan, MAP_FILE, SCAN_EVERY))
    if family is None:
        return 0
    (case,) = make_cases(family, (args.scale,), 0)
    print(f"{family.name} s={args.scale}: the bench's case, registered with RegistrationConfig(seed=k)")
    for acceleration in (True, False):
        successes = 0
        for seed in range(seeds):
            result = register(
                case.data, family.model, RegistrationConfig(seed=seed, acceleration=acceleration)
            )
            error = case.truth.inverse() @ result.similarity
            rotation, scale = float(np.rad2deg(rotation_angle(error.rotation))), abs(error.scale - 1.0)
            ok = rotation < 1.0 and scale < 0.01
            successes += ok
            print(
                f"  acceleration={acceleration!s:5s} seed={seed}: rotation {rotation:6.2f} deg, scale"
                f" {100 * scale:6.2f} %, {'ok' if ok else 'FAIL'}, reliable={result.reliable}"
            )
        print(f"  acceleration={acceleration}: {successes}/{seeds} seeds succeed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
