"""Symmetric and repetitive man-made scenes: never confidently wrong where the scene repeats itself.

Synthetic scenes of :mod:`frisicp_bench.structures` (a corridor open at both ends, an empty hall,
a hall with tables laid out symmetrically, stairs, a rack of shelves, three and six pillars on a
circle, a corner of three walls), sampled at 1,500 points per square metre. Each case is a crop
of 10, 30 or 50 % of the scene registered onto the scene, and the scene onto the crop. The two
clouds are independent samplings, as two sensors' or two visits' are
(:func:`frisicp_bench.structures.structured_crop_case`): the crop a
cube about a random point of one sampling (30-100 % of its points kept), the scene another,
each with Gaussian noise of 0.3 % of the scene's diagonal; the data moved by ``frisicp bench``'s
protocol (scale one of 0.5, 0.8, 1.3, 2, 3 about the model's centroid, turned up to 30 degrees,
shifted a tenth of the model's size); both capped at 10,000 random points (the node's cap;
``--cap N`` another: at 5,000 the finest level ICP runs is thinned to fewer than half of them);
default ``RegistrationConfig()``, one OpenMP thread. Scored like benchmarks/trustworthy.py (right: rotation < 1 deg, scale < 1 %,
translation < 0.5 % of the model's diagonal).

Every scene has exact symmetries, so most crops fit the scene as well at a twin of the true pose
(a half turn of the hall, a bay along the rack, another corner): being right there is luck, and
the honest verdict is "ambiguous" or "not determined". What counts is the **wrong and reliable**
column, which must be 0; how many came out right, and how many of those reliable, is shown
for completeness.

These scenes were made to find the symmetric twins the probes missed
(:func:`frisicp_core.ambiguity.symmetric_starts`); ``--draw N`` salts every seed for fresh
crops, noise, scales and turns that the method was never looked at on.

``--kinds furnished`` runs rooms without symmetry instead (:data:`frisicp_bench.structures.ROOMS`:
a room of random size with furniture at random places and headings, a new layout for every
case, none of them looked at while the method was built): there a crop holding furniture
determines its pose, and right answers may be reliable; wrong and reliable must still be 0.
``--repeats N`` gives each kind, share and direction N cases (default 3). ``--truth-starts``
also registers every case from the truth (``trustworthy.truth_start``): where that start is right
and reliable the data determine the pose to the tolerance, and a refusal of the cold answer
there is the search's miss; the table then counts the successes among those cases.

Usage: python benchmarks/structured_scenes.py [--jobs 2] [--draw N] [--cap N] [--out docs/structured_scenes.md]
       python benchmarks/structured_scenes.py --kinds furnished --repeats 6 --truth-starts [--draw N] --out docs/furnished_rooms.md
       python benchmarks/structured_scenes.py --quick   # the tables hall's 50 % crop, both ways -> build/
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # before numpy and pykdtree load

import functools
import sys
from collections import Counter
from typing import Any

from trustworthy import pose_determined, truth_start

from frisicp_bench import script
from frisicp_bench.metrics import pose_errors
from frisicp_bench.report import case_record, write_report, wrong_but_reliable
from frisicp_bench.structures import DIRECTIONS, KINDS, ROOMS, seeded_case
from frisicp_core import RegistrationConfig, register

TITLE = "Symmetric and repetitive scenes: crops both ways, default config, capped at {cap:,} points"
ROOMS_TITLE = "Furnished rooms without symmetry: crops both ways, default config, capped at {cap:,} points"
SHARES = (0.1, 0.3, 0.5)
REPEATS = 3
CAP = 10_000


def score(
    key: tuple[str, float, str, int], draw: int, cap: int = CAP, truth_starts: bool = False
) -> dict[str, Any]:
    """Build, register and score one case (deterministic in its key and ``draw``), both clouds
    capped at ``cap`` points; with ``truth_starts`` also from the truth."""
    kind, share, direction, repeat = key
    built, data, model = seeded_case(kind, share, direction, repeat, draw, cap)
    assert built.truth is not None
    result = register(data, model, RegistrationConfig())
    errors = pose_errors(result.similarity, built.truth, data, built.model_diagonal)
    extra = (
        {"truth_start": truth_start(data, model, built.truth, built.model_diagonal)} if truth_starts else {}
    )
    return case_record(
        errors,
        result,
        scene=kind,
        share=share,
        direction=direction,
        case=built.name,
        reason=result.reason,
        competitor_ratio=None if result.competitor is None else result.competitor.merit_ratio,
        **extra,
    )


def line(record: dict[str, Any]) -> str:
    verdict = "reliable" if record["reliable"] else record["reason"][:60]
    flag = "  WRONG AND RELIABLE" if record["reliable"] and not record["success"] else ""
    return (
        f"{record['direction']:15s} {record['case']:22s} {'ok  ' if record['success'] else 'FAIL'} "
        f"rot {record['rotation_deg']:7.2f} deg  scale {100 * record['scale_error']:7.2f} %  {verdict}{flag}"
    )


def refusal(reason: str) -> str:
    """What a refusal is counted as: ambiguous when its reason names a rival, else undetermined (a
    3 sigma past a tolerance), else unconverged, else a misfit (the fit checks)."""
    for word, name in (
        ("ambiguous", "ambiguous"),
        ("not determined", "undetermined"),
        ("converge", "unconverged"),
    ):
        if word in reason:
            return name
    return "misfit"


def main(argv: list[str] | None = None) -> int:
    quick = "the tables hall's 50 % crop, both directions"
    command = script.parser(__file__, __doc__, quick, report=True)
    command.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    command.add_argument("--draw", type=int, default=0, help="salt of every seed: fresh cases (default 0)")
    command.add_argument("--cap", type=int, default=CAP, help=f"points of each cloud at most (default {CAP})")
    command.add_argument(
        "--kinds",
        default=",".join(KINDS),
        help=f"comma-separated scenes of {', '.join(KINDS + ROOMS)} (default: the symmetric ones)",
    )
    command.add_argument(
        "--repeats",
        type=int,
        default=REPEATS,
        help=f"cases per kind, share and direction (default {REPEATS})",
    )
    command.add_argument(
        "--truth-starts",
        action="store_true",
        help="also register every case from the truth (determined or not)",
    )
    args = script.parse(command, argv)
    if args.cap < 1:
        command.error("--cap must be at least 1")
    if args.repeats < 1:
        command.error("--repeats must be at least 1")
    kinds = tuple(kind for kind in args.kinds.split(",") if kind)
    unknown = [kind for kind in kinds if kind not in KINDS + ROOMS]
    if unknown or not kinds:
        command.error(f"--kinds: unknown {unknown or 'none given'}; choose from {', '.join(KINDS + ROOMS)}")
    if args.quick:
        cases = [("tables", 0.5, direction, 0) for direction in DIRECTIONS]
    else:
        cases = [
            (kind, share, direction, repeat)
            for kind in kinds
            for direction in DIRECTIONS
            for share in SHARES
            for repeat in range(args.repeats)
        ]
    scored = functools.partial(score, draw=args.draw, cap=args.cap, truth_starts=args.truth_starts)
    records = script.map_cases(args, scored, cases, line)
    assert records is not None  # synthetic: no data to miss
    rows = []
    for kind in dict.fromkeys(r["scene"] for r in records):
        cells = []
        for direction in DIRECTIONS:
            group = [r for r in records if (r["scene"], r["direction"]) == (kind, direction)]
            refused = Counter(refusal(r["reason"]) for r in group if not r["reliable"])
            cells += [
                f"{sum(r['success'] for r in group)}/{len(group)} ({sum(r['success'] and r['reliable'] for r in group)})",
                str(wrong_but_reliable(group)),
                ", ".join(f"{n} {why}" for why, n in refused.most_common()) or "-",
            ]
            if args.truth_starts:
                determined = [r for r in group if pose_determined(r)]
                cells.append(f"{sum(r['success'] and r['reliable'] for r in determined)}/{len(determined)}")
        rows.append([kind, *cells])
    header = ["scene"]
    for direction in DIRECTIONS:
        header += [f"{direction}: right (reliable)", "wrong and reliable", "refused as"]
        if args.truth_starts:
            header.append("success where determined (truth start right, reliable)")
    summary = (
        f"**{wrong_but_reliable(records)} of {len(records)} results wrong and reliable**; "
        f"{sum(r['success'] for r in records)} right, {sum(r['success'] and r['reliable'] for r in records)} "
        f"of them reliable; {sum(r['reliable'] for r in records)} reliable in all"
        + (f" (draw {args.draw}: fresh cases)." if args.draw else ".")
    )
    title = (ROOMS_TITLE if set(kinds) <= set(ROOMS) else TITLE).format(cap=args.cap)
    write_report(args.out, title, script.command_line(args), summary, (header, rows), records)
    return 0


if __name__ == "__main__":
    sys.exit(main())
