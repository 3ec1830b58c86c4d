"""An initial guess (a rough pose and its sigmas) bounds the cold search: it finds answers the
blind search misses, and a result outside the guess's region is not reliable."""

from __future__ import annotations

import numpy as np
import pytest

from frisicp_core import RegistrationConfig, Similarity, axis_angle_rotation, bumpy_surface, register
from frisicp_core.config import InitialGuess
from frisicp_core.hypotheses import beyond_guess, guess_hypotheses


def crop_of_surface() -> tuple[np.ndarray, np.ndarray]:
    """A 30 % strip of a bumpy surface, re-sampled with 0.3 % noise, and the whole surface."""
    model = bumpy_surface(20000, seed=3)
    crop = model[model[:, 0] < np.quantile(model[:, 0], 0.3)]
    rng = np.random.default_rng(7)
    crop = crop[rng.choice(len(crop), 3000, replace=False)] + rng.normal(scale=0.003, size=(3000, 3))
    return crop, model


def test_a_guess_finds_a_turned_crop_without_a_blind_search() -> None:
    crop, model = crop_of_surface()
    truth = Similarity(2.0, axis_angle_rotation([0.2, 0.3, 1.0], np.deg2rad(150.0)), [0.3, -0.2, 1.0])
    data = truth.inverse().apply(crop)
    rough = Similarity(1.0, axis_angle_rotation([0.2, 0.3, 1.0], np.deg2rad(158.0)), [0.4, -0.2, 1.0])
    guided = register(data, model, RegistrationConfig(guess=InitialGuess(rough, 5.0, 0.1, scale=None)))
    error = guided.similarity @ truth.inverse()
    assert np.degrees(error.rotation_angle()) < 0.5
    assert abs(np.log(guided.similarity.scale / 2.0)) < 0.01


def test_an_unknown_scale_is_searched_and_a_known_one_is_not() -> None:
    guess = Similarity(3.0, np.eye(3), np.zeros(3))
    unknown = guess_hypotheses(InitialGuess(guess, 0.0, 0.0, scale=None), ratio=0.5, dim=3)
    known = guess_hypotheses(InitialGuess(guess, 0.0, 0.0, scale=0.01), ratio=0.5, dim=3)
    assert [len(f) for f in unknown] == [1, 13]
    assert unknown[0][0].scale == 0.5  # an unknown scale starts at the radius ratio
    assert [len(f) for f in known] == [1] and known[0][0].scale == 3.0
    turned = guess_hypotheses(InitialGuess(guess, 10.0, 0.5, scale=0.01), ratio=0.5, dim=3)
    assert [len(f) for f in turned] == [1, 6, 6]
    angles = [np.degrees(Similarity(1.0, s.rotation, s.translation).rotation_angle()) for s in turned[1]]
    assert angles == pytest.approx([20.0] * 6)


def test_a_result_beyond_three_sigmas_of_the_guess_is_named() -> None:
    guess = InitialGuess(
        Similarity(1.0, np.eye(3), np.zeros(3)), rotation_deg=2.0, translation=0.1, scale=0.01
    )
    inside = Similarity(1.02, axis_angle_rotation([0, 0, 1], np.deg2rad(6.0)), [0.2, 0.0, 0.0])
    assert beyond_guess(guess, inside, model_radius=1.0) == ""
    outside = Similarity(1.2, axis_angle_rotation([0, 0, 1], np.deg2rad(20.0)), [1.0, 0.0, 0.0])
    reason = beyond_guess(guess, outside, model_radius=1.0)
    assert "20 deg from the guess's rotation" in reason
    assert "1 from the guess's position" in reason
    assert "scale 1.2" in reason
