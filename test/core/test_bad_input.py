"""Unusable input ends in a ValueError that names the problem, never a hang or a wrong answer."""

import numpy as np
import pytest

from frisicp_core import RegistrationConfig, bumpy_surface, register

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
        # Used to end in numpy's "Eigenvalues did not converge".
        (GOOD * 1e300, r"coordinates up to .*e\+300 overflow float64", "Eigenvalues"),
        (GOOD * 1e200, r"coordinates up to .*e\+200 overflow float64", "Eigenvalues"),
    ],
    ids=["far-outlier", "coordinates-1e300", "coordinates-1e200"],
)
def test_extreme_values_are_named_for_what_they_are(data, message, not_said):
    with pytest.raises(ValueError, match=message) as raised:
        register(data, GOOD)
    assert not_said not in str(raised.value)
    with pytest.raises(ValueError, match=message):
        register(GOOD, data)  # either side


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
    ],
)
def test_invalid_options_are_refused_with_a_reason(option):
    with pytest.raises(ValueError, match=r"."):  # any reason, but one
        RegistrationConfig(**option)


def test_initial_similarity_of_the_wrong_dimension():
    from frisicp_core import Similarity

    with pytest.raises(ValueError, match="2-D"):
        register(GOOD, GOOD, RegistrationConfig(initial=Similarity.identity(2)))
