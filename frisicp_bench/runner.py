"""Runs every (family, scale, method) case and scores it."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from frisicp_core import Similarity

from .cases import Case, Family, make_cases
from .methods import ConvergencePoint, MethodSpec
from .metrics import pose_errors, symmetric_rms


@dataclass(frozen=True)
class CaseRecord:
    """The score of one method on one case. Errors are NaN when the method returned nothing."""

    family: str
    scale: float
    method: str  # MethodSpec.key
    rotation_deg: float
    scale_error: float
    translation_error: float
    rms: float  # symmetric RMS in the model's units
    rms_ratio: float | None  # rms / the reference's RMS (different-shape families only)
    iterations: int  # -1: the method does not report it
    seconds: float
    converged: bool
    success: bool
    estimate: Similarity | None
    history: tuple[ConvergencePoint, ...]
    failure: str | None = None


@dataclass(frozen=True)
class BenchmarkRun:
    families: tuple[Family, ...]
    methods: tuple[MethodSpec, ...]
    cases: tuple[Case, ...]
    records: tuple[CaseRecord, ...]
    seed: int
    seconds: float = math.nan  # wall time of the whole run, filled in by the caller

    def case(self, family: str, scale: float) -> Case:
        return next(c for c in self.cases if c.family.name == family and c.scale == scale)

    def family(self, name: str) -> Family:
        return next(f for f in self.families if f.name == name)

    def method_label(self, key: str) -> str:
        return next(m.label for m in self.methods if m.key == key)


def score(case: Case, method: MethodSpec) -> CaseRecord:
    family = case.family
    data = case.data
    try:
        outcome = method.run(data, family.model)
    except (ValueError, FloatingPointError) as err:  # a method that gives up is a failed case, not a crash
        return _failed(case, method, str(err))
    if outcome.similarity is None:
        return _failed(case, method, outcome.failure or "no result", outcome.seconds)
    errors = pose_errors(outcome.similarity, case.truth, data, family.size)
    rms = symmetric_rms(outcome.similarity.apply(data), family.model)
    return CaseRecord(
        **_identity(case, method),
        rotation_deg=errors.rotation_deg,
        scale_error=errors.scale,
        translation_error=errors.translation,
        rms=rms,
        rms_ratio=rms / family.reference_rms if family.reference_rms else None,
        iterations=outcome.iterations,
        seconds=outcome.seconds,
        converged=outcome.converged,
        success=errors.success,
        estimate=outcome.similarity,
        history=outcome.history,
    )


def _failed(case: Case, method: MethodSpec, reason: str, seconds: float = math.nan) -> CaseRecord:
    no_result: dict[str, Any] = dict.fromkeys(
        ("rotation_deg", "scale_error", "translation_error", "rms"), math.nan
    )
    no_result.update(rms_ratio=None, iterations=0, converged=False, success=False, estimate=None, history=())
    return CaseRecord(**_identity(case, method), **no_result, seconds=seconds, failure=reason)


def _identity(case: Case, method: MethodSpec) -> dict[str, Any]:
    """Which case a record scores."""
    return {"family": case.family.name, "scale": case.scale, "method": method.key}


def run_benchmark(
    families: Sequence[Family],
    methods: Sequence[MethodSpec],
    scales: Sequence[float],
    seed: int,
    progress: Callable[[str], None] = lambda line: None,
) -> BenchmarkRun:
    cases: list[Case] = []
    records: list[CaseRecord] = []
    for family in families:
        applicable = [m for m in methods if family.dim in m.dims]
        for case in make_cases(family, tuple(scales), seed):
            cases.append(case)
            for method in applicable:
                record = score(case, method)
                records.append(record)
                progress(
                    f"{family.name:16s} s={case.scale:<4} {method.key:15s} "
                    f"{'ok  ' if record.success else 'FAIL'} rot {record.rotation_deg:8.3f} deg  "
                    f"scale {record.scale_error:9.2e}  rms {record.rms:9.4g}  {record.seconds:6.2f} s"
                )
    return BenchmarkRun(tuple(families), tuple(methods), tuple(cases), tuple(records), seed)
