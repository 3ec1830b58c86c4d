"""How certain a registration is: the covariance of the similarity, and its 1-sigma summary.

**Parameters.** A similarity T near the estimate is written as a perturbation
xi = (log-scale sigma, rotation vector w, displacement d) about the centre c, the image of the
data's centroid in the model frame:

    T_xi(a) = c + e^sigma exp(sum_k w_k G_k) (T(a) - c) + d

(G_k the generators of :mod:`frisicp_core.rotations`; in 3-D, w is a rotation vector about the
model frame's axes). About the centroid the blocks are nearly uncorrelated, and d is the
uncertainty of *where the data lands*; the translation t of the similarity itself (the image of
the data frame's origin, far from the data in a map frame) is had with :meth:`Uncertainty.at`.
The covariance is (p, p), p = 1 + m(m - 1)/2 + m, in the order (sigma, w, d): 7 x 7 in 3-D,
4 x 4 in 2-D.

**Model** (Censi 2007, "An accurate closed-form estimate of ICP's covariance", for
point-to-plane residuals; Bonnabel, Barczyk and Goulette 2016): each pair (a, b) of the final
pass, forward and backward alike, gives a point-to-plane residual r = n . (T(a) - b), n the
model's unit normal at b (:class:`frisicp_core.refine.ModelNormals`). Its Jacobian with respect to xi is

    J = [n . y,  (n . G_k y)_k,  n],   y = T(a) - c,

and H = sum J^T J are the normal equations. A direction along which the clouds may slide (a
plane, a sphere turning, a corridor) adds nothing to H, so the covariance grows without bound
there: degeneracy shows as uncertainty (Zhang and Singh 2016 read it off H's eigenvalues).

**Correlated residuals.** Censi's closed form, sigma^2 H^-1, treats the residuals as
independent and is known to be over-confident: neighbouring pairs share the sensor's artefacts
and the two samplings' offsets, so a structured scene leaves errors that are smooth over the
surface. The covariance here is the cluster-robust ("sandwich") estimator (Liang and Zeger
1986; Cameron and Miller 2015):

    Cov = g/(g - 1) H^-1 (sum_b u_b u_b^T) H^-1,   u_b = sum_{i in b} J_i^T r_i,

with the pairs grouped into g spatial blocks (cells of a grid in the model frame, sized so that
about :data:`_TARGET_BLOCKS` are occupied). Residuals correlated within a block add up in u_b
instead of averaging out, which is what they do to the estimate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rotations import generators, vector_size
from .similarity import FloatArray, Similarity

# Standard deviations a stated uncertainty must cover: a result is reliable only when this many
# lie within the tolerances (frisicp_core.verdict), and an undetermined answer's prior spans the
# whole range in this many (Uncertainty.undetermined).
SIGMAS = 3.0
# Neighbours whose covariance gives a point's surface normal. Fewer leave the normals of a noisy
# cloud noisy, and a noisy model's normals bias the point-to-plane estimate and hide part of its
# spread (two noisy views of rs1, 8 noise draws: 10 neighbours biased the scale 0.22 % and made
# the split halves miss 1.5x of the spread; 40: 0.11-0.17 % and 1.0-1.2x).
NORMAL_NEIGHBOURS = 40
# Spatial blocks of the sandwich estimator: enough for the sum over blocks to estimate a p x p
# covariance (p = 7 in 3-D), few enough that each spans many correlated pairs.
_TARGET_BLOCKS = 64
# Pairs the covariance is computed from (a random subset above this; see estimate_uncertainty).
_MAX_PAIRS = 20000


@dataclass(frozen=True)
class Uncertainty:
    """The covariance of a registration's similarity and 1-sigma summaries of it.

    ``covariance`` is over (log-scale, rotation vector, displacement of ``centre``) as in the
    module doc; ``centre`` is the model-frame point the displacement refers to (by default the
    image of the data's centroid).
    """

    covariance: FloatArray
    centre: FloatArray
    # How much the sandwich estimate was widened, per parameter (frisicp_core.refine.uncertainty_of):
    # measured by split halves on a cold start, reused while tracking the same scene.
    widening: FloatArray | None = None

    @property
    def dim(self) -> int:
        return int(self.centre.shape[0])

    @property
    def scale(self) -> float:
        """1-sigma relative error of the scale (sigma of log s, ~ sigma_s / s)."""
        return float(np.sqrt(max(self.covariance[0, 0], 0.0)))

    @property
    def rotation_deg(self) -> float:
        """1-sigma rotation error in degrees, about the worst-determined axis."""
        r = vector_size(self.dim)
        return float(np.degrees(np.sqrt(_largest_eigenvalue(self.covariance[1 : 1 + r, 1 : 1 + r]))))

    @property
    def translation(self) -> float:
        """1-sigma error of where ``centre`` lands, in model units, along the worst direction."""
        m = self.dim
        return float(np.sqrt(_largest_eigenvalue(self.covariance[-m:, -m:])))

    def at(self, point: FloatArray) -> Uncertainty:
        """The same uncertainty with the displacement referring to the model-frame ``point``.

        A model-frame point q moves by sigma (q - c) + sum_k w_k G_k (q - c) + d under the
        perturbation, so the covariance is carried over by that linear map.
        """
        q = np.asarray(point, dtype=np.float64).reshape(-1)
        m, r = self.dim, vector_size(self.dim)
        offset = q - self.centre
        carry = np.eye(1 + r + m)
        carry[-m:, 0] = offset
        carry[-m:, 1 : 1 + r] = np.einsum("kij,j->ik", generators(m), offset)
        covariance: FloatArray = carry @ self.covariance @ carry.T
        return Uncertainty(covariance, q, self.widening)

    def including(self, offset: FloatArray) -> Uncertainty:
        """This uncertainty with a second answer ``offset`` away (a perturbation in this
        covariance's parameters, about the same centre) counted as one standard deviation along
        it: covariance + offset offset^T. Where the data fit two poses as well
        (:mod:`frisicp_core.near_probes`), the truth may be either, or anywhere between: one
        sigma spanning the two says so, where the covariance at one of them cannot."""
        d = np.asarray(offset, dtype=np.float64).reshape(-1)
        return Uncertainty(self.covariance + np.outer(d, d), self.centre, self.widening)

    @classmethod
    def undetermined(
        cls,
        answer: Similarity,
        centre: FloatArray,
        scale_range: tuple[float, float],
        model_bounds: tuple[FloatArray, FloatArray],
        data_reach: float,
    ) -> Uncertainty:
        """The uncertainty of an ``answer`` the data do not determine: the clouds do not fit
        there, or another distinct pose fits as well (:class:`frisicp_core.verdict.Verdict`'s
        ``determined``). Its local covariance describes the neighbourhood of a pose that may be
        anywhere, so the honest statement is the prior over every pose the answer could be
        instead: :data:`SIGMAS` sigmas span every rotation (180 deg), every scale in
        ``scale_range`` (the plausible interval, :data:`frisicp_core.verdict.SCALE_RANGE` about
        the clouds' size ratio) and every place the data's centroid may land while some of the
        data lies in the model's bounding box ``model_bounds`` (low, high corners): the box's
        farthest corner plus ``data_reach`` (the data's largest distance from its centroid)
        at the largest plausible scale, each from the answer. A fusing filter reads it as
        "no information"; :attr:`RegistrationResult.competitor` names the rival pose when there
        is one. Diagonal in the module doc's parameters, about ``centre``."""
        c = np.asarray(centre, dtype=np.float64).reshape(-1)
        m, r = c.shape[0], vector_size(c.shape[0])
        low, high = (np.asarray(corner, dtype=np.float64).reshape(-1) for corner in model_bounds)
        with np.errstate(divide="ignore"):  # a scale of 0 or inf (hostile input): an infinite prior
            log_scale = max(abs(np.log(answer.scale / bound)) for bound in scale_range) / SIGMAS
        farthest_corner = float(np.linalg.norm(np.maximum(np.abs(c - low), np.abs(c - high))))
        landing = farthest_corner + max(scale_range) * data_reach
        sigmas = np.concatenate([[log_scale], np.full(r, np.pi / SIGMAS), np.full(m, landing / SIGMAS)])
        return cls(np.diag(sigmas**2), c)

    def pose_covariance(self, similarity: Similarity) -> FloatArray:
        """The 6 x 6 covariance of the pose (R, t) in ROS's order (x, y, z, roll, pitch, yaw).

        The position is the similarity's translation t (the image of the data frame's origin),
        the rotation is about the model frame's fixed axes (as ``geometry_msgs/PoseWithCovariance``
        defines it, to first order). The scale's own variance is ``scale**2`` (not part of a pose).
        In 2-D, x, y and yaw are filled and z, roll and pitch are zero.
        """
        at_origin = self.at(similarity.translation)
        m, r = self.dim, vector_size(self.dim)
        if m == 3:
            order = [1 + r + k for k in range(3)] + [1, 2, 3]
            pose: FloatArray = at_origin.covariance[np.ix_(order, order)]
            return pose
        if m == 2:
            pose = np.zeros((6, 6))
            rows = [0, 1, 5]
            source = [2, 3, 1]
            pose[np.ix_(rows, rows)] = at_origin.covariance[np.ix_(source, source)]
            return pose
        raise ValueError(f"a ROS pose covariance exists only in 2-D and 3-D, not {m}-D")


def _largest_eigenvalue(block: FloatArray) -> float:
    if not np.all(np.isfinite(block)):
        return float("inf")
    return float(max(np.linalg.eigvalsh(block)[-1], 0.0))


def pair_jacobians(mapped: FloatArray, normals: FloatArray, centre: FloatArray) -> FloatArray:
    """(n, p) Jacobians of the point-to-plane residuals n . (T(a) - b) with respect to xi (module
    doc), for data points already mapped into the model frame (``mapped`` = T(a))."""
    m = mapped.shape[1]
    y = mapped - centre
    turned = np.einsum("kij,nj->nki", generators(m), y)  # G_k y
    rotation = np.einsum("nki,ni->nk", turned, normals)
    scale = np.einsum("ni,ni->n", normals, y)
    jacobians: FloatArray = np.concatenate([scale[:, None], rotation, normals], axis=1)
    return jacobians


def estimate_uncertainty(
    mapped: FloatArray,
    targets: FloatArray,
    normals: FloatArray,
    centre: FloatArray,
    rng: np.random.Generator,
) -> Uncertainty:
    """The sandwich covariance (module doc) from pairs ``mapped`` = T(a) -> ``targets`` = b with
    the model's normals at b, about ``centre``.

    At most :data:`_MAX_PAIRS` pairs are used (a random subset): a subset of correlated pairs
    estimates the same spread, and of independent ones a larger one, never a smaller one.
    """
    count = mapped.shape[0]
    if count > _MAX_PAIRS:
        keep = rng.choice(count, size=_MAX_PAIRS, replace=False)
        mapped, targets, normals = mapped[keep], targets[keep], normals[keep]
    m = mapped.shape[1]
    p = 1 + vector_size(m) + m
    residuals = np.einsum("ni,ni->n", normals, mapped - targets)
    jacobians = pair_jacobians(mapped, normals, centre)
    hessian = jacobians.T @ jacobians
    blocks = _blocks(mapped)
    scores = np.zeros((int(blocks.max()) + 1, p))
    np.add.at(scores, blocks, jacobians * residuals[:, None])
    groups = scores.shape[0]
    meat = scores.T @ scores * (groups / max(groups - 1, 1))
    try:
        inverse = np.linalg.inv(hessian)
    except np.linalg.LinAlgError:
        inverse = np.full((p, p), np.inf)
    covariance = inverse @ meat @ inverse
    covariance = 0.5 * (covariance + covariance.T)
    return Uncertainty(covariance, np.array(centre, dtype=np.float64))


def _blocks(points: FloatArray) -> np.ndarray:
    """Block label of every point: grid cells coarsened until about :data:`_TARGET_BLOCKS` are
    occupied (a surface fills cells in proportion to the square of their count per axis)."""
    low = points.min(axis=0)
    span = float((points.max(axis=0) - low).max()) or 1.0
    cells_per_axis = 2
    labels = np.zeros(points.shape[0], dtype=np.int64)
    while cells_per_axis <= 1024:
        cells = np.minimum(((points - low) / span * cells_per_axis).astype(np.int64), cells_per_axis - 1)
        key = cells @ (cells_per_axis ** np.arange(points.shape[1], dtype=np.int64))
        _, labels = np.unique(key, return_inverse=True)
        if labels.max() + 1 >= _TARGET_BLOCKS:
            break
        cells_per_axis *= 2
    return labels.reshape(-1)
