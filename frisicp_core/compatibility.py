"""Triples of descriptor matches that agree with each other, found through the matches' graph.

At the right rung of a small crop's scale search only 1-3 % of the descriptor matches are right
(measured on the development scenes), and a triple drawn at random is all right with probability
~1e-5: random sampling (:func:`frisicp_core.global_search._robust_poses`) then misses the pose.
Right matches agree *pairwise*, whatever their share: for two right matches (x_i -> y_i),
(x_j -> y_j) of a similarity with scale s,

- the lengths agree: |y_i - y_j| = s |x_i - x_j| (up to the keypoints' placement, ~ half a model
  descriptor radius each, and the rung's uncertainty about s, a quarter octave);
- the angles agree: with u the unit chord and n the unoriented normals, the scale-free
  invariants |n_i . u|, |n_j . u| (as an unordered pair) and |n_i . n_j| are the same on both
  sides (the point pair feature of Drost et al. 2010, without its distance).

A wrong pair passes both tests by chance (~1 % of pairs on the development scenes); a right pair
with the noisy normals of a re-sampled scene ~15-40 %. What separates them is the *second-order*
count, how many matches agree with both (SC^2, Chen et al., "SC^2-PCR", CVPR 2022): the right
matches form a near-clique, so a right pair shares the other right matches, a wrong pair only
the chance ones. The pairs of highest count, each completed by the match that agrees best with
both, are the triples returned.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.spatial.distance import cdist

from .features import Descriptors
from .similarity import FloatArray

# The scale of a rung is known to a quarter octave (rungs lie half an octave apart).
_SCALE_SLACK = 2.0**0.25 - 1.0
# Keypoints lie within about half a model descriptor radius of their true place.
_PLACEMENT = 0.5
# The invariants |cos| of two right matches agree within this (noisy normals of ~10 degrees).
ANGLE_AGREEMENT = 0.15
# Pairs of highest second-order count completed to triples.
PAIRS = 200
# Data keypoints whose matches enter the graph at most (an even subset beyond): its cost grows
# with the square of the matches.
MAX_KEYPOINTS = 400


def consistent_triples(data: Descriptors, model: Descriptors, nearest: np.ndarray, rung: float) -> np.ndarray:
    """Triples (K, 3) of matches that agree pairwise at a scale near ``rung`` (module doc), best
    first. Match ``k`` pairs data keypoint ``k // M`` with model keypoint ``nearest.flat[k]``
    (``nearest``: (n, M), each data keypoint's M matches), as rows of ``nearest.reshape(-1)``.
    Pairs whose data keypoints lie within one data descriptor radius are not used: too short
    for a well-conditioned fit, as :func:`frisicp_core.global_search._robust_poses` asks."""
    keys, per_key = nearest.shape
    kept = np.arange(keys)
    if keys > MAX_KEYPOINTS:  # evenly along the keypoints' (spatial) order
        kept = np.unique(np.linspace(0, keys - 1, MAX_KEYPOINTS).astype(np.int64))
    # Matches in (match, keypoint) order: the data's side of a pair depends on its keypoints
    # alone and is broadcast over the matches, cheaply along the leading axes.
    match_rows = (kept[None, :] * per_key + np.arange(per_key)[:, None]).reshape(-1)
    count = match_rows.size
    targets, target_of = np.unique(nearest[kept].T.reshape(-1), return_inverse=True)
    source, source_normals = data.keypoints[kept], data.normals[kept]
    target, target_normals = model.keypoints[targets], model.normals[targets]
    # Bounds on the model's side of each pair (module doc): length and the normals' angle.
    data_length = cdist(source, source)
    reach = _PLACEMENT * model.radius + _SCALE_SLACK * rung * data_length
    low_length = np.where(data_length > data.radius, rung * data_length - reach, np.inf)
    data_cosine = np.abs(source_normals @ source_normals.T)
    shape = (per_key, kept.size, per_key, kept.size)
    agree = _within(cdist(target, target), target_of, shape, low_length, rung * data_length + reach)
    agree &= _within(
        np.abs(target_normals @ target_normals.T),
        target_of,
        shape,
        data_cosine - ANGLE_AGREEMENT,
        data_cosine + ANGLE_AGREEMENT,
    )
    rows, cols = np.nonzero(np.triu(agree.reshape(count, count), 1))
    agree = _chords_agree(
        np.tile(source, (per_key, 1)),
        np.tile(source_normals, (per_key, 1)),
        target[target_of],
        target_normals[target_of],
        rows,
        cols,
    )
    rows, cols = rows[agree], cols[agree]
    if rows.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    ones = np.ones(2 * rows.size, dtype=np.float32)
    graph = sparse.csr_matrix((ones, (np.r_[rows, cols], np.r_[cols, rows])), shape=(count, count))
    # Second order: matches agreeing with both ends of each agreeing pair.
    shared = graph.multiply(graph @ graph).tocsr()
    support = np.asarray(shared[rows, cols]).ravel()
    best = np.argsort(-support, kind="stable")[:PAIRS]
    first, second = rows[best], cols[best]
    both = (graph[first].multiply(graph[second])).toarray() > 0
    score = np.where(both, shared[first].toarray() + shared[second].toarray(), -1.0)
    third = np.argmax(score, axis=1)
    found = both[np.arange(first.size), third]
    triples: np.ndarray = match_rows[np.stack([first, second, third], axis=1)[found]]
    return triples


def _within(
    model_values: FloatArray, target_of: np.ndarray, shape: tuple[int, ...], low: FloatArray, high: FloatArray
) -> np.ndarray:
    """Whether each pair's model value (``model_values`` between its targets) lies strictly
    between the bounds of its data keypoints' pair: (count, count) as ``shape``."""
    values = model_values.astype(np.float32).take(target_of, axis=0).take(target_of, axis=1).reshape(shape)
    inside: np.ndarray = np.greater(values, low.astype(np.float32)[None, :, None, :])
    inside &= np.less(values, high.astype(np.float32)[None, :, None, :])
    return inside


def _chords_agree(
    source: FloatArray,
    source_normals: FloatArray,
    target: FloatArray,
    target_normals: FloatArray,
    rows: np.ndarray,
    cols: np.ndarray,
) -> np.ndarray:
    """Whether the chord's invariants (module doc) of each pair (rows, cols) agree."""
    data = _along_chord(source, source_normals, rows, cols)
    model = _along_chord(target, target_normals, rows, cols)
    agree: np.ndarray = np.all(np.abs(data - model) < ANGLE_AGREEMENT, axis=1)
    return agree


def _along_chord(points: FloatArray, normals: FloatArray, rows: np.ndarray, cols: np.ndarray) -> FloatArray:
    """(smaller, larger) of |n_i . u| and |n_j . u| per pair, u the unit chord: (P, 2)."""
    chord = points[cols] - points[rows]
    chord /= np.maximum(np.linalg.norm(chord, axis=1), 1e-300)[:, None]
    along_first = np.abs(np.einsum("pi,pi->p", chord, normals[rows]))
    along_second = np.abs(np.einsum("pi,pi->p", chord, normals[cols]))
    return np.stack([np.minimum(along_first, along_second), np.maximum(along_first, along_second)], axis=1)
