"""FRISICP recovers isotropic scale, rotation and translation; the baselines behave as the paper says."""

import itertools

import numpy as np
import pytest
from support.bunny import bunny, scan_pose
from support.data import axis_rotation

from frisicp_core import (
    Initialization,
    Method,
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    bumpy_surface,
    closed_contour,
    register,
    rotation_angle,
)

PAPER_SCALES = [round(s, 1) for s in np.arange(0.1, 3.0, 0.2)]  # 0.1, 0.3, ..., 2.9


def errors(estimate: Similarity, truth: Similarity) -> tuple[float, float]:
    """(rotation error in degrees, relative scale error)."""
    rotation = np.rad2deg(rotation_angle(estimate.rotation.T @ truth.rotation))
    return rotation, abs(estimate.scale / truth.scale - 1.0)


def scaled_copy(model: np.ndarray, scale: float, degrees: float = 10.0) -> tuple[np.ndarray, Similarity]:
    """The paper's protocol: data = s R model + t. Returns data and the truth mapping data -> model."""
    dim = model.shape[1]
    forward = Similarity(scale, axis_rotation(dim, degrees), np.linspace(0.02, 0.06, dim))
    return forward.apply(model), forward.inverse()


SHAPES = {"3-D surface": bumpy_surface(3000, seed=1), "2-D contour": closed_contour(800)}


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("scale", PAPER_SCALES)
def test_paper_frisicp_recovers_every_scale(shape, scale):
    model = SHAPES[shape]
    data, truth = scaled_copy(model, scale)
    result = register(data, model, RegistrationConfig.paper())
    rotation_error, scale_error = errors(result.similarity, truth)
    assert rotation_error < 0.5
    assert scale_error < 0.005
    assert result.converged


@pytest.mark.parametrize("shape", SHAPES)
def test_default_config_recovers_large_rotations_and_scales(shape):
    model = SHAPES[shape]
    for scale, degrees in [(0.1, 60.0), (2.9, 120.0), (0.5, 170.0)]:
        data, truth = scaled_copy(model, scale, degrees)
        rotation_error, scale_error = errors(register(data, model).similarity, truth)
        assert rotation_error < 0.5 and scale_error < 0.005, (scale, degrees)


def test_forward_only_scale_icp_collapses_where_frisicp_does_not():
    """The paper's motivating failure: the forward term alone is minimised by shrinking the data."""
    model = SHAPES["3-D surface"]
    data, truth = scaled_copy(model, 0.1)  # data ten times smaller: the truth has s = 10
    zinsser = register(data, model, RegistrationConfig.paper(Method.SCALE_ICP)).similarity
    assert zinsser.scale < 0.1 * truth.scale  # collapsed towards s = 0
    frisicp = register(data, model, RegistrationConfig.paper()).similarity
    assert errors(frisicp, truth)[1] < 0.005


def test_rigid_icp_cannot_recover_a_scale():
    model = SHAPES["3-D surface"]
    data, _ = scaled_copy(model, 2.0)
    result = register(data, model, RegistrationConfig.paper(Method.ICP))
    assert result.similarity.scale == 1.0


def test_bounded_icp_keeps_the_scale_inside_its_covariance_bounds():
    model = SHAPES["2-D contour"]
    data, truth = scaled_copy(model, 1.5)
    result = register(data, model, RegistrationConfig.paper(Method.BOUNDED_ICP))
    assert errors(result.similarity, truth)[1] < 0.005


@pytest.mark.parametrize("dim", [2, 3, 4])
def test_works_in_any_dimension(dim):
    rng = np.random.default_rng(dim)
    model = rng.normal(size=(600, dim)) * np.linspace(1.0, 2.0, dim)
    model[:, 0] += 0.3 * model[:, 1] ** 2  # break the symmetry of the Gaussian blob
    truth = Similarity(0.6, np.eye(dim), np.full(dim, 0.1))
    result = register(
        truth.inverse().apply(model), model, RegistrationConfig(initialization=Initialization.MOMENTS)
    )
    assert errors(result.similarity, truth)[1] < 1e-6


def test_result_reports_errors_levels_and_history():
    model = SHAPES["3-D surface"]
    data, _ = scaled_copy(model, 0.7)
    result = register(data, model, RegistrationConfig(levels=3, coarsest_points=300))
    assert [level.data_points for level in result.levels][-1] == 3000
    assert result.levels[0].data_points == 300
    assert len(result.iterations) == 3 and sum(result.iterations) == len(result.history)
    # The errors are those of the last correspondence pass, before a final step that moved the
    # data by less than the convergence tolerance (1e-5 of the model's size): no extra pass.
    size = np.sqrt(((model - model.mean(axis=0)) ** 2).sum(axis=1).mean())
    assert max(result.rms, result.forward_rms, result.backward_rms) < 1e-5 * size
    assert result.fitness == 1.0 and result.overlap_forward == result.overlap_backward == 1.0
    seconds = [record.seconds for record in result.history]
    assert seconds == sorted(seconds) and result.seconds >= seconds[-1]


def test_initial_similarity_is_used_as_the_start():
    model = SHAPES["3-D surface"]
    data, truth = scaled_copy(model, 1.3)
    result = register(data, model, RegistrationConfig(initial=truth))
    assert sum(result.iterations) <= 3 * len(result.levels)
    assert errors(result.similarity, truth)[1] < 1e-9


def test_tracking_from_the_answer_costs_one_pass_per_level_and_screens_nothing():
    """A warm start skips the hypotheses and the thinned screening level: each level confirms
    the start with one pass."""
    model = SHAPES["3-D surface"]
    data, truth = scaled_copy(model, 1.3)
    result = register(data, model, RegistrationConfig(initial=truth))
    assert result.iterations == (1,) * RegistrationConfig().levels
    assert len(result.history) == RegistrationConfig().levels
    assert result.warm_started


def test_tracking_from_a_start_a_few_degrees_off_leaves_the_full_sets_one_or_two_passes():
    """The coarse dense level catches up with the start (its neighbours are exact, so the finer
    levels inherit no thinning bias); the full sets only confirm."""
    model = SHAPES["3-D surface"]
    data, truth = scaled_copy(model, 1.3)
    turn = axis_angle_rotation([0.2, 1.0, 0.3], np.deg2rad(2.0))
    start = Similarity(truth.scale * 1.02, turn @ truth.rotation, truth.translation)
    result = register(data, model, RegistrationConfig(initial=start))
    assert result.iterations[-1] <= 2
    assert errors(result.similarity, truth)[1] < 1e-9


def test_default_config_ignores_gross_outliers_and_estimates_their_share():
    rng = np.random.default_rng(7)
    model = SHAPES["3-D surface"]
    data, truth = scaled_copy(model, 0.4)
    clutter = rng.uniform(-3, 3, size=(300, 3)) * 0.4  # gross outliers around the data: 1 in 11 points
    result = register(np.vstack([data, clutter]), model)
    rotation_error, scale_error = errors(result.similarity, truth)
    assert rotation_error < 0.5 and scale_error < 0.005
    assert result.overlap_forward == pytest.approx(3000 / 3300, abs=0.03)
    assert result.overlap_backward == pytest.approx(1.0, abs=0.03)
    assert result.reliable, result.reason


@pytest.mark.real_data
@pytest.mark.parametrize("scale", [0.1, 0.9, 2.9])
def test_real_bunny_against_a_scaled_copy(scale):
    model = bunny("bun_zipper.ply")
    data, truth = scaled_copy(model, scale)
    result = register(data, model, RegistrationConfig.paper())
    rotation_error, scale_error = errors(result.similarity, truth)
    assert rotation_error < 0.5 and scale_error < 0.005


@pytest.mark.real_data
@pytest.mark.parametrize("scale", [0.3, 1.0, 2.5])
def test_real_partial_overlap_scan_pair(scale):
    """bun045 onto bun000: real scans, about 10 % of each without a counterpart, 34 deg apart."""
    model = bunny("bun000.ply")
    scan = bunny("bun045.ply")
    data = scale * scan
    truth = (
        scan_pose("bun000.ply").inverse()
        @ scan_pose("bun045.ply")
        @ Similarity(1 / scale, np.eye(3), np.zeros(3))
    )
    result = register(data, model, RegistrationConfig())
    rotation_error, scale_error = errors(result.similarity, truth)
    diagonal = np.linalg.norm(model.max(axis=0) - model.min(axis=0))
    translation_error = np.linalg.norm(result.similarity.translation - truth.translation) / diagonal
    assert rotation_error < 1.0
    assert scale_error < 0.01
    assert translation_error < 0.005


@pytest.mark.parametrize("acceleration", [False, True])
def test_error_never_increases_within_a_level(acceleration):
    """Plain ICP steps are monotone; accelerated proposals are kept only when they lower the error."""
    model = SHAPES["3-D surface"]
    data, _ = scaled_copy(model, 2.3, degrees=40.0)
    data = data + np.random.default_rng(2).normal(scale=0.01, size=data.shape)  # a noisy, slow problem
    result = register(data, model, RegistrationConfig(acceleration=acceleration, overlap=0.9))
    for level in range(len(result.levels)):
        errors_of_level = [r.rms for r in result.history if r.level == level]
        assert all(b <= a * (1 + 1e-12) for a, b in itertools.pairwise(errors_of_level))


@pytest.mark.real_data
def test_acceleration_needs_far_fewer_iterations_on_real_partial_overlap():
    """Point-to-point ICP crawls on real scans; extrapolated steps get there in fewer iterations.

    Measured down to the tight tolerance (no noise floor): that is where the crawl is long."""
    from frisicp_core import ConvergenceCriteria, downsample

    rng = np.random.default_rng(0)
    model = downsample(bunny("bun000.ply"), 10000, rng)
    scan = downsample(bunny("bun045.ply"), 10000, rng)
    truth = scan_pose("bun000.ply").inverse() @ scan_pose("bun045.ply")
    criteria = ConvergenceCriteria(noise_floor=False)
    plain = register(scan, model, RegistrationConfig(acceleration=False, criteria=criteria))
    fast = register(scan, model, RegistrationConfig(criteria=criteria))
    assert sum(fast.iterations) < 0.75 * sum(plain.iterations)
    for result in (plain, fast):
        rotation_error, scale_error = errors(result.similarity, truth)
        assert rotation_error < 0.5 and scale_error < 0.005


def test_iteration_cap_is_honoured_and_reported_as_not_converged():
    from frisicp_core import ConvergenceCriteria

    model = SHAPES["2-D contour"]
    data, _ = scaled_copy(model, 0.3, degrees=30.0)
    result = register(
        data, model, RegistrationConfig.paper(levels=1, criteria=ConvergenceCriteria(max_iterations=2))
    )
    assert result.iterations == (2,) and not result.converged


def test_du_scale_bounds_contain_the_true_scale():
    from frisicp_core.hypotheses import covariance_scale_bounds

    model = SHAPES["3-D surface"]
    for scale in PAPER_SCALES:
        data, truth = scaled_copy(model, scale)
        low, high = covariance_scale_bounds(data, model)
        assert low <= truth.scale <= high


def test_bounded_icp_from_the_paper_start_iterates_inside_its_bounds():
    """Regression: s = 1 lay outside Du's bounds at s_true = 10, and the run stopped after 1 iteration."""
    model = SHAPES["2-D contour"]
    data, truth = scaled_copy(model, 0.1)
    result = register(data, model, RegistrationConfig.paper(Method.BOUNDED_ICP))
    assert result.iterations[0] > 1
    assert errors(result.similarity, truth)[1] < 0.005
