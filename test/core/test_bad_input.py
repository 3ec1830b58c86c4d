"""Unusable input ends in a ValueError that names the problem, never a hang or a wrong answer."""

import numpy as np
import pytest

from frisicp_core import (
    RegistrationConfig,
    Similarity,
    axis_angle_rotation,
    bumpy_surface,
    register,
    rotation_angle,
)

GOOD = bumpy_surface(500)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (np.empty((0, 3)), "empty"),
        (GOOD[:3], "too few"),
        (np.ones((50, 3)), "identical"),
        (np.outer(np.linspace(0, 1, 50), [1.0, 2.0, 3.0]), "collinear"),
        (np.zeros(10), "shape"),
        (np.ones((10, 1)), "at least 2 coordinates"),
        ([["a", "b", "c"]] * 5, "numeric"),
    ],
)
def test_unusable_data_is_named(data, message):
    with pytest.raises(ValueError, match=message):
        register(data, GOOD)


def with_outlier(points: np.ndarray, at: float) -> np.ndarray:
    far = points.copy()
    far[7] = [at, 0.0, 0.0]
    return far


@pytest.mark.parametrize(
    ("data", "message", "not_said"),
    [
        # One far point used to be reported as "collinear"; the rest of the cloud is fine.
        (with_outlier(GOOD, 1e30), r"one point is 1e\+30 away from the others.*an outlier", "collinear"),
        # So far away that the other points' squared distances vanish below float64's range.
        (with_outlier(GOOD, 1e300), r"one point is 1e\+300 away from the others.*an outlier", "collinear"),
        # Used to be "all points are identical" (the real parts of these are all 0) after a warning.
        (GOOD * 1j, "complex numbers are not coordinates", "identical"),
    ],
    ids=["far-outlier", "outlier-at-1e300", "complex"],
)
def test_extreme_values_are_named_for_what_they_are(data, message, not_said):
    with pytest.raises(ValueError, match=message) as raised:
        register(data, GOOD)
    assert not_said not in str(raised.value)
    with pytest.raises(ValueError, match=message):
        register(GOOD, data)  # either side


TURN = Similarity(1.5, axis_angle_rotation((0.2, 0.3, 1.0), 0.5), [0.2, -0.1, 0.3])


@pytest.mark.parametrize(
    ("data_exponent", "model_exponent"),
    [(80, 0), (0, 80), (-150, 150), (200, 200), (-300, -300), (300, 0)],
)
def test_clouds_in_any_finite_units_register(data_exponent, model_exponent):
    """The data in units 1e80 times the model's ended in an IndexError; both clouds at 1e200
    were refused as overflowing, both at 1e-300 called "all points are identical"."""
    data_unit, model_unit = 10.0**data_exponent, 10.0**model_exponent
    result = register(GOOD * data_unit, TURN.apply(GOOD) * model_unit)
    assert result.reliable and result.converged, result.reason
    assert result.similarity.scale / (1.5 * model_unit / data_unit) == pytest.approx(1.0, abs=1e-9)
    assert rotation_angle(result.similarity.rotation.T @ TURN.rotation) < 1e-6
    np.testing.assert_allclose(result.similarity.translation / model_unit, TURN.translation, atol=1e-9)
    assert result.rms / model_unit < 1e-9  # an exact copy: errors (in the model's units) about 0


def test_clouds_whose_scale_is_beyond_float64_are_refused_with_the_reason():
    with pytest.raises(ValueError, match=r"about 1e-600 times the data's: the scale .* beyond float64"):
        register(GOOD * 1e300, GOOD * 1e-300)


@pytest.mark.filterwarnings("error::RuntimeWarning")  # and no numpy overflow warning on the way
@pytest.mark.parametrize(("scale", "backend"), [(1e200, "pykdtree"), (1e-200, "scipy")])
def test_a_warm_start_that_throws_the_points_out_of_float64_range_is_survived(backend, scale):
    """Squared distances past 1.8e308 made the KD-trees return no neighbour (index 2**32 - 1 or n),
    and the registration an IndexError."""
    start = Similarity(scale, np.eye(3), np.zeros(3))
    result = register(GOOD, GOOD * 2.0, RegistrationConfig(initial=start, backend=backend))
    assert result.reliable and result.similarity.scale == pytest.approx(2.0, rel=1e-9)


def test_a_degenerate_cloud_with_an_outlier_is_still_called_degenerate():
    line = np.outer(np.linspace(0, 1, 50), [1.0, 2.0, 3.0])
    line[3] = [1e30, 5.0, 0.0]
    with pytest.raises(ValueError, match="collinear"):
        register(line, GOOD)


def test_collinear_points_in_2d_are_degenerate():
    line = np.column_stack([np.linspace(0, 1, 20), np.linspace(0, 2, 20)])
    with pytest.raises(ValueError, match="collinear"):
        register(line, line)


def test_a_planar_patch_in_3d_is_accepted():
    rng = np.random.default_rng(0)
    patch = np.column_stack([rng.uniform(size=(300, 2)) * [2.0, 1.0], np.zeros(300)])
    patch[:, 2] = 0.0
    result = register(patch, patch)
    assert result.similarity.scale == pytest.approx(1.0, abs=1e-6)


def test_mismatched_dimensions():
    with pytest.raises(ValueError, match="coordinates per point"):
        register(GOOD[:, :2], GOOD)


def test_nan_rows_are_refused_unless_dropping_was_asked_for():
    data = GOOD.copy()
    data[::50] = np.nan
    data[1, 2] = np.inf
    with pytest.raises(ValueError, match="11 of 500 points contain NaN or Inf"):
        register(data, GOOD)
    result = register(data, GOOD, RegistrationConfig(drop_nonfinite=True))
    assert result.similarity.scale == pytest.approx(1.0, abs=1e-3)  # 489 of 500 points remain


def test_all_nan_is_empty_after_dropping():
    with pytest.raises(ValueError, match="empty after dropping"):
        register(np.full((20, 3), np.nan), GOOD, RegistrationConfig(drop_nonfinite=True))


@pytest.mark.parametrize(
    "option",
    [
        dict(overlap=0.0),
        dict(overlap=1.5),
        dict(levels=0),
        dict(max_distance=-1.0),
        dict(coarsest_points=1),
        dict(method="gauss-newton"),
        dict(initialization="random"),
        dict(backend="flann"),
        dict(seed=-1),
        dict(seed=0.5),
    ],
)
def test_invalid_options_are_refused_with_a_reason(option):
    with pytest.raises(ValueError, match=r"."):  # any reason, but one
        RegistrationConfig(**option)


def test_initial_similarity_of_the_wrong_dimension():
    from frisicp_core import Similarity

    with pytest.raises(ValueError, match="2-D"):
        register(GOOD, GOOD, RegistrationConfig(initial=Similarity.identity(2)))
