"""benchmarks/widening.py replays the verdict at other widening factors: only a refusal for 3 sigma
alone can turn, and it turns when the scaled 3 sigma fall within the tolerances the refusal names."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[2] / "benchmarks"))

import widening  # a script of benchmarks/, found through the path above

SAME = np.ones(3)  # factors over the used ones: (scale, rotation, translation)
NARROWER_SCALE = np.array([0.8, 1.0, 1.0])


def record(
    case: str, reliable: bool, right: bool, reason: str, rotation_deg: float = 0.1, scale_sigma: float = 0.003
) -> dict[str, Any]:
    """A trustworthy.py record: sigmas of 0.3 % scale (unless given), 0.2 deg, 0.001 (diagonal 1)."""
    return {
        "case": case,
        "reliable": reliable,
        "right": right,
        "reason": reason,
        "sigma": {"scale": scale_sigma, "rotation_deg": 0.2, "translation": 0.001},
        "rotation_deg": rotation_deg,
        "log_scale_error": 0.006,
        "translation_error": 0.002,
        "model_diagonal": 1.0,
    }


SCALE_ONLY = "not determined to the tolerance: 3 sigma of the scale is 1.2% (tolerance 1%)"
RECORDS = [
    record("reliable", True, True, ""),
    record("refused for its scale's 3 sigma", False, True, SCALE_ONLY, scale_sigma=0.004),
    record(
        "a misfit",
        False,
        True,
        "the clouds do not coincide where they meet; " + SCALE_ONLY,
        scale_sigma=0.004,
    ),
    record(
        "wrong, refused for its scale's 3 sigma",
        False,
        False,
        SCALE_ONLY,
        rotation_deg=1.5,
        scale_sigma=0.004,
    ),
    {"case": "a sphere", "reliable": False, "reason": "ambiguous", "sigma": {}},  # no answer exists
]


def test_only_results_with_their_own_sigmas_are_read_with_their_ratios_and_limits() -> None:
    results, wrong_reliable = widening.local_results("example", RECORDS)
    assert [r.case for r in results] == [RECORDS[k]["case"] for k in (0, 1, 3)]
    assert wrong_reliable == 0
    np.testing.assert_allclose(results[0].ratios, [2.0, 0.5, 2.0])  # scale, rotation, translation
    np.testing.assert_allclose(results[1].limits, [0.01, 1.0, 0.005])  # the refusal's and the defaults


def test_a_refusal_for_3_sigma_turns_reliable_where_the_scaled_3_sigma_fit() -> None:
    results, _ = widening.local_results("example", RECORDS)
    refused = results[1]  # its scale's 3 sigma 1.2 %, the tolerance 1 %
    assert not refused.reliable_at(SAME)
    assert refused.reliable_at(NARROWER_SCALE)  # 0.96 %
    reliable = results[0]
    assert reliable.reliable_at(np.array([0.5, 0.5, 0.5]))  # narrower sigmas keep it reliable
    assert not reliable.reliable_at(np.array([1.0, 2.0, 6.0]))  # 3 sigma of translation 0.018 > 0.005


def test_the_replay_counts_a_wrong_answer_turned_reliable() -> None:
    results, wrong_now = widening.local_results("example", RECORDS)
    assert widening.replay_row("example", results, wrong_now, SAME)[1:5] == [1, 1, 0, 0]
    row = widening.replay_row("example", results, wrong_now, NARROWER_SCALE)
    # successes now and replayed, wrong and reliable now and replayed, replayed within 3 sigma
    assert row[1:5] == [1, 2, 0, 1]
    assert row[5] == "2 / 3 / 3 of 3"  # rotation / scale / translation: the wrong one is 7.5 sigma off
