"""The descriptor search's triangle tests: the one-side screen never drops a triple they pass."""

import numpy as np

from frisicp_core.global_search import _may_agree, _sides


def test_the_one_side_screen_keeps_every_triple_the_full_tests_pass():
    rng = np.random.default_rng(0)
    source = rng.uniform(0.0, 1.0, (300, 3))
    rung, radius = 2.0, 0.05
    # Half the targets are the sources at the rung's scale, slightly disturbed: their triangles
    # agree, many just inside the tests' limits; the others are unrelated.
    target = np.where(
        (np.arange(300) % 2 == 0)[:, None],
        rung * source + rng.normal(scale=0.02, size=source.shape),
        rng.uniform(0.0, 20.0, source.shape),
    )
    triples = rng.integers(300, size=(50000, 3))
    sides_a, sides_b = _sides(source[triples]), _sides(target[triples])
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = sides_b / sides_a
        passes = ratios.max(axis=1) / ratios.min(axis=1) < 1.15
        passes &= np.abs(np.log(ratios.mean(axis=1) / rung)) < 0.5 * np.log(2.0)
    passes &= sides_a.min(axis=1) > radius
    kept = _may_agree(source, target, triples, rung, radius)
    assert passes.sum() > 1000
    assert not (passes & ~kept).any()
    assert kept.mean() < 0.5  # and it does screen
