"""Guesses from first and second moments: starting similarities and Du's scale bounds."""

from __future__ import annotations

import itertools

import numpy as np

from .similarity import FloatArray, Similarity


def _principal_axes(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Centroid, covariance eigenvalues (descending) and eigenvectors (columns, same order)."""
    centroid = points.mean(axis=0)
    centred = points - centroid
    eigval, eigvec = np.linalg.eigh(centred.T @ centred / points.shape[0])
    return centroid, eigval[::-1], eigvec[:, ::-1]


def moment_guesses(data: FloatArray, model: FloatArray, *, principal_axes: bool) -> list[Similarity]:
    """Similarities that align the centroids and the RMS radii of ``data`` onto ``model``.

    The first guess keeps R = I (right when the sets are already roughly aligned, the common
    robotics case). With ``principal_axes``, the 2^(m-1) proper rotations mapping the data's
    principal axes onto the model's (every sign pattern with det R = +1) follow, since axis
    signs are undetermined by the moments.
    """
    mu_d, val_d, vec_d = _principal_axes(data)
    mu_m, val_m, vec_m = _principal_axes(model)
    scale = float(np.sqrt(val_m.sum() / val_d.sum()))  # ratio of RMS radii
    rotations = [np.eye(data.shape[1])]
    if principal_axes:
        dim = data.shape[1]
        for signs in itertools.product((1.0, -1.0), repeat=dim - 1):
            flip = np.array((*signs, 1.0))
            rotation = (vec_m * flip) @ vec_d.T
            if np.linalg.det(rotation) < 0:
                flip[-1] = -1.0
                rotation = (vec_m * flip) @ vec_d.T
            rotations.append(rotation)
    return [Similarity(scale, rot, mu_m - scale * rot @ mu_d) for rot in rotations]


def covariance_scale_bounds(data: FloatArray, model: FloatArray) -> tuple[float, float]:
    """Scale interval for Du et al.'s bounded-scale ICP, from the covariance eigenvalues.

    With eigenvalues lambda of the data (A) and model (B) covariances, any similarity
    B = s R A + t satisfies lambda_B = s^2 lambda_A axis by axis, so
    ``sqrt(min lambda_B / max lambda_A) <= s <= sqrt(max lambda_B / min lambda_A)``.
    """
    _, val_d, _ = _principal_axes(data)
    _, val_m, _ = _principal_axes(model)
    floor = np.finfo(float).tiny
    low = float(np.sqrt(max(val_m[-1], floor) / max(val_d[0], floor)))
    high = float(np.sqrt(max(val_m[0], floor) / max(val_d[-1], floor)))
    return low, high
