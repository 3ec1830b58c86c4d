"""The uncertainty's widening per block, from trust reports: error / sigma, and the verdicts under other factors.

    python benchmarks/widening.py                         # docs/trustworthy*.json -> docs/widening.md
    python benchmarks/widening.py --widening 2.25,2.25,2.25   # replay the verdicts at other factors
    python benchmarks/widening.py --quick                 # the first 40 records of one report -> build/

:func:`frisicp_core.refine.uncertainty_of` widens each block of a result's covariance (scale,
rotation, translation) by :data:`frisicp_core.refine.WIDENING`, the smallest factor per block that
keeps ``--quantile`` (99) % of the development results within three sigmas in that block. This
reads ``benchmarks/trustworthy.py``'s JSON reports, run on a core with the factors ``--used``
(default: the current ``refine.WIDENING``; the records do not say), and takes the results with an
uncertainty of their own: reliable, or refused only because three sigmas exceed a tolerance (every
clause of the reason is the verdict's "not determined to the tolerance"). Any other refusal states
the prior (``Uncertainty.undetermined``), which no factor touches. Per report and for the
development and held-out groups it prints the 95th, 98th and 99th percentile of |error| / sigma
per block (rotation angle, |log scale|, the data centroid's offset: what ``within_3_sigma``
compares), how many reliable results lie within three sigmas, and the factor that would put the group's quantile at
three sigmas: used x percentile / 3.

The replay (``--widening S,R,T``, scale, rotation, translation): every such result's sigmas scaled
by the proposed factor over the used one. A result becomes or stays reliable when every scaled
three sigmas lies within its tolerance (read from the refusal's own clauses where it has them,
else the defaults, rotation 1 deg, scale 1 %, translation 0.5 % of the case's model diagonal;
the verdict's diagonal is the model it saw, a capped or windowed one, so a reliable result that
a widening would push to its translation tolerance is an estimate). The other checks do not
depend on the factor, nor does the pose (but for the warm start's retry, which reads the
track's uncertainty), so this predicts the successes, the wrong-and-reliable results and the
calibration of a core with those factors; rerun the reports to confirm. Records written before
trustworthy.py kept ``log_scale_error`` and ``model_diagonal`` cannot be read: rerun them.
"""

from __future__ import annotations

import argparse
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from trustworthy import DEVELOPMENT_REPORTS, HELD_OUT_REPORTS, REPORTS_DIR, sigma_ratios

from frisicp_bench import script
from frisicp_bench.report import markdown_table, write_report
from frisicp_core import Tolerance
from frisicp_core.refine import WIDENING
from frisicp_core.uncertainty import SIGMAS
from frisicp_core.verdict import UNDETERMINED

TITLE = "The uncertainty's widening per block: error / sigma on the trust reports"
BLOCKS = ("scale", "rotation", "translation")  # refine.WIDENING's order
# Shown as trustworthy.py's reports show them: rotation / scale / translation.
_SHOWN = (1, 0, 2)
PERCENTILES = (95.0, 98.0, 99.0)
_CLAUSE = re.compile(
    UNDETERMINED + f": {SIGMAS:g}" + r" sigma of the (scale|rotation|translation) is ([0-9.eE+-]+)(?:deg|%)? "
    r"\(tolerance ([0-9.eE+-]+)"
)
_DEFAULT_TOLERANCE = Tolerance()  # RegistrationConfig's, which the reports ran with
_QUICK_RECORDS = 40


@dataclass(frozen=True)
class Local:
    """A result with an uncertainty of its own: its |error| / sigma per block and what the verdict
    compared its three sigmas with (rotation in degrees, scale relative, translation in model units)."""

    report: str
    case: str
    reliable: bool
    right: bool
    ratios: np.ndarray  # |error| / sigma, BLOCKS order
    three_sigma: np.ndarray
    limits: np.ndarray

    def reliable_at(self, factors: np.ndarray) -> bool:
        """The verdict with every block's sigma scaled by ``factors`` (proposed / used)."""
        if self.reliable and np.all(factors <= 1.0):
            return True
        return bool(np.all(self.three_sigma * factors <= self.limits))


def local_results(name: str, records: list[dict[str, Any]]) -> tuple[list[Local], int]:
    """The records with an uncertainty of their own and a known answer, and how many records
    were reliable and wrong (with or without: the replay cannot turn those)."""
    out: list[Local] = []
    wrong_reliable = 0
    for entry in records:
        wrong_reliable += bool(entry["reliable"]) and not entry.get("right", False)
        sigma = entry.get("sigma")
        if sigma is None or "rotation_deg" not in entry:
            continue  # no uncertainty, or no answer exists (unrelated objects)
        # Rotation / scale / translation -> BLOCKS order (the swap is its own inverse).
        ratios = np.array(sigma_ratios(name, entry))[list(_SHOWN)]
        clauses = [c.strip() for c in entry["reason"].split(";") if c.strip()]
        if not entry["reliable"] and not all(c.startswith(UNDETERMINED) for c in clauses):
            continue
        diagonal = float(entry["model_diagonal"])
        limits = {
            "rotation": _DEFAULT_TOLERANCE.rotation_deg,
            "scale": _DEFAULT_TOLERANCE.scale,
            "translation": _DEFAULT_TOLERANCE.translation * diagonal,
        }
        for block, _, limit in _CLAUSE.findall(entry["reason"]):
            limits[block] = float(limit) / (100.0 if block == "scale" else 1.0)
        sigmas = np.array([sigma["scale"], sigma["rotation_deg"], sigma["translation"]])
        out.append(
            Local(
                name,
                entry["case"],
                bool(entry["reliable"]),
                bool(entry["right"]),
                ratios,
                SIGMAS * sigmas,
                np.array([limits[b] for b in BLOCKS]),
            )
        )
    return out, wrong_reliable


def shown(values: np.ndarray, form: str) -> str:
    """Per-block figures in the trust reports' order (rotation / scale / translation)."""
    return " / ".join(form.format(values[k]) for k in _SHOWN)


def summary_row(label: str, results: list[Local], used: np.ndarray, quantile: float) -> list[object]:
    """Percentiles of |error| / sigma per block over ``results`` (every result with sigmas of its
    own), the reliable ones' count within three sigmas, and the factors that would put the
    ``quantile`` of the ratios at three sigmas."""
    reliable = np.array([r.ratios for r in results if r.reliable]).reshape(-1, 3)
    every = np.array([r.ratios for r in results]).reshape(-1, 3)
    row: list[object] = [label, len(every), len(reliable)]
    for p in PERCENTILES:
        row.append(shown(np.percentile(every, p, axis=0), "{:.2f}") if len(every) else "-")
    within = (reliable <= SIGMAS).sum(axis=0)
    row.append(shown(within, "{}") + f" of {len(reliable)}")
    factors = used * np.percentile(every, quantile, axis=0) / SIGMAS if len(every) else None
    row.append(shown(factors, "{:.2f}") if factors is not None else "-")
    return row


def replay_row(label: str, results: list[Local], wrong_now: int, factors: np.ndarray) -> list[object]:
    """Successes, wrong-and-reliable results and calibration now and with ``factors`` (proposed / used)."""
    now = [r for r in results if r.reliable]
    then = [r for r in results if r.reliable_at(factors)]
    within = np.array([r.ratios / factors <= SIGMAS for r in then]).reshape(-1, 3).sum(axis=0)
    wrong_then = wrong_now - sum(not r.right for r in now) + sum(not r.right for r in then)
    return [
        label,
        sum(r.right for r in now),
        sum(r.right for r in then),
        wrong_now,
        wrong_then,
        shown(within, "{}") + f" of {len(then)}",
    ]


def parse_factors(text: str) -> np.ndarray:
    """Three positive factors from "S,R,T" (scale, rotation, translation: refine.WIDENING's order)."""
    values = np.array([float(v) for v in text.split(",")])
    if values.shape != (3,) or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise argparse.ArgumentTypeError(f"three positive factors (scale,rotation,translation), got {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    parser = script.parser(__file__, __doc__, "the first 40 records of docs/trustworthy.json", report=True)
    parser.add_argument(
        "--reports", type=Path, default=REPORTS_DIR, metavar="DIR", help="where the reports' JSON are (docs/)"
    )
    parser.add_argument(
        "--development", default=",".join(DEVELOPMENT_REPORTS), help="report names (tuned on)"
    )
    parser.add_argument("--held-out", default=",".join(HELD_OUT_REPORTS), help="report names (checked on)")
    parser.add_argument(
        "--quantile", type=float, default=99.0, help="the share kept within 3 sigma (default 99)"
    )
    default_used = ",".join(f"{w:g}" for w in WIDENING)
    parser.add_argument(
        "--used",
        type=parse_factors,
        default=parse_factors(default_used),
        help=f"the reports' factors ({default_used})",
    )
    parser.add_argument(
        "--widening", type=parse_factors, default=None, help="factors to replay, e.g. 2.25,2.25,2.25"
    )
    args = script.parse(parser, argv)
    groups = {"development": args.development.split(","), "held-out": args.held_out.split(",")}
    if args.quick:
        groups = {"development": [DEVELOPMENT_REPORTS[0]], "held-out": []}
    proposed = args.widening if args.widening is not None else args.used
    factors = proposed / args.used
    per_group: dict[str, list[Local]] = {}
    wrong: dict[str, int] = {}
    stats_rows: list[list[object]] = []
    replay_rows: list[list[object]] = []
    records_out: list[dict[str, Any]] = []
    for group, names in groups.items():
        per_group[group] = []
        wrong[group] = 0
        for name in names:
            path = args.reports / f"{name}.json"
            if not path.is_file():
                return script.skip(args, f"no report {path}: run benchmarks/trustworthy.py first")
            records = json.loads(path.read_text())["records"]
            if args.quick:
                records = records[:_QUICK_RECORDS]
            results, wrong_reliable = local_results(name, records)
            per_group[group] += results
            wrong[group] += wrong_reliable
            stats_rows.append(summary_row(name, results, args.used, args.quantile))
            replay_rows.append(replay_row(name, results, wrong_reliable, factors))
            records_out += [
                {
                    "report": r.report,
                    "case": r.case,
                    "reliable": r.reliable,
                    "right": r.right,
                    "ratios_scale_rotation_translation": [round(float(x), 3) for x in r.ratios],
                    "reliable_replayed": r.reliable_at(factors),
                }
                for r in results
            ]
        if names:
            stats_rows.append(summary_row(f"**{group}**", per_group[group], args.used, args.quantile))
            replay_rows.append(replay_row(f"**{group}**", per_group[group], wrong[group], factors))
    header = [
        "report",
        "results with own sigmas",
        "reliable",
        *(f"p{p:g} of error / sigma (rot / scale / trans)" for p in PERCENTILES),
        "reliable within 3 sigma (rot / scale / trans)",
        f"factors putting p{args.quantile:g} at 3 sigma (rot / scale / trans)",
    ]
    replay = markdown_table(
        [
            "report",
            "successes",
            "replayed",
            "wrong and reliable",
            "replayed",
            "replayed reliable within 3 sigma (rot / scale / trans)",
        ],
        replay_rows,
    )
    summary = (
        f"Factors used by the reports: {' / '.join(f'{w:g}' for w in args.used)} (scale / rotation /"
        f" translation); replayed: {' / '.join(f'{w:g}' for w in proposed)}. The replay (the script's"
        " docstring) predicts each result's verdict at those factors:\n\n"
        + "\n".join(replay)
        + "\n\nPer report, over the results with an uncertainty of their own:"
    )
    write_report(args.out, TITLE, script.command_line(args), summary, (header, stats_rows), records_out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
