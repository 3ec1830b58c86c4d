"""The last refinement: bidirectional point-to-plane Gauss-Newton steps on the trimmed pairs.

Point-to-point ICP converges slowly along the surfaces and stops at its noise floor, and two
clouds that sample a surface differently pull it off the truth (the pairs' tangential offsets
do not average out on curved parts: a bias of a tenth of a degree on real scenes). The
point-to-plane residual r = n . (T(a) - b), with n the model's normal at b (Chen and Medioni
1992), ignores the tangential offsets. Once ICP has found the basin, a few Gauss-Newton steps on
the point-to-plane residuals of both directions' kept pairs, re-paired at every step, reach its
optimum (Censi 2007 and :mod:`frisicp_core.uncertainty` use the same residuals for the
covariance, so estimate and covariance describe one estimator).

A step solves H delta = -J^T r for the perturbation delta = (log-scale, rotation vector,
displacement) about the data centroid's image (the parametrisation of
:mod:`frisicp_core.uncertainty`), with a small Levenberg-Marquardt damping so that a direction
the clouds do not determine (a plane's slide) does not move. The forward pairs are the data
points and their nearest model points, the backward ones the model points and their nearest
data points, each direction trimmed by its estimated overlap (:mod:`frisicp_core.overlap`).
Both are sampled (at most :data:`MAX_PAIRS` per direction, evenly over the storage order) so a
large map costs what a sample of it costs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kdtree import NearestNeighbors
from .overlap import select_pairs
from .rotations import exp_rotation, log_rotation, vector_size
from .similarity import FloatArray, Similarity
from .uncertainty import NORMAL_NEIGHBOURS, Uncertainty, estimate_uncertainty, pair_jacobians

MAX_PAIRS = 20000
# Levenberg-Marquardt damping relative to the mean diagonal of H.
_DAMPING = 1e-9


@dataclass(frozen=True)
class PlanePairs:
    """Kept pairs of one pass in the model frame: T(a), b and the model's normal at b."""

    mapped: FloatArray
    targets: FloatArray
    normals: FloatArray

    @property
    def residuals(self) -> FloatArray:
        values: FloatArray = np.einsum("ni,ni->n", self.normals, self.mapped - self.targets)
        return values


class ModelNormals:
    """Unit normals of the model's points, computed when first asked for and kept."""

    def __init__(self, tree: NearestNeighbors) -> None:
        self.tree = tree
        self._normals = np.full(tree.points.shape, np.nan)

    def __getitem__(self, index: np.ndarray) -> FloatArray:
        missing = np.unique(index[np.isnan(self._normals[index, 0])])
        if missing.size:
            self._normals[missing] = _normals(self.tree, missing)
        values: FloatArray = self._normals[index]
        return values


def _normals(tree: NearestNeighbors, index: np.ndarray) -> FloatArray:
    _, neighbours = tree.query_k(tree.points[index], NORMAL_NEIGHBOURS)
    patches = tree.points[neighbours]
    centred = patches - patches.mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred))
    normals: FloatArray = vectors[:, :, 0]
    return normals


@dataclass(frozen=True)
class Sets:
    """The two clouds as the refinement sees them: points, trees, spacings, model normals
    (which may come from a larger cloud of the same surface: a half-sample borrows the whole
    model's normals through ``model_index``)."""

    data_tree: NearestNeighbors
    model_tree: NearestNeighbors
    data_spacing: float
    model_spacing: float
    normals: ModelNormals
    model_index: np.ndarray | None = None  # model point k is point model_index[k] of normals' cloud

    def model_normals(self, index: np.ndarray) -> FloatArray:
        return self.normals[index if self.model_index is None else self.model_index[index]]


def plane_pairs(sim: Similarity, sets: Sets, bidirectional: bool = True) -> PlanePairs:
    """The kept pairs of ``sim`` in both directions (sampled, see the module doc)."""
    data, model = sets.data_tree.points, sets.model_tree.points
    rows = _sample(data.shape[0])
    mapped = sim.apply(data[rows])
    forward_sq, forward_index = sets.model_tree.query(mapped)
    keep = select_pairs(forward_sq[None], np.array([sets.model_spacing**2]), None, None).keep[0]
    parts = [(mapped[keep], forward_index[keep])]
    if bidirectional:
        columns = _sample(model.shape[0])
        backward_sq, backward_index = sets.data_tree.query(sim.inverse().apply(model[columns]))
        backward_sq = backward_sq * sim.scale**2
        keep_back = select_pairs(
            backward_sq[None], np.array([(sets.data_spacing * sim.scale) ** 2]), None, None
        ).keep[0]
        parts.append((sim.apply(data[backward_index[keep_back]]), columns[keep_back]))
    index = np.concatenate([target for _, target in parts])
    return PlanePairs(
        np.concatenate([source for source, _ in parts]), model[index], sets.model_normals(index)
    )


def _sample(count: int) -> np.ndarray:
    return np.arange(0, count, max(1, -(-count // MAX_PAIRS)))


def perturb(sim: Similarity, delta: FloatArray, centre: FloatArray) -> Similarity:
    """exp(delta) applied on the left of ``sim`` about the model-frame point ``centre``
    (the parametrisation of :mod:`frisicp_core.uncertainty`)."""
    dim = sim.dim
    r = vector_size(dim)
    scale = float(np.exp(delta[0]))
    turn = exp_rotation(delta[1 : 1 + r], dim)
    return Similarity.about(centre, scale, turn, delta[1 + r :]) @ sim


def polish(
    sim: Similarity, sets: Sets, centroid: FloatArray, iterations: int = 3
) -> tuple[Similarity, PlanePairs]:
    """``iterations`` Gauss-Newton steps (module doc) from ``sim``; the pose reached and the
    pairs of its last pass. ``centroid`` is the data's centroid (data frame)."""
    pairs = plane_pairs(sim, sets)
    for _ in range(iterations):
        if pairs.mapped.shape[0] <= 1 + vector_size(sim.dim) + sim.dim:
            break
        centre = sim.apply(centroid)
        jacobians = pair_jacobians(pairs.mapped, pairs.normals, centre)
        hessian = jacobians.T @ jacobians
        hessian += _DAMPING * np.trace(hessian) / hessian.shape[0] * np.eye(hessian.shape[0])
        try:
            delta = -np.linalg.solve(hessian, jacobians.T @ pairs.residuals)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(delta)):
            break
        sim = perturb(sim, delta, centre)
        pairs = plane_pairs(sim, sets)
    return sim, pairs


def difference(a: Similarity, b: Similarity, centroid: FloatArray) -> FloatArray:
    """The perturbation taking ``b`` to ``a`` about where ``b`` puts the data centroid (to first
    order: log scale ratio, rotation vector of R_a R_b^T, displacement of the centroid)."""
    return np.concatenate(
        [
            [np.log(a.scale / b.scale)],
            log_rotation(a.rotation @ b.rotation.T),
            a.apply(centroid) - b.apply(centroid),
        ]
    )


def half_samples(sets: Sets, rng: np.random.Generator) -> tuple[Sets, Sets]:
    """Two disjoint random halves of both clouds, with their own trees and the model's normals."""
    data, model = sets.data_tree.points, sets.model_tree.points
    data_order, model_order = rng.permutation(data.shape[0]), rng.permutation(model.shape[0])
    halves = []
    for start in (0, 1):
        data_rows = np.sort(data_order[start::2])
        model_rows = np.sort(model_order[start::2])
        data_tree, model_tree = NearestNeighbors(data[data_rows]), NearestNeighbors(model[model_rows])
        base = model_rows if sets.model_index is None else sets.model_index[model_rows]
        halves.append(
            Sets(data_tree, model_tree, data_tree.spacing(), model_tree.spacing(), sets.normals, base)
        )
    return halves[0], halves[1]


# Random splits into halves that size the covariance (see uncertainty_of).
SPLITS = 3


def uncertainty_of(
    sim: Similarity, pairs: PlanePairs, sets: Sets, centroid: FloatArray, rng: np.random.Generator
) -> Uncertainty:
    """The covariance of the refined ``sim``: the sandwich estimate's shape
    (:func:`frisicp_core.uncertainty.estimate_uncertainty`), its size checked against the
    spread of the estimator itself.

    The sandwich alone came out two to three times too small on real scenes (re-sampled noisy
    crops of rs1: 8 noise realisations spread 0.04 degrees where it said 0.02): the estimator
    re-pairs, trims and fits normals to noisy points, none of which the linearisation sees. So
    the refinement is run again on :data:`SPLITS` random splits of both clouds into disjoint
    halves. The difference of the two half estimates has four times the variance of the full
    estimate (each half has twice its variance), so per block (scale, rotation, translation)
    ``kappa = mean ||delta_b||^2 / 4 / trace(Cov_b)``, and the block is scaled by
    ``max(1, kappa)``. A half that falls into another basin makes its block's spread, and the
    result's uncertainty, large: an answer that depends on which half of the points one
    looks at is not determined.
    """
    centre = sim.apply(centroid)
    sandwich = estimate_uncertainty(pairs.mapped, pairs.targets, pairs.normals, centre, rng)
    dim = sim.dim
    r = vector_size(dim)
    blocks = [slice(0, 1), slice(1, 1 + r), slice(1 + r, 1 + r + dim)]
    spreads = np.zeros(len(blocks))
    for _ in range(SPLITS):
        first, second = half_samples(sets, rng)
        delta = difference(polish(sim, first, centroid)[0], polish(sim, second, centroid)[0], centroid)
        spreads += [float(delta[block] @ delta[block]) / 4.0 / SPLITS for block in blocks]
    covariance = sandwich.covariance.copy()
    factors = np.ones(covariance.shape[0])
    for block, spread in zip(blocks, spreads, strict=True):
        trace = float(np.trace(covariance[block, block]))
        factors[block] = np.sqrt(max(1.0, spread / trace)) if trace > 0 else (np.inf if spread > 0 else 1.0)
    with np.errstate(invalid="ignore"):
        scaled = factors[:, None] * covariance * factors[None, :]
    return Uncertainty(np.where(np.isnan(scaled), np.inf, scaled), centre)
