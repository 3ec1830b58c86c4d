"""Where the iterations may start: the initial hypotheses that ``register`` screens.

ICP only finds the nearest local minimum, so a cold start tries several poses and keeps the
one whose short run on the coarsest level reaches the lowest error. The candidates
(``RegistrationConfig.initialization``):

- *moments*: centroids aligned, scale = ratio of the RMS radii, R = I. Right for full overlap
  with the frames roughly aligned.
- *principal axes*: the same centroid and scale, R mapping the data's principal axes onto the
  model's, one hypothesis per sign pattern with det R = +1 (the moments leave the axes' signs
  open). Right for full overlap at any rotation.
- *in place* (``search``): the data left where it is (R = I, its centroid fixed) at the scales
  ``ratio * 2^k``, k in :data:`IN_PLACE_OCTAVES`. With partial overlap centroids and radii
  mislead: a scan's centroid is not its map's, and its radius is that of the part it saw. Frames
  that are roughly aligned (a scan in a map, two sensors, the usual robotics case) are not.
- *turned in place* (``search``): the data in place at the radius ratio, turned by
  :data:`IN_PLACE_TURN` either way in each coordinate plane (6 poses in 3-D, 2 in 2-D). "Roughly
  aligned" frames are often tens of degrees apart, and a partial scan's basin is narrow: from the
  starts above, a bunny scan of ``frisicp bench`` (turned up to 30 degrees) ended 14-25 degrees
  off with two of six random thinnings. A start turned part of the way brings it into reach.
"""

from __future__ import annotations

import itertools

import numpy as np

from .config import Initialization, Method, RegistrationConfig
from .points import centroid, rms_radius
from .similarity import FloatArray, Similarity

# Scales of the in-place hypotheses, in octaves around the RMS-radius ratio: a part of a surface
# has an RMS radius between about a quarter and all of the whole's, so the ratio misses the true
# scale by up to a factor of a few in either direction (scan onto map, map onto scan).
IN_PLACE_OCTAVES = tuple(k / 2 for k in range(-6, 7))
# Turn of the turned in-place hypotheses, in radians (see benchmarks/turned_frames.py for the
# turns they reach).
IN_PLACE_TURN = np.deg2rad(30.0)


def principal_axes(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Centroid, covariance eigenvalues (descending) and eigenvectors (columns, same order)."""
    mean = centroid(points)
    centred = points - mean
    eigval, eigvec = np.linalg.eigh(centred.T @ centred / points.shape[0])
    return mean, eigval[::-1], eigvec[:, ::-1]


def radius_ratio(data: FloatArray, model: FloatArray) -> float:
    """Model RMS radius over data RMS radius: the scale if the two sets overlap fully."""
    return rms_radius(model) / rms_radius(data)


def initial_hypotheses(
    data: FloatArray,
    model: FloatArray,
    config: RegistrationConfig,
    scale_bounds: tuple[float, float] | None,
) -> list[list[Similarity]]:
    """The starting poses for ``config``, in families: poses of one family differ in one
    parameter (the sign pattern of the principal axes, the scale), so the screening compares
    them with each other first. One pose for a warm start or a single-pose initialization."""
    dim = data.shape[1]
    if config.initial is not None:
        if config.initial.dim != dim:
            raise ValueError(f"initial similarity is {config.initial.dim}-D but the points are {dim}-D")
        families = [[config.initial]]
    elif config.initialization is Initialization.IDENTITY:
        families = [[Similarity.identity(dim)]]
    else:
        ratio = radius_ratio(data, model)
        mu_d, mu_m = centroid(data), centroid(model)
        scale = 1.0 if config.method is Method.ICP else ratio

        def centred(rotation: FloatArray) -> Similarity:
            return Similarity(scale, rotation, mu_m - scale * rotation @ mu_d)

        families = [[centred(np.eye(dim))]]
        if config.initialization in (Initialization.PRINCIPAL_AXES, Initialization.SEARCH):
            families.append([centred(rotation) for rotation in _principal_axes_rotations(data, model)])
        if config.initialization is Initialization.SEARCH and config.method is not Method.ICP:
            scales = [ratio * 2.0**k for k in IN_PLACE_OCTAVES]
            families.append([Similarity.about(mu_d, s, np.eye(dim)) for s in scales])
            families.append([Similarity.about(mu_d, ratio, r) for r in plane_rotations(dim, IN_PLACE_TURN)])
    if scale_bounds is not None:
        # Du's method must start inside its bounds: from outside, the first clipped step can raise
        # the error, which the loop would take for convergence after one iteration.
        families = [
            [Similarity(float(np.clip(g.scale, *scale_bounds)), g.rotation, g.translation) for g in family]
            for family in families
        ]
    return families


def plane_rotations(dim: int, angle: float) -> list[FloatArray]:
    """The rotations by +-``angle`` in each coordinate plane (about each axis in 3-D)."""
    rotations = []
    for i, j in itertools.combinations(range(dim), 2):
        for turn in (angle, -angle):
            rotation = np.eye(dim)
            rotation[[i, i, j, j], [i, j, i, j]] = (np.cos(turn), -np.sin(turn), np.sin(turn), np.cos(turn))
            rotations.append(rotation)
    return rotations


def _principal_axes_rotations(data: FloatArray, model: FloatArray) -> list[FloatArray]:
    """The 2^(m-1) proper rotations mapping the data's principal axes onto the model's."""
    _, _, vec_d = principal_axes(data)
    _, _, vec_m = principal_axes(model)
    dim = data.shape[1]
    rotations = []
    for signs in itertools.product((1.0, -1.0), repeat=dim - 1):
        flip = np.array((*signs, 1.0))
        rotation = (vec_m * flip) @ vec_d.T
        if np.linalg.det(rotation) < 0:
            flip[-1] = -1.0
            rotation = (vec_m * flip) @ vec_d.T
        rotations.append(rotation)
    return rotations


def covariance_scale_bounds(data: FloatArray, model: FloatArray) -> tuple[float, float]:
    """Scale interval for Du et al.'s bounded-scale ICP, from the covariance eigenvalues.

    With eigenvalues lambda of the data (A) and model (B) covariances, any similarity
    B = s R A + t satisfies lambda_B = s^2 lambda_A axis by axis, so
    ``sqrt(min lambda_B / max lambda_A) <= s <= sqrt(max lambda_B / min lambda_A)``.
    """
    _, val_d, _ = principal_axes(data)
    _, val_m, _ = principal_axes(model)
    floor = np.finfo(float).tiny
    low = float(np.sqrt(max(val_m[-1], floor) / max(val_d[0], floor)))
    high = float(np.sqrt(max(val_m[0], floor) / max(val_d[-1], floor)))
    return low, high
