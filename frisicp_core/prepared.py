"""A model cloud prepared once and registered against many times: a map, a reference object.

``register(data, model)`` with an array prepares the model on every call: validation, the spatial
order, its statistics, its KD-tree, the normals its points need, its thinned levels and, for a
global search, its shape descriptors at 13 radii. Against a 250,000-point scene that work is most
of a registration, and against a 2,000,000-point map it is all of it. A :class:`PreparedModel`
keeps it all, so every registration after the first pays only for what depends on the data:

    map = PreparedModel(map_points)           # validates, orders; the rest on first use
    for scan in scans:
        result = register(scan, map, RegistrationConfig(initial=last))

What it holds, each computed when first needed and kept:

- the validated points (:func:`frisicp_core.points.as_point_set`) in spatial order
  (:func:`frisicp_core.sampling.in_spatial_order`), their RMS radius, centroid, binary magnitude
  (:mod:`frisicp_core.units`), bounding-box diagonal and spread (:mod:`frisicp_core.verdict`);
- one KD-tree per backend (:class:`frisicp_core.kdtree.NearestNeighbors`) and its spacing;
- the surface normals of the points the point-to-plane refinement asked for
  (:class:`frisicp_core.refine.ModelNormals`);
- a grid index for box queries (:class:`frisicp_core.grid_index.GridIndex`), from which
  :mod:`frisicp_core.window` cuts the part of a map around a tracked scan;
- the thinned levels of the sparse-to-dense pyramid (:meth:`thinned`: the same random subsets a
  fresh preparation would draw, so results do not depend on whether the model was prepared);
- the shape descriptors of a global search (:mod:`frisicp_core.global_search`), per radius;
- its dominant plane directions (:mod:`frisicp_core.plane_directions`) for the plane-arrangement
  starts;
- the depth camera's shells its points lie on about the origin, if any
  (:func:`frisicp_core.depth_steps.find_depth_steps`: a model cloud in its sensor's frame), and
  its average over voxels a step wide, prepared, where a registration averages both clouds
  (:mod:`frisicp_core.terraces`).

Memory, beyond the points themselves (24 bytes per 3-D point): the grid index 8 bytes per point;
a pykdtree 4-8; the normals 24 (allocated with the first normal asked for); the descriptors of a
global search about 1 MiB per radius. About 130 MB for a 2,000,000-point map with everything
built (``benchmarks/big_map.py`` measures it).

A prepared model is safe to share between threads: its caches only gain entries, and an entry
two threads compute at once is computed alike. It never changes its points: the constructor
copies an array it would otherwise share with the caller, so changing that array afterwards
changes nothing here.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from .depth_steps import DepthSteps, find_depth_steps
from .features import Descriptors, describe
from .grid_index import GridIndex
from .kdtree import NearestNeighbors
from .plane_directions import PlaneDirections, plane_directions
from .points import as_point_set, centroid, rms_radius, spread
from .refine import ModelNormals
from .sampling import downsample, in_spatial_order
from .similarity import FloatArray
from .units import magnitude_exponent
from .voxel import voxel_centroids

# Thinned-level draws remembered (see thinned): a few per data size and seed in use.
_THINNED_KEPT = 32

T = TypeVar("T")


class PreparedModel:
    """A model cloud with everything a registration derives from it alone (module doc).

    ``PreparedModel(points)`` validates the points as ``register`` does (``ValueError`` with the
    reason for unusable ones; ``drop_nonfinite`` removes NaN/Inf rows instead) and puts them in
    spatial order. Pass it to :func:`frisicp_core.register` in place of the model array.
    ``copy=False`` hands an array over without a copy (2,000,000 points are 48 MB): the caller
    must not change it afterwards.
    """

    def __init__(self, points: ArrayLike, *, drop_nonfinite: bool = False, copy: bool = True) -> None:
        validated = as_point_set(points, "model", drop_nonfinite=drop_nonfinite)
        if copy and isinstance(points, np.ndarray) and np.may_share_memory(validated, points):
            validated = validated.copy()
        self._set_up(validated)
        self.points.flags.writeable = False

    @classmethod
    def of(cls, validated: FloatArray) -> PreparedModel:
        """A prepared model of points already validated (:func:`as_point_set`), used as they are
        (no copy): ``register``'s own preparation of a model array for one call."""
        prepared = cls.__new__(cls)
        prepared._set_up(validated)
        return prepared

    def _set_up(self, validated: FloatArray) -> None:
        # The radius before the spatial order, as register always measured it (the sum's order
        # changes its last bits, and with them every tolerance derived from it).
        self.radius = rms_radius(validated)
        self.points: FloatArray = in_spatial_order(validated, self.radius)
        self._cache = _Cache()
        self._parent: tuple[PreparedModel, np.ndarray] | None = None

    @property
    def dim(self) -> int:
        return int(self.points.shape[1])

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def __repr__(self) -> str:
        return f"PreparedModel({len(self)} points, {self.dim}-D, RMS radius {self.radius:.4g})"

    @property
    def exponent(self) -> int:
        """The binary magnitude of the points (:func:`frisicp_core.units.magnitude_exponent`)."""
        return self._cache.value(("exponent",), lambda: magnitude_exponent(self.points))

    @property
    def centroid(self) -> FloatArray:
        return self._cache.value(("centroid",), lambda: centroid(self.points))

    @property
    def diagonal(self) -> float:
        """Length of the bounding box's diagonal."""
        return self._cache.value(("diagonal",), lambda: _diagonal(self.points))

    @property
    def bounds(self) -> tuple[FloatArray, FloatArray]:
        """The bounding box's low and high corners."""
        return self._cache.value(("bounds",), lambda: _bounds(self.points))

    @property
    def spread(self) -> float:
        """:func:`frisicp_core.points.spread` of the points (the verdict's one-scene check)."""
        return self._cache.value(("spread",), lambda: spread(self.points))

    @property
    def depth_steps(self) -> DepthSteps | None:
        """The shells a depth camera at the origin put the points on (None: none found), looked
        for once (:func:`frisicp_core.depth_steps.find_depth_steps`)."""
        return self._cache.value(("depth_steps",), lambda: find_depth_steps(self.points))

    def averaged(self, edge: float, offset: float = 0.0) -> PreparedModel:
        """The model averaged over voxels of ``edge`` on the grid moved by ``offset`` voxels
        (:func:`frisicp_core.voxel_centroids`), prepared, kept per edge and offset
        (:mod:`frisicp_core.terraces`); ``ValueError`` when the average is no usable point set."""
        return self._cache.value(
            ("averaged", edge, offset),
            lambda: PreparedModel.of(
                as_point_set(
                    voxel_centroids(self.points, edge, offset), "model averaged over its depth steps"
                )
            ),
        )

    def tree(self, backend: str = "auto") -> NearestNeighbors:
        """The KD-tree over the points (built on first use, one per backend)."""
        return self._cache.value(("tree", backend), lambda: NearestNeighbors(self.points, backend))

    def normals(self, tree: NearestNeighbors) -> ModelNormals:
        """The normals of the points of ``tree``: kept when it is one of this model's trees, so a
        normal is fitted once however many registrations ask for it; a fresh cache otherwise.
        A window's (:meth:`subset`) are its parent's, at its rows (:class:`_ParentNormals`)."""
        if not any(value is tree for key, value in self._cache.values.items() if key[0] == "tree"):
            return ModelNormals(tree)
        if self._parent is not None:
            parent, rows = self._parent
            return self._cache.value(
                ("normals", id(tree)), lambda: _ParentNormals(parent.normals(parent.tree(tree.backend)), rows)
            )
        return self._cache.value(("normals", id(tree)), lambda: ModelNormals(tree))

    def grid(self) -> GridIndex:
        """The grid index of the points for box queries (built on first use)."""
        return self._cache.value(("grid",), lambda: GridIndex(self.points))

    def inside(self, low: FloatArray, high: FloatArray, most: int | None = None) -> tuple[np.ndarray, int]:
        """Rows (ascending) of the points within the box [low, high] (per axis, inclusive), and
        how many there are. With ``most``, a random subset of about that many when there are more:
        the points whose fixed random key (uniform in [0, 1), drawn once per model) is below
        ``most / count``. Two boxes keep the same points where they overlap, so the windows of a
        tracked sensor, scan after scan, are one sampling of the map (a new one per scan would
        jitter the estimates), and what was fitted to those points (their normals) serves again.

        A box holding the whole model takes every row; the first other box tests every point (one
        vectorised pass, cheaper than building the grid index for a model used once, as one
        ``register`` call with an array uses it); later ones use the grid index
        (:class:`frisicp_core.grid_index.GridIndex`, built then). The rows do not depend on which."""
        bounds = self.bounds
        if np.all(low <= bounds[0]) and np.all(high >= bounds[1]):
            rows = np.arange(len(self))
        elif self._cache.boxes > 0 or ("grid",) in self._cache.values:
            rows = self.grid().box(low, high)
        else:
            inside = np.ones(len(self), dtype=bool)
            for k in range(self.dim):
                column = self.points[:, k]
                inside &= (column >= low[k]) & (column <= high[k])
            rows = np.flatnonzero(inside)
        self._cache.boxes += 1
        count = int(rows.shape[0])
        if most is not None and count > most:
            keys = self._cache.value(("keys",), lambda: _keys(len(self)))
            rows = rows[keys[rows] < most / count]
        return rows, count

    def index(self, backend: str = "auto") -> PreparedModel:
        """Build the KD-tree and the grid index now (else the first registration that needs them
        builds them): a node can pay for them when the map arrives instead of in a scan's
        latency. Returns the model itself."""
        self.tree(backend).spacing()
        self.grid()
        return self

    def subset(self, rows: np.ndarray) -> PreparedModel:
        """The points ``rows`` (ascending, so the spatial order is kept) as a prepared model of
        their own; ``ValueError`` when they are no usable point set (too few, degenerate).
        Its normals are this model's at ``rows`` (:meth:`normals`)."""
        subset = PreparedModel.of(as_point_set(self.points[rows], "model window"))
        subset._parent = (self, rows)
        return subset

    def in_units(self, unit: float) -> PreparedModel:
        """The model divided by ``unit``, a power of two (:mod:`frisicp_core.units`), prepared;
        kept per unit. ``unit`` 1 is the model itself."""
        if unit == 1.0:
            return self
        return self._cache.value(("units", unit), lambda: self._divided(unit))

    def _divided(self, unit: float) -> PreparedModel:
        # (Its thinning keys are drawn as the model's: the same seed, the same count.)
        # Dividing by a power of two is exact: the radius divides exactly, and the spatial order
        # (a grid over the bounding box) is the same, so this is what preparing the divided
        # points would give.
        prepared = PreparedModel.__new__(PreparedModel)
        prepared.radius = self.radius / unit
        prepared.points = self.points / unit
        prepared._cache = _Cache()
        prepared._parent = None
        return prepared

    def descriptors(self, radius: float, max_keypoints: int | None) -> Descriptors:
        """:func:`frisicp_core.features.describe` of the points at ``radius`` (kept per radius)."""
        return self._cache.value(
            ("descriptors", radius, max_keypoints), lambda: describe(self.points, radius, max_keypoints)
        )

    def plane_directions(self) -> PlaneDirections:
        """:func:`frisicp_core.plane_directions.plane_directions` of the points (kept)."""
        return self._cache.value(("plane directions",), lambda: plane_directions(self.points))

    def thinned(self, chain: Thinning, size: int, rng: np.random.Generator) -> Thinning:
        """The next coarser level of a pyramid: ``downsample(chain.points, size, rng)``,
        remembered with the generator's state before and after the draw.

        The draw is a pure function of the finer level and the generator's state, so a draw with
        the same chain of states returns the same subset and leaves ``rng`` in the same state as
        drawing it again would: the data's draws, which share the generator, come out as they
        would have. Start a chain with :meth:`levels`."""
        key = (*chain.key, (size, _state_key(rng)))
        thinned = self._cache.thinned
        if key in thinned:
            thinned.move_to_end(key)
            points, state = thinned[key]
            rng.bit_generator.state = state
        else:
            points = downsample(chain.points, size, rng)
            thinned[key] = (points, rng.bit_generator.state)
            while len(thinned) > _THINNED_KEPT:
                thinned.popitem(last=False)
        return Thinning(key, points)

    def levels(self) -> Thinning:
        """The start of a chain of :meth:`thinned` levels: the full set."""
        return Thinning((), self.points)


class _ParentNormals(ModelNormals):
    """A window's normals: its parent model's at the window's rows. Fitted to the whole map's
    points, a point at the window's edge gets the normal of its whole neighbourhood, and a normal
    is fitted once for every window it falls in (a tracked sensor's windows overlap scan after
    scan): the normals of a 100,000-point window were a fifth of a tracking registration.
    Copied into tables of the window's own as they are first asked for: the refinement looks
    them up a dozen times per registration, and reads scattered over a big map's tables miss the
    processor's caches. (In a one-off profile of tracking in benchmarks/big_map_node.py's
    2,000,000-point map the lookups were a quarter of a pairing's cost, mostly fitting normals
    new to the track; what the copies save was too small to tell from this machine's noise.)"""

    def __init__(self, parent: ModelNormals, rows: np.ndarray) -> None:
        # No super().__init__(): the parent fits the normals (and its tree is the whole map's).
        self.tree = parent.tree
        self.neighbours = parent.neighbours
        self._parent_normals = parent
        self._rows = rows
        self._normals = np.full((rows.shape[0], parent.tree.points.shape[1]), np.nan)
        self._curvatures = np.zeros((rows.shape[0], parent.curvature_width), np.float32)

    def _fitted(self, index: np.ndarray) -> FloatArray:
        missing = self._unfitted(index)
        if missing.size:
            self._normals[missing], self._curvatures[missing] = self._parent_normals.surface(
                self._rows[missing]
            )
        return self._normals


@dataclass(frozen=True)
class Thinning:
    """One level of a model's thinned pyramid: its points and the draws that led to it."""

    key: tuple[Any, ...]
    points: FloatArray


@dataclass
class _Cache:
    """What a prepared model computed so far. Entries are only ever added (or, for the thinned
    draws, dropped oldest first), never changed."""

    values: dict[tuple[Any, ...], Any] = field(default_factory=dict)
    thinned: OrderedDict[tuple[Any, ...], tuple[FloatArray, Mapping[str, Any]]] = field(
        default_factory=OrderedDict
    )
    boxes: int = 0  # box queries answered (see inside)

    def value(self, key: tuple[Any, ...], compute: Callable[[], T]) -> T:
        """The entry ``key``, computed by ``compute`` the first time."""
        if key not in self.values:
            self.values[key] = compute()
        found: T = self.values[key]
        return found


def _bounds(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    columns = range(points.shape[1])
    return np.array([points[:, k].min() for k in columns]), np.array([points[:, k].max() for k in columns])


def _keys(count: int) -> np.ndarray:
    """The points' thinning keys (see PreparedModel.inside): fixed, uniform, 4 bytes a point."""
    keys: np.ndarray = np.random.default_rng(0).random(count, dtype=np.float32)
    return keys


def _diagonal(points: FloatArray) -> float:
    # Per column: an (n, m) array's axis-0 reductions are several times slower (points.centroid).
    extent = [float(points[:, k].max() - points[:, k].min()) for k in range(points.shape[1])]
    return float(np.linalg.norm(extent))


def _state_key(rng: np.random.Generator) -> Any:
    """The generator's state as a hashable value."""
    return _frozen(rng.bit_generator.state)


def _frozen(value: Any) -> Any:
    if isinstance(value, dict):
        return tuple(sorted((k, _frozen(v)) for k, v in value.items()))
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.tobytes())
    if isinstance(value, list):
        return tuple(_frozen(v) for v in value)
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    return value
