"""The demo's data stream (frisicp-demo): what it shows must be what the core gets right."""

import numpy as np

from frisicp_core import bumpy_surface, register, rotation_angle
from frisicp_ros.node.demo import truth_at


def test_noisy_resampled_cold_starts_never_pick_a_flipped_pose():
    """Regression: the live demo's stream (a fresh noisy sample of the surface per frame, scale
    0.7-1.3, up to 25 deg) once got 180-degree flips when hypotheses were screened on too few points."""
    model = bumpy_surface(20000, seed=0)
    rng = np.random.default_rng(7)
    for k in range(10):
        truth = truth_at(0.5 * k)
        sample = bumpy_surface(5000, seed=int(rng.integers(1 << 30)))
        data = truth.inverse().apply(sample) + rng.normal(scale=0.005, size=sample.shape)
        estimate = register(data, model).similarity
        assert np.rad2deg(rotation_angle(estimate.rotation.T @ truth.rotation)) < 1.0, f"t = {0.5 * k}"
