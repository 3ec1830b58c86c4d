"""The outer contour of a binary silhouette as a 2-D point set (the paper's 2-D shapes)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from frisicp_core import FloatArray


def outer_contour(foreground: np.ndarray) -> FloatArray:
    """Boundary pixels of the largest foreground component, holes filled, as (x, y) points.

    A boundary pixel is a foreground pixel with a background 4-neighbour (``mask & ~eroded``);
    filling holes first keeps only the outer boundary. The points are unordered: registration
    needs none. ``y`` is flipped (image rows grow downwards) so plots show the shape upright.
    """
    mask = np.asarray(foreground) != 0
    if mask.ndim != 2:
        raise ValueError(f"expected a 2-D image, got shape {mask.shape}")
    labels, count = ndimage.label(mask)
    if count == 0:
        raise ValueError("the image has no foreground pixels")
    sizes = np.bincount(labels.ravel())[1:]
    largest = ndimage.binary_fill_holes(labels == 1 + int(np.argmax(sizes)))
    # Erosion treats outside the image as background, so shapes touching the border keep a
    # boundary there.
    boundary = largest & ~ndimage.binary_erosion(largest)
    rows, cols = np.nonzero(boundary)
    return np.column_stack((cols, mask.shape[0] - 1 - rows)).astype(np.float64)
