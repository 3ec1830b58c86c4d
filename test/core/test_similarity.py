"""Similarity algebra and the closed-form estimator."""

import numpy as np
import pytest
from support.data import random_rotation

from frisicp_core import Similarity, estimate_similarity, rotation_angle


@pytest.mark.parametrize("dim", [2, 3, 4])
def test_compose_inverse_and_matrix_agree(dim):
    rng = np.random.default_rng(dim)
    a = Similarity(2.5, random_rotation(dim, rng), rng.normal(size=dim))
    b = Similarity(0.3, random_rotation(dim, rng), rng.normal(size=dim))
    pts = rng.normal(size=(20, dim))
    np.testing.assert_allclose((a @ b).apply(pts), a.apply(b.apply(pts)), atol=1e-12)
    np.testing.assert_allclose(a.inverse().apply(a.apply(pts)), pts, atol=1e-12)
    homogeneous = np.c_[pts, np.ones(20)] @ a.matrix().T
    np.testing.assert_allclose(homogeneous[:, :dim], a.apply(pts), atol=1e-12)
    back = Similarity.from_matrix(a.matrix())
    assert back.scale == pytest.approx(2.5)
    np.testing.assert_allclose(back.rotation, a.rotation, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_about_a_point_scales_and_turns_around_it_then_shifts(dim):
    rng = np.random.default_rng(7)
    centre, shift, rotation = rng.normal(size=dim), rng.normal(size=dim), random_rotation(dim, rng)
    pts = rng.normal(size=(10, dim))
    moved = Similarity.about(centre, 1.7, rotation, shift)
    np.testing.assert_allclose(
        moved.apply(pts), 1.7 * (pts - centre) @ rotation.T + centre + shift, atol=1e-12
    )
    np.testing.assert_allclose(Similarity.about(centre, 1.7, rotation).apply(centre), centre, atol=1e-12)


def test_quaternion_round_trip_uses_ros_order_xyzw():
    quarter_turn_about_z = Similarity.from_quaternion(
        1.0, [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)], [0, 0, 0]
    )
    np.testing.assert_allclose(quarter_turn_about_z.apply([1.0, 0, 0]), [0, 1, 0], atol=1e-12)
    rng = np.random.default_rng(0)
    for _ in range(50):
        rot = random_rotation(3, rng)
        q = Similarity(1.0, rot, np.zeros(3)).quaternion()
        assert q[3] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)
        np.testing.assert_allclose(Similarity.from_quaternion(1.0, q, np.zeros(3)).rotation, rot, atol=1e-9)


@pytest.mark.parametrize(
    "bad",
    [
        dict(scale=0.0),
        dict(scale=-1.0),
        dict(scale=np.nan),
        dict(rotation=np.diag([1.0, 1.0, -1.0])),
        dict(rotation=2 * np.eye(3)),
        dict(translation=[0.0, 0.0]),
    ],
)
def test_invalid_similarities_are_refused(bad):
    args = dict(scale=1.0, rotation=np.eye(3), translation=np.zeros(3)) | bad
    with pytest.raises(ValueError, match=r"."):  # any reason, but one
        Similarity(**args)


@pytest.mark.parametrize("dim", [2, 3, 5])
@pytest.mark.parametrize("seed", range(5))
def test_estimate_similarity_is_exact_on_noise_free_pairs(dim, seed):
    rng = np.random.default_rng(seed)
    truth = Similarity(rng.uniform(0.05, 20), random_rotation(dim, rng), rng.normal(size=dim) * 10)
    x = rng.normal(size=(30, dim))
    est = estimate_similarity(x, truth.apply(x))
    assert est.scale == pytest.approx(truth.scale, rel=1e-10)
    assert rotation_angle(est.rotation.T @ truth.rotation) < 1e-7
    np.testing.assert_allclose(est.translation, truth.translation, atol=1e-8 * truth.scale * 10)


def test_estimate_similarity_never_returns_a_reflection():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(40, 3))
    mirrored = x * np.array([1.0, 1.0, -1.0])
    est = estimate_similarity(x, mirrored)
    assert np.linalg.det(est.rotation) == pytest.approx(1.0)


def test_weights_select_the_pairs_that_count():
    rng = np.random.default_rng(4)
    truth = Similarity(1.7, random_rotation(3, rng), [1.0, 2.0, 3.0])
    x = rng.normal(size=(50, 3))
    y = truth.apply(x)
    y[:10] += rng.normal(size=(10, 3)) * 5  # outliers
    weights = np.r_[np.zeros(10), np.ones(40)]
    est = estimate_similarity(x, y, weights)
    assert est.scale == pytest.approx(1.7, rel=1e-10)


def test_fixed_and_bounded_scale():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(30, 3))
    y = 3.0 * x
    assert estimate_similarity(x, y, with_scale=False).scale == 1.0
    assert estimate_similarity(x, y, scale_bounds=(0.5, 2.0)).scale == pytest.approx(2.0)


def test_symmetric_scale_makes_swapping_the_sets_give_the_inverse():
    """Horn's symmetric scale: the fit of y onto x is exactly the inverse of x onto y, even with
    noise (Umeyama's scale is not: it shrinks towards the noisier side)."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(200, 3))
    y = Similarity(2.0, random_rotation(3, rng), [1.0, 2.0, 3.0]).apply(x) + rng.normal(0, 0.3, (200, 3))
    forward = estimate_similarity(x, y, symmetric=True)
    backward = estimate_similarity(y, x, symmetric=True)
    np.testing.assert_allclose((forward @ backward).matrix(), np.eye(4), atol=1e-9)
    umeyama = estimate_similarity(x, y) @ estimate_similarity(y, x)
    assert abs(umeyama.scale - 1.0) > 1e-3


def test_the_rotation_vector_is_scipys_to_the_last_bit_whatever_the_check_it_skips():
    """log_rotation skips scipy's orthonormality check for a rotation well within it; the
    vectors are still scipy's own, and a matrix that is not a rotation takes scipy's full path."""
    from scipy.spatial.transform import Rotation

    from frisicp_core.rotations import log_rotation

    turns = Rotation.random(200, random_state=3).as_matrix()
    products = turns @ Rotation.random(200, random_state=4).as_matrix().transpose(0, 2, 1)
    for matrix in products:
        np.testing.assert_array_equal(log_rotation(matrix), Rotation.from_matrix(matrix).as_rotvec())
    skewed = products[0] * 1.001  # re-fitted to a rotation by scipy
    np.testing.assert_array_equal(log_rotation(skewed), Rotation.from_matrix(skewed).as_rotvec())
    with pytest.raises(ValueError, match="determinant"):
        log_rotation(-products[0])
