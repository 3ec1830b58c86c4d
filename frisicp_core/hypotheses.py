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

from .config import InitialGuess, Initialization, Method, RegistrationConfig
from .points import centroid, rms_radius
from .similarity import FloatArray, Similarity, rotation_angle

# Scales of the in-place hypotheses, in octaves around the RMS-radius ratio: a part of a surface
# has an RMS radius between about a quarter and all of the whole's, so the ratio misses the true
# scale by up to a factor of a few in either direction (scan onto map, map onto scan).
IN_PLACE_OCTAVES = tuple(k / 2 for k in range(-6, 7))
# Turn of the turned in-place hypotheses, in radians (see benchmarks/turned_frames.py for the
# turns they reach).
IN_PLACE_TURN = np.deg2rad(30.0)
# An initial guess is searched within this many of its sigmas, and a result beyond them (plus the
# verdict's tolerances) is not reliable: the guess says the answer is not there.
GUESS_SIGMAS = 3.0


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
    elif config.guess is not None:
        families = guess_hypotheses(config.guess, radius_ratio(data, model), dim)
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


def guess_hypotheses(guess: InitialGuess, ratio: float, dim: int) -> list[list[Similarity]]:
    """Starting poses around an initial guess, in families: the guess itself; when its scale is
    unknown, the guess at the scales ``ratio * 2^k`` (k in :data:`IN_PLACE_OCTAVES`, the data
    frame's origin kept where the guess puts it); the guess turned by two of its sigmas either
    way in each coordinate plane (about where it puts the origin), and shifted by two sigmas
    either way along each axis. The sigmas bound the search: nothing farther is tried."""
    base = guess.similarity
    if base.dim != dim:
        raise ValueError(f"the initial guess is {base.dim}-D but the points are {dim}-D")
    if guess.scale is None:
        base = Similarity(ratio, base.rotation, base.translation)
    families = [[base]]
    if guess.scale is None:
        families.append(
            [Similarity(ratio * 2.0**k, base.rotation, base.translation) for k in IN_PLACE_OCTAVES]
        )
    turn = np.deg2rad(min(2.0 * guess.rotation_deg, 60.0))
    if turn > 0:
        families.append(
            [Similarity(base.scale, q @ base.rotation, base.translation) for q in plane_rotations(dim, turn)]
        )
    if guess.translation > 0:
        shifts = 2.0 * guess.translation * np.concatenate([np.eye(dim), -np.eye(dim)])
        families.append([Similarity(base.scale, base.rotation, base.translation + d) for d in shifts])
    return families


def beyond_guess(guess: InitialGuess, result: Similarity, model_radius: float) -> str:
    """Why ``result`` lies outside the region an initial guess allows (:data:`GUESS_SIGMAS` of
    its sigmas, plus 1 degree, 1 % and 1 % of the model's radius for guesses given as exact),
    or '' when it lies inside."""
    base = guess.similarity
    problems = []
    turn = np.degrees(rotation_angle(result.rotation @ base.rotation.T))
    if turn > GUESS_SIGMAS * guess.rotation_deg + 1.0:
        problems.append(f"{turn:.3g} deg from the guess's rotation (sigma {guess.rotation_deg:.3g} deg)")
    shift = float(np.linalg.norm(result.translation - base.translation))
    if shift > GUESS_SIGMAS * guess.translation + 0.01 * model_radius:
        problems.append(f"{shift:.3g} from the guess's position (sigma {guess.translation:.3g})")
    if guess.scale is not None:
        ratio = abs(np.log(result.scale / base.scale))
        if ratio > GUESS_SIGMAS * guess.scale + 0.01:
            problems.append(
                f"scale {result.scale:.4g} against the guess's {base.scale:.4g} (sigma {guess.scale:.3g})"
            )
    return "; ".join(f"the result is {p}" for p in problems)


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
