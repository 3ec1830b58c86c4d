"""Does a case's verdict depend on the seed? One trustworthy.py case, cold and from the truth, per seed.

    python benchmarks/verdict_seeds.py --suite 'sparse map onto scene' --scene bunny_part2.xyz \\
        --index 1 --draw 3 --seeds 6
    python benchmarks/verdict_seeds.py --quick    # one seed of a small case

``RegistrationConfig.seed`` draws the thinned levels, the global search's samples, the
covariance's pair subset and the random halves that size the sigmas
(:func:`frisicp_core.refine.uncertainty_of`). A right answer whose 3 sigma lies near a tolerance
is reliable for some seeds and refused for others; ``benchmarks/trustworthy.py`` calls a case
*determined* when one registration from the truth (seed 0) is right and reliable, which is as
much a draw. This registers one of its cases (``--suite``, ``--scene``, ``--index``, ``--cap``,
``--draw`` as there) with ``seed`` = 0 .. N-1, cold and from the truth
(``trustworthy.from_truth``, as there), and prints per seed the
errors against the truth and 3 sigma (rotation in degrees, scale in percent), the verdict, and
the ranges over the seeds. Exits 0 without measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

from trustworthy import SUITES, Spec, capped_case, from_truth

from frisicp_bench import script
from frisicp_bench.metrics import pose_errors
from frisicp_core import RegistrationConfig, register
from frisicp_core.uncertainty import SIGMAS


def main(argv: list[str] | None = None) -> int:
    parser = script.parser(
        __file__, __doc__, "one seed of a 60 % crop of the bunny, cold and from the truth", data=True
    )
    parser.add_argument("--suite", choices=SUITES, default="crop onto scene")
    parser.add_argument("--scene", default="bun_zipper.ply", help="a file of DATA/real or DATA/bunny")
    parser.add_argument("--index", type=int, default=5, help="the case's number in its suite (default 5)")
    parser.add_argument("--cap", type=int, default=10_000, help="points of each cloud at most (0: all)")
    parser.add_argument("--draw", type=int, default=0, help="as trustworthy.py's --draw (default 0)")
    parser.add_argument("--seeds", type=int, default=6)
    args = script.parse(parser, argv)
    if args.seeds < 1 or args.cap < 0 or args.index < 0:
        parser.error("--seeds must be at least 1, --cap and --index at least 0")
    seeds = 1 if args.quick else args.seeds
    spec = Spec(args.suite, args.scene, args.index, args.cap, args.draw)
    built = script.load_data(args, lambda data: capped_case(spec, data))
    if built is None:
        return 0
    case, data, model, _ = built
    if case.truth is None:
        print(f"{case.name}: no known answer, nothing to compare")
        return 0
    print(f"{case.name} ({data.shape[0]} points onto {model.shape[0]}): RegistrationConfig(seed=k)")
    for start in ("cold", "truth"):
        sigmas_scale, sigmas_rotation, reliable = [], [], 0
        for seed in range(seeds):
            if start == "truth":
                result = from_truth(data, model, case.truth, seed)
            else:
                result = register(data, model, RegistrationConfig(seed=seed))
            errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
            assert result.uncertainty is not None
            scale_3s = SIGMAS * 100.0 * result.uncertainty.scale
            rotation_3s = SIGMAS * result.uncertainty.rotation_deg
            sigmas_scale.append(scale_3s)
            sigmas_rotation.append(rotation_3s)
            reliable += result.reliable
            print(
                f"  {start:5s} seed={seed}: error {errors.rotation_deg:5.2f} deg, {100 * errors.scale:5.2f} %;"
                f" 3 sigma {rotation_3s:5.2f} deg, {scale_3s:5.2f} %;"
                f" {'right' if errors.success else 'WRONG'}, {'reliable' if result.reliable else 'refused'}"
            )
        print(
            f"  {start}: 3 sigma {min(sigmas_rotation):.2f}-{max(sigmas_rotation):.2f} deg,"
            f" {min(sigmas_scale):.2f}-{max(sigmas_scale):.2f} %; reliable {reliable}/{seeds}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
