"""Where does a warm start a few sigmas off a reliable answer come to rest? Default config.

The stated covariance (``RegistrationResult.uncertainty``) says how far the estimate may be off.
The estimator stops where its steps become smaller than their own noise (the noise floor of the
ICP levels and of the point-to-plane polish): where the re-paired, trimmed objective is flat over
more than the stated sigmas, it stops anywhere in that flat region, and where it stops depends on
where it came from. This measures how wide that resting region is, in the answer's own sigmas.

For every reliable cold answer of ``trustworthy.py``'s *frames* and *crop onto scene* cases (the
same cases, seeds and caps; the development scenes rs1, the bunny and the dragon, and cturtle,
which is never reliable), along the three longest axes of the answer's covariance (over log
scale, rotation vector and displacement of the data centroid's image), both ways: a warm start
(``RegistrationConfig(initial=...)``, as a tracked pose that far off would start) at Mahalanobis
distance 3 from the answer. Where it comes to rest is measured from the answer as the Mahalanobis
distance under the answer's covariance: about 1 or less when the data and the estimator pin the
pose to the stated sigmas (the start is pulled back), about 3 when the start is not pulled back
at all. A start that is not pulled back (rests more than 1.5 sigmas away) marks an answer whose
stated sigmas are narrower than the region the estimator may stop in.

Reported per suite and resolution: the reliable answers, their errors within three of their
sigmas (rotation / scale / translation, as ``trustworthy.py``), the median and largest resting
distance, the starts not pulled back, and how the answers with such a start and those without
are calibrated (within 3 sigma in every component).

Usage: python benchmarks/resting_region.py [--jobs 2] [--data DIR] [--out docs/resting_region.md]
       python benchmarks/resting_region.py --quick   # one capped rs1 frames case -> build/
Exits 0 without measuring when the data folder is absent, saying so.
"""

from __future__ import annotations

import os

os.environ["OMP_NUM_THREADS"] = "1"  # before numpy and pykdtree load

import functools
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from trustworthy import Spec, capped_case, specs, within_3_sigma

from frisicp_bench import script
from frisicp_bench.metrics import pose_errors
from frisicp_bench.report import write_report
from frisicp_core import RegistrationConfig, RegistrationResult, register
from frisicp_core.refine import difference, perturb

TITLE = "Where warm starts 3 sigmas off a reliable answer come to rest"
SUITES = ("frames", "crop onto scene")
START_SIGMAS = 3.0
AXES = 3
NOT_PULLED_BACK = 1.5


def rests(data: np.ndarray, model: np.ndarray, result: RegistrationResult) -> list[float]:
    """Mahalanobis distances from ``result`` (a reliable answer) at which warm starts
    :data:`START_SIGMAS` along the longest :data:`AXES` axes of its covariance, both ways, end."""
    assert result.uncertainty is not None
    covariance = result.uncertainty.covariance
    centroid = data.mean(axis=0)
    centre = result.similarity.apply(centroid)
    values, vectors = np.linalg.eigh(covariance)
    out = []
    for axis in range(len(values) - 1, len(values) - 1 - AXES, -1):
        for sign in (1.0, -1.0):
            step = sign * START_SIGMAS * np.sqrt(values[axis]) * vectors[:, axis]
            start = perturb(result.similarity, step, centre)
            rest = register(data, model, RegistrationConfig(initial=start)).similarity
            offset = difference(rest, result.similarity, centroid)
            out.append(float(np.sqrt(offset @ np.linalg.solve(covariance, offset))))
    return out


def score(spec: Spec, data_dir: Path) -> dict[str, Any]:
    """Build the case as ``trustworthy.py`` does, register it cold, and probe a reliable answer."""
    case, data, model, _ = capped_case(spec, data_dir)
    started = time.perf_counter()
    result = register(data, model)
    entry: dict[str, Any] = {
        "suite": spec.suite,
        "scene": spec.scene,
        "case": case.name,
        "cap": spec.cap or "full",
        "reliable": result.reliable,
    }
    if not result.reliable or case.truth is None or result.uncertainty is None:
        return entry
    errors = pose_errors(result.similarity, case.truth, data, case.model_diagonal)
    entry.update(
        right=errors.success,
        within_3_sigma=within_3_sigma(result, case.truth, errors, case.model_diagonal),
        rests=[round(value, 2) for value in rests(data, model, result)],
        seconds=round(time.perf_counter() - started, 2),
    )
    return entry


def summarise(records: list[dict[str, Any]]) -> tuple[list[str], list[list[object]]]:
    header = [
        "suite",
        "resolution",
        "reliable",
        "within 3 sigma (rot / scale / trans)",
        "rest median (sigmas)",
        "rest max (sigmas)",
        "starts not pulled back",
        "answers with one: within 3 sigma in all",
        "answers without: within 3 sigma in all",
    ]
    rows: list[list[object]] = []
    for suite in SUITES:
        for cap in sorted({str(e["cap"]) for e in records if e["suite"] == suite}):
            group = [e for e in records if e["suite"] == suite and str(e["cap"]) == cap and "rests" in e]
            if not group:
                continue
            distances = [value for e in group for value in e["rests"]]
            loose = [e for e in group if max(e["rests"]) > NOT_PULLED_BACK]
            pinned = [e for e in group if max(e["rests"]) <= NOT_PULLED_BACK]
            rows.append(
                [
                    suite,
                    "full" if cap == "full" else f"cap {int(cap):,}",
                    len(group),
                    " / ".join(str(sum(e["within_3_sigma"][k] for e in group)) for k in range(3)),
                    f"{statistics.median(distances):.2f}",
                    f"{max(distances):.1f}",
                    f"{sum(value > NOT_PULLED_BACK for value in distances)} of {len(distances)}",
                    f"{sum(all(e['within_3_sigma']) for e in loose)} of {len(loose)}",
                    f"{sum(all(e['within_3_sigma']) for e in pinned)} of {len(pinned)}",
                ]
            )
    return header, rows


def main(argv: list[str] | None = None) -> int:
    command = script.parser(__file__, __doc__, "one capped rs1 frames case", data=True, report=True)
    command.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    args = script.parse(command, argv)
    if not (args.data / "real").is_dir() or not (args.data / "bunny").is_dir():
        return script.skip(args, f"no data: {args.data}/real and {args.data}/bunny are needed")
    todo = [spec for spec in specs(quick=False) if spec.suite in SUITES]
    if args.quick:
        todo = [spec for spec in todo if spec.suite == "frames"][:1]
    records = script.map_cases(
        args,
        functools.partial(score, data_dir=args.data),
        todo,
        lambda entry: f"{entry['case']} {entry['cap']} {entry.get('rests')}",
    )
    if records is None:
        return 0
    header, rows = summarise(records)
    probed = [e for e in records if "rests" in e]
    loose = sum(max(e["rests"]) > NOT_PULLED_BACK for e in probed)
    summary = (
        f"{len(records)} cases, {len(probed)} reliable and probed with {AXES * 2} warm starts each"
        f" ({START_SIGMAS:g} sigmas along the covariance's {AXES} longest axes, both ways). {loose} of"
        f" them have a start that comes to rest more than {NOT_PULLED_BACK:g} of their sigmas away:"
        " there the estimator stops anywhere in a region wider than its stated sigmas say. Every"
        " case's resting distances in the JSON file beside this one."
    )
    write_report(args.out, TITLE, script.command_line(args), summary, (header, rows), records)
    return 0


if __name__ == "__main__":
    sys.exit(main())
