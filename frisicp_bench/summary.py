"""Aggregates over records: success rates, medians, paper-style averages, speed ratios."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from .runner import BenchmarkRun, CaseRecord


def select(
    run: BenchmarkRun,
    *,
    family: str | None = None,
    method: str | None = None,
    kind: str | None = None,
    true_pose: bool | None = None,
) -> list[CaseRecord]:
    families = {f.name: f for f in run.families}
    return [
        r
        for r in run.records
        if (family is None or r.family == family)
        and (method is None or r.method == method)
        and (kind is None or families[r.family].kind == kind)
        and (true_pose is None or families[r.family].true_pose == true_pose)
    ]


def success_rate(records: Sequence[CaseRecord]) -> float:
    return sum(r.success for r in records) / len(records) if records else math.nan


def median(values: Iterable[float]) -> float:
    """Median ignoring NaN (failed runs); NaN when nothing is left."""
    finite = [v for v in values if v is not None and not math.isnan(v)]
    return float(np.median(finite)) if finite else math.nan


def fmt(value: float | None, spec: str = ".4g") -> str:
    """A number for a table; a dash for a missing one (NaN: nothing to report)."""
    return "—" if value is None or math.isnan(value) else format(value, spec)


def mean(values: Iterable[float]) -> float:
    finite = [v for v in values if v is not None and not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


@dataclass(frozen=True)
class SpeedComparison:
    """A baseline against FRISICP on one family: mean seconds per case and success rates.

    ``common_ratio`` compares only the cases both methods solve (equal accuracy): a baseline
    that gives up early on the cases it fails looks fast in the overall mean.
    """

    family: str
    frisicp: str  # the FRISICP configuration timed (MethodSpec.key)
    baseline: str
    frisicp_seconds: float
    baseline_seconds: float
    frisicp_success: float
    baseline_success: float
    common_ratio: float  # NaN when no case is solved by both
    common_cases: int

    @property
    def ratio(self) -> float:
        """How many times longer the baseline takes over all cases (> 1: FRISICP is faster)."""
        return self.baseline_seconds / self.frisicp_seconds

    @property
    def frisicp_wins(self) -> bool:
        """At equal or better success rate, faster on the cases both solve (all cases if none)."""
        faster = self.common_ratio > 1.0 if self.common_cases else self.ratio > 1.0
        return faster and self.frisicp_success >= self.baseline_success


def contender(
    run: BenchmarkRun, family: str, variants: Sequence[str] = ("frisicp", "frisicp-default")
) -> str:
    """The FRISICP configuration to time against the baselines on a family: the one with the
    highest success rate there (the paper's settings on a tie), so a speed ratio never pits a
    failing configuration against a failing baseline when a working one exists."""
    present = [k for k in variants if select(run, family=family, method=k)]
    return max(present, key=lambda k: (success_rate(select(run, family=family, method=k)), -present.index(k)))


def speed_comparisons(run: BenchmarkRun, family: str, frisicp: str | None = None) -> list[SpeedComparison]:
    frisicp = frisicp or contender(run, family)
    ours = select(run, family=family, method=frisicp)
    comparisons = []
    for method in run.methods:
        theirs = select(run, family=family, method=method.key)
        if method.key.startswith("frisicp") or not theirs:
            continue
        by_scale = {r.scale: r for r in theirs}
        common = [
            (r, by_scale[r.scale])
            for r in ours
            if r.success and r.scale in by_scale and by_scale[r.scale].success
        ]
        common_ratio = (
            (sum(b.seconds for _, b in common) / sum(a.seconds for a, _ in common)) if common else math.nan
        )
        comparisons.append(
            SpeedComparison(
                family,
                frisicp,
                method.key,
                mean(r.seconds for r in ours),
                mean(r.seconds for r in theirs),
                success_rate(ours),
                success_rate(theirs),
                common_ratio,
                len(common),
            )
        )
    return comparisons
