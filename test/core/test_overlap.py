"""Which pairs enter the estimate: trimmed ICP's overlap estimate, per direction."""

import numpy as np
import pytest

from frisicp_core.overlap import MIN_FRACTION, select_pairs, select_within


def residuals(inliers: int, outliers: int, seed: int = 0) -> np.ndarray:
    """Squared distances of one direction: inliers at the noise level, outliers spread far out."""
    rng = np.random.default_rng(seed)
    near = rng.rayleigh(0.01, inliers)
    far = rng.uniform(0.1, 1.0, outliers)
    return np.concatenate([near, far])[None, :] ** 2


@pytest.mark.parametrize("share", [0.15, 0.3, 0.65, 1.0])
def test_the_estimated_overlap_is_the_share_of_pairs_at_the_noise_level(share):
    """Outliers 10-100 times the inliers' RMS. (The smaller the overlap, the farther the rest
    must lie: psi keeps a share xi only when e(1) / e(xi) > xi^-3, e.g. 100x the RMS at 10 %.)"""
    count = 4000
    dist_sq = residuals(int(share * count), count - int(share * count))
    selection = select_pairs(dist_sq, np.zeros(1), overlap=None, max_distance=None)
    assert selection.fraction[0] == pytest.approx(share, abs=0.03)
    assert selection.keep[0, : int(share * count)].mean() > 0.97  # the inliers are the ones kept


def test_pairs_closer_than_the_target_spacing_are_always_kept():
    """A map that contains some of the scan's own points: exact matches must not be mistaken
    for the whole overlap."""
    rng = np.random.default_rng(1)
    exact = np.zeros(400)
    within_spacing = rng.uniform(0.0, 0.01, 1200)
    dist_sq = np.concatenate([exact, within_spacing, rng.uniform(0.2, 1.0, 2400)])[None, :] ** 2
    without_floor = select_pairs(dist_sq, np.zeros(1), overlap=None, max_distance=None)
    with_floor = select_pairs(dist_sq, np.array([0.01**2]), overlap=None, max_distance=None)
    assert with_floor.fraction[0] == pytest.approx(0.4, abs=0.02)
    assert without_floor.fraction[0] < with_floor.fraction[0]


def test_never_fewer_than_the_smallest_share():
    dist_sq = np.random.default_rng(2).uniform(0.0, 1.0, (1, 1000))
    assert select_pairs(dist_sq, np.zeros(1), None, None).fraction[0] >= MIN_FRACTION


def test_a_fixed_overlap_keeps_that_share_and_one_keeps_all():
    dist_sq = residuals(700, 300)
    assert select_pairs(dist_sq, np.zeros(1), overlap=0.5, max_distance=None).fraction[0] == 0.5
    every = select_pairs(dist_sq, np.zeros(1), overlap=1.0, max_distance=None)
    assert every.keep.all() and every.merit[0] == pytest.approx(dist_sq.mean())


def test_gating_drops_pairs_far_beyond_the_median():
    dist_sq = residuals(900, 100)
    gated = select_pairs(dist_sq, np.zeros(1), overlap=1.0, max_distance=3.0)
    assert gated.fraction[0] == pytest.approx(0.9, abs=0.02)


def test_several_poses_are_selected_independently():
    dist_sq = np.vstack([residuals(300, 700, seed=3), residuals(800, 200, seed=4)])
    selection = select_pairs(dist_sq, np.zeros(2), overlap=None, max_distance=None)
    np.testing.assert_allclose(selection.fraction, [0.3, 0.8], atol=0.03)


def test_distances_known_only_below_a_bound_select_exactly_the_same_pairs():
    """A bounded query leaves the far pairs unknown (inf); where the cut falls below the bound
    the selection and its merit are those of the full distances, to the last bit, and where
    it would fall beyond, the row says so."""
    crop = residuals(300, 700, seed=5)  # 30 % at the noise level, the rest 10-100 times farther
    spread = np.random.default_rng(6).uniform(0.0, 1.0, (1, 1000)) ** 2  # no knee: a cut far out
    dist_sq = np.vstack([crop, spread])
    bound_sq = np.array([0.3**2, 0.3**2])
    unknown = np.where(dist_sq < bound_sq[:, None], dist_sq, np.inf)
    full = select_pairs(dist_sq, np.zeros(2), None, None)
    selection, exact = select_within(unknown, np.zeros(2), bound_sq)
    assert exact.tolist() == [True, False]
    np.testing.assert_array_equal(selection.keep[0], full.keep[0])
    assert selection.merit[0] == full.merit[0] and selection.sum_sq[0] == full.sum_sq[0]
    assert full.fraction[1] > 0.5  # what the bounded row could not have known
