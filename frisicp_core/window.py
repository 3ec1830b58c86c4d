"""Tracking against a big map: the part of the map around the scan's predicted pose.

A scan that covers 2 % of a 2,000,000-point map meets 40,000 of its points; registering it
against all of them costs what the map costs (its tree, its levels, its backward pairs), and a
random cap of the map to the scan's size keeps one point in 200 of those the scan meets. When a
pose is predicted (a warm start, ``RegistrationConfig.initial``, or an initial guess with a known
scale, ``RegistrationConfig.guess``), the scan is registered against the map's points inside
its bounding box under that pose, enlarged by a margin, at the map's full resolution: the
local map of dynamic map loading (Autoware's NDT loads the map cells around the vehicle),
cut per scan from the prepared model's grid index (:meth:`PreparedModel.grid
<frisicp_core.prepared.PreparedModel.grid>`), so a tracking registration costs what the scan
and its surroundings cost, whatever the size of the map.

The margin, per side and on every axis (the scan's largest extent, so a flat scan's box is not
flat): :data:`MARGIN` of the scan's extent in the model frame, which holds the scan's points
when the prediction is off by up to that much (a sensor's motion between two scans is a few
percent of what it sees), plus, for a guess, what its sigmas allow: :data:`frisicp_core.
hypotheses.GUESS_SIGMAS` times its translation sigma, and its rotation and scale sigmas times
the scan's reach from the point the guess turns and scales it about (the data frame's origin).

When the model is cut:

- only a model with more than :data:`MODEL_RATIO` times the data's points (a scan against a
  scan of the same size is not a map) and at least :data:`MIN_MODEL` points;
- only when the window is a usable point set; else the whole model (a prediction that puts
  the scan off the map; ``register`` then retries it cold, see below);
- a window of more than :data:`DENSITY` times the data's points (more for a guess's wider box,
  :class:`Box`) is thinned to about that many
  (a random subset that is the same where two windows overlap: :meth:`PreparedModel.inside
  <frisicp_core.prepared.PreparedModel.inside>`), also when it holds the whole model (an object
  tracked against its full-resolution model). A map denser than the scan adds to the cost, not
  to the accuracy: the last level fits point-to-plane, with the normals fitted to the map at full
  resolution (:meth:`PreparedModel.normals <frisicp_core.prepared.PreparedModel.normals>`), so
  the distance between the map's samples hardly enters; and the cost stays that of the scan
  however dense the map (``benchmarks/big_map.py``: maps of 100,000 to 4,000,000 points). 1.5
  times: a 2,000,000-point terrain tracked with 10,000-point scans took 31, 33 and 41 ms of CPU
  per scan at 1, 1.5 and 3 times (largest rotation errors 0.064, 0.019, 0.017 degrees); a
  100,000-point object model 42, 43 and 64 ms (0.021, 0.021, 0.023 degrees), where the node's
  old random cap of the model to 10,000 points took 40 ms.

What the verdict sees changes with it, deliberately: overlaps, radius and diagonal are the
window's. The backward overlap is the share of the window the scan covers (about half: the
margin), not the scan's sliver of the whole map; the RMS is compared with the window's radius
and the uncertainty with a share (``Tolerance.translation``) of the window's diagonal, that is
of the scan's own size, where a share of the map's diagonal would grow with the map and accept
a scan misplaced by its own width on a large enough map. A wrong prediction shows as a worse
fit than the track's or an unreliable verdict, and ``register`` retries the scan against the
whole map (:func:`frisicp_core.registration.register`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import RegistrationConfig
from .hypotheses import GUESS_SIGMAS
from .prepared import PreparedModel
from .similarity import FloatArray

# Margin of the window per side, a share of the scan's largest extent in the model frame.
MARGIN = 0.15
# A model is cut only when it has more than this many times the data's points, and this many.
MODEL_RATIO = 4.0
MIN_MODEL = 20_000
# Most points of a window, in data points: a window with more is thinned at random to this many.
DENSITY = 1.5


@dataclass(frozen=True)
class Box:
    """A window's box (low and high corners, model frame) and how many more map points than the
    data's box it should keep, for the same density where the data lie (``spread``: a guess's
    wider box holds the same surface more thinly)."""

    low: FloatArray
    high: FloatArray
    spread: float


def window_bounds(data: FloatArray, config: RegistrationConfig) -> Box | None:
    """The box of the window for ``data`` under the predicted pose of ``config`` (module doc),
    or None when ``config`` predicts none: no warm start, and no initial guess with a known
    scale (an unknown scale leaves the scan's size open)."""
    guess = config.guess
    if config.initial is not None:
        pose = config.initial
    elif guess is not None and guess.scale is not None:
        pose = guess.similarity
    else:
        return None
    mapped = pose.apply(data)
    extra = 0.0
    if config.initial is None and guess is not None and guess.scale is not None:
        # A turn by a and a scale error e move a point at distance r from the point the guess
        # turns about by at most 2 r sin(a / 2) and r (e^e - 1).
        offsets = mapped - pose.translation
        reach = float(np.sqrt(np.max(np.einsum("ij,ij->i", offsets, offsets))))
        turn = min(float(np.deg2rad(GUESS_SIGMAS * guess.rotation_deg)), np.pi)
        stretch = float(np.expm1(GUESS_SIGMAS * guess.scale))
        extra = GUESS_SIGMAS * guess.translation + reach * (2.0 * np.sin(turn / 2.0) + stretch)
    low = np.array([mapped[:, k].min() for k in range(mapped.shape[1])])
    high = np.array([mapped[:, k].max() for k in range(mapped.shape[1])])
    span = float(np.max(high - low))
    margin = MARGIN * span + extra
    # A surface (dimension m - 1) in a box widened by 2 extra holds that much more of the map.
    spread = ((span + 2.0 * extra) / span) ** (data.shape[1] - 1) if span > 0 else 1.0
    return Box(low - margin, high + margin, spread)


def cut(data: FloatArray, model: PreparedModel, config: RegistrationConfig) -> PreparedModel | None:
    """The window of ``model`` for ``data`` under ``config``'s prediction (module doc), or None
    when the whole model is to be used."""
    if len(model) < max(MIN_MODEL, MODEL_RATIO * data.shape[0]):
        return None
    box = window_bounds(data, config)
    if box is None:
        return None
    rows, _ = model.inside(box.low, box.high, most=int(DENSITY * box.spread * data.shape[0]))
    try:
        return model.subset(rows)
    except ValueError:  # too few points, degenerate: the prediction put the scan off the map
        return None
