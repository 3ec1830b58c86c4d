"""Configuration of a registration: plain frozen dataclasses, validated on construction."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from .kdtree import BACKENDS
from .similarity import Similarity


class Method(str, Enum):
    """Which algorithm ``register`` runs.

    FRISICP: bidirectional correspondences, free scale (Li et al. 2011, Eq. 3).
    ICP: forward correspondences, s = 1 (Besl and McKay 1992).
    SCALE_ICP: forward correspondences, free scale (Zinsser et al. 2005); may collapse s -> 0.
    BOUNDED_ICP: forward correspondences, s clipped to bounds from the sets' covariances
    (Du et al. 2007).
    """

    FRISICP = "frisicp"
    ICP = "icp"
    SCALE_ICP = "scale-icp"
    BOUNDED_ICP = "bounded-icp"


class Initialization(str, Enum):
    """Where the iterations start when no initial similarity is given.

    IDENTITY: s = 1, R = I, t = 0 (the paper).
    MOMENTS: centroids aligned, s = ratio of RMS radii, R = I.
    PRINCIPAL_AXES: MOMENTS plus one hypothesis per proper principal-axes alignment.
    SEARCH: PRINCIPAL_AXES plus the data left in place (R = I, its centroid fixed) at scales
    around the RMS-radius ratio, and turned 30 degrees either way in each coordinate plane: the
    right start when the frames are roughly aligned but the clouds overlap only partly (a scan
    in a map), where centroids and radii mislead.
    With several hypotheses, all are iterated together on the coarsest level and the one with
    the lowest error is kept (see ``frisicp_core.hypotheses``).
    """

    IDENTITY = "identity"
    MOMENTS = "moments"
    PRINCIPAL_AXES = "principal-axes"
    SEARCH = "search"


@dataclass(frozen=True)
class InitialGuess:
    """A pose known roughly, and how roughly: RViz's "2D Pose Estimate", a GNSS fix, a known
    mounting. A cold registration searches around it instead of searching blind.

    ``similarity``: the guessed pose, model ~ s R data + t; t is where the data frame's origin
    lands in the model frame (the sensor's position for a sensor frame).
    ``rotation_deg``, ``translation``: 1-sigma of the guess, in degrees and model units (of t).
    ``scale``: 1-sigma relative error of ``similarity.scale``, or None when the scale is unknown
    (then ``similarity.scale`` is only a starting value and the scale is searched).
    Answers farther than :data:`frisicp_core.hypotheses.GUESS_SIGMAS` sigmas from the guess are
    not searched for, and a result that ends there is not reliable.
    """

    similarity: Similarity
    rotation_deg: float
    translation: float
    scale: float | None = None

    def __post_init__(self) -> None:
        _require(isinstance(self.similarity, Similarity), "InitialGuess.similarity must be a Similarity")
        _require(
            math.isfinite(self.rotation_deg) and self.rotation_deg >= 0,
            f"InitialGuess.rotation_deg must be finite and >= 0, got {self.rotation_deg}",
        )
        _require(
            math.isfinite(self.translation) and self.translation >= 0,
            f"InitialGuess.translation must be finite and >= 0, got {self.translation}",
        )
        _require(
            self.scale is None or (math.isfinite(self.scale) and self.scale >= 0),
            f"InitialGuess.scale must be None (unknown) or finite and >= 0, got {self.scale}",
        )


@dataclass(frozen=True)
class Tolerance:
    """How close to the truth a result must be known to be before it is called reliable.

    A result is reliable only when three of its standard deviations lie within these (and it
    passes the other checks of :mod:`frisicp_core.verdict`); two poses farther apart than these
    in any component are distinct answers (an ambiguity when both fit about as well).
    ``rotation_deg`` in degrees, ``scale`` relative, ``translation`` a share of the model's
    bounding-box diagonal (of where the data's centroid lands). The stated sigmas near these
    (three of them within 0.5-3 tolerances) are sized by more split halves
    (:data:`frisicp_core.refine.BORDERLINE`), so a result's covariance may differ a little with
    the tolerance it is judged by.
    """

    rotation_deg: float = 1.0
    scale: float = 0.01
    translation: float = 0.005

    def __post_init__(self) -> None:
        for name in ("rotation_deg", "scale", "translation"):
            value = getattr(self, name)
            _require(
                math.isfinite(value) and value > 0, f"tolerance {name} must be finite and > 0, got {value}"
            )

    def limits(self, diagonal: float) -> tuple[float, float, float]:
        """What three sigmas of a result are held against (rotation in degrees, relative scale,
        translation in model units) for a model whose bounding-box diagonal is ``diagonal``."""
        return (self.rotation_deg, self.scale, self.translation * diagonal)


@dataclass(frozen=True)
class ConvergenceCriteria:
    """When one level stops iterating (like Open3D's ICPConvergenceCriteria).

    A level converges when the similarity moved the data by less than ``relative_motion`` times
    the model's RMS radius (RMS over the data points) between two iterations, or the error
    changed by less than ``relative_rmse`` relative to itself.
    The coarsest level uses the looser ``coarse_relative_motion`` (the next level refines it
    anyway), the levels between a tolerance geometrically between the two.
    ``noise_floor``: a level also converges once a step moves the data by less than the standard
    error of the estimate, RMS residual / sqrt(pairs kept). Two clouds that sample a surface
    differently (every real pair) fit only up to that; iterating below it moves the answer by
    less than its own uncertainty, slowly, since point-to-point ICP crawls along the surface.
    Noise-free copies have RMS ~ 0, so they still converge to ``relative_motion``.
    """

    max_iterations: int = 100
    relative_motion: float = 1e-5
    relative_rmse: float = 1e-9
    coarse_relative_motion: float = 1e-3
    noise_floor: bool = True

    def __post_init__(self) -> None:
        _require(self.max_iterations >= 1, "max_iterations must be >= 1")
        for name in ("relative_motion", "relative_rmse", "coarse_relative_motion"):
            value = getattr(self, name)
            _require(0 <= value < 1, f"{name} must be in [0, 1), got {value}")


@dataclass(frozen=True)
class RegistrationConfig:
    """Everything ``register`` can be told. ``RegistrationConfig.paper()`` is the paper exactly.

    Paper options: ``method``, ``levels`` and ``coarsest_points`` (sparse-to-dense hierarchy),
    ``criteria``. Ours, on by default: ``overlap`` (estimated per direction), ``symmetric``
    (scale rule), ``initialization`` (hypothesis search), ``acceleration``. Also ``initial``
    (warm start: tracking, iterated from there), ``guess`` (a rough pose with its uncertainty: searched
    around), ``max_distance`` (gating), ``average_depth_steps``, ``drop_nonfinite``, ``seed`` (the
    random down-sampling), ``backend`` (KD-tree library), ``budget_seconds``.

    ``overlap``: None (default) estimates, in each direction separately and at every iteration,
    which share of the nearest-neighbour pairs belongs to the overlap (trimmed ICP's criterion,
    see :mod:`frisicp_core.overlap`): full overlap, a scan in a map, a map in a scan and two
    partly overlapping scans all work without being told. A number in (0, 1] fixes that share
    in both directions instead (1 keeps every pair, the paper).
    ``max_distance``: correspondences farther than this many times the median kept distance of
    their direction are dropped (None keeps all).
    ``symmetric``: Horn's symmetric scale, errors measured half-way between the two frames, so
    registering data onto model and model onto data are one problem (see
    :mod:`frisicp_core.estimate`); False is the paper's (Umeyama's) scale, errors in the model
    frame, which favours a smaller data set when the overlap is partial.
    ``dense_targets``: the levels above the coarsest pair a growing subset of each set's points
    with the *full* other set (its nearest neighbours are exact), instead of with an equally
    thinned subset (the paper). Two independently thinned samplings of a surface pair
    point-to-point with a bias of a sizeable fraction of their spacing, so each paper level
    converges somewhere else and the finest level starts a few iterations away; with dense
    targets every level estimates the same optimum and the finest needs one or two. The
    coarsest level, where the initial hypotheses are screened, is thinned on both sides.
    ``average_depth_steps``: where both clouds come in a depth camera's coarse depth steps about
    their own origins (each in its camera's frame), register their averages over voxels a step
    wide instead (:mod:`frisicp_core.terraces`): two such frames lock terrace onto terrace, a
    wrong pose that looks right. Costs a look at the model's depths (milliseconds; once per
    :class:`~frisicp_core.PreparedModel`) and, where they show steps, at the data's; the result's
    ``depth_averaged`` says what was done. False for clouds the caller averaged already.
    ``budget_seconds``: wall-clock time one ``register`` call may take (None, the default:
    unbounded; the node and ``frisicp bag`` set 5 s). Past it the iterations stop and the result
    is returned unreliable, reason "budget exceeded" (see :mod:`frisicp_core.budget`); the cold
    retry of a warm start gets what is left.
    """

    method: Method = Method.FRISICP
    levels: int = 3
    coarsest_points: int = 1000
    criteria: ConvergenceCriteria = field(default_factory=ConvergenceCriteria)
    overlap: float | None = None
    max_distance: float | None = None
    symmetric: bool = True
    dense_targets: bool = True
    initialization: Initialization = Initialization.SEARCH
    initial: Similarity | None = None
    guess: InitialGuess | None = None
    tolerance: Tolerance = field(default_factory=Tolerance)
    probe: bool = True
    polish: bool = True
    acceleration: bool = True
    average_depth_steps: bool = True
    drop_nonfinite: bool = False
    seed: int = 0
    backend: str = "auto"
    budget_seconds: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "method", Method(self.method))
        object.__setattr__(self, "initialization", Initialization(self.initialization))
        _require(self.levels >= 1, f"levels must be >= 1, got {self.levels}")
        _require(self.coarsest_points >= 10, f"coarsest_points must be >= 10, got {self.coarsest_points}")
        _require(
            self.overlap is None or 0 < self.overlap <= 1,
            f"overlap must be in (0, 1] or None (estimated), got {self.overlap}",
        )
        _require(
            self.max_distance is None or self.max_distance > 0,
            f"max_distance must be positive or None, got {self.max_distance}",
        )
        _require(
            isinstance(self.seed, (int, np.integer)) and not isinstance(self.seed, bool) and self.seed >= 0,
            f"seed must be a non-negative integer, got {self.seed!r}",
        )
        _require(self.backend in BACKENDS, f"unknown backend {self.backend!r}; choose one of {BACKENDS}")
        _require(
            self.budget_seconds is None or self.budget_seconds > 0,
            f"budget_seconds must be positive or None (unbounded), got {self.budget_seconds}",
        )
        _require(self.initial is None or isinstance(self.initial, Similarity), "initial must be a Similarity")
        _require(self.guess is None or isinstance(self.guess, InitialGuess), "guess must be an InitialGuess")

    @classmethod
    def paper(cls, method: Method | str = Method.FRISICP, **overrides: object) -> RegistrationConfig:
        """The published algorithm: identity start, no trimming, gating or acceleration.

        The baselines (ICP and its scaled variants) run single-level, as in the paper.
        """
        method = Method(method)
        settings: dict[str, object] = {
            "method": method,
            "initialization": Initialization.IDENTITY,
            "levels": 3 if method is Method.FRISICP else 1,
            "overlap": 1.0,
            "symmetric": False,
            "dense_targets": False,
            "criteria": ConvergenceCriteria(noise_floor=False),
            "acceleration": False,
            "probe": False,
            "polish": False,
            "average_depth_steps": False,
        }
        settings.update(overrides)
        return cls(**settings)  # type: ignore[arg-type]


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise ValueError(message)
