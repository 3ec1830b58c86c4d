"""Configuration of a registration: plain frozen dataclasses, validated on construction."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

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
    PRINCIPAL_AXES: MOMENTS plus one hypothesis per proper principal-axes alignment; each is
    registered on the coarsest level and the one with the lowest error is kept.
    """

    IDENTITY = "identity"
    MOMENTS = "moments"
    PRINCIPAL_AXES = "principal-axes"


@dataclass(frozen=True)
class ConvergenceCriteria:
    """When one level stops iterating (like Open3D's ICPConvergenceCriteria).

    A level converges when the similarity moved the data by less than ``relative_motion`` times
    the model's RMS radius (RMS over the data points) between two iterations, or the error
    changed by less than ``relative_rmse`` relative to itself.
    Coarse levels use the looser ``coarse_relative_motion``: the next level refines them anyway.
    """

    max_iterations: int = 100
    relative_motion: float = 1e-5
    relative_rmse: float = 1e-9
    coarse_relative_motion: float = 1e-3

    def __post_init__(self) -> None:
        _require(self.max_iterations >= 1, "max_iterations must be >= 1")
        for name in ("relative_motion", "relative_rmse", "coarse_relative_motion"):
            value = getattr(self, name)
            _require(0 <= value < 1, f"{name} must be in [0, 1), got {value}")


@dataclass(frozen=True)
class RegistrationConfig:
    """Everything ``register`` can be told. ``RegistrationConfig.paper()`` is the paper exactly.

    Paper options: ``method``, ``levels`` and ``coarsest_points`` (sparse-to-dense hierarchy),
    ``criteria``. Ours: ``overlap`` and ``max_distance`` (robustness to partial overlap and
    outliers), ``initialization`` (start far from the truth), ``initial`` (warm start),
    ``drop_nonfinite``, ``seed`` (the random down-sampling), ``backend`` (KD-tree library).

    ``overlap`` in (0, 1]: in each direction only this fraction of the correspondences, the
    closest ones, enters the estimate (trimmed ICP, Chetverikov et al. 2002); 1 keeps all.
    ``max_distance``: correspondences farther than this many times the median correspondence
    distance of their direction are dropped (None keeps all).
    """

    method: Method = Method.FRISICP
    levels: int = 3
    coarsest_points: int = 1000
    criteria: ConvergenceCriteria = field(default_factory=ConvergenceCriteria)
    overlap: float = 1.0
    max_distance: float | None = None
    initialization: Initialization = Initialization.PRINCIPAL_AXES
    initial: Similarity | None = None
    acceleration: bool = True
    drop_nonfinite: bool = False
    seed: int = 0
    backend: str = "auto"

    def __post_init__(self) -> None:
        object.__setattr__(self, "method", Method(self.method))
        object.__setattr__(self, "initialization", Initialization(self.initialization))
        _require(self.levels >= 1, f"levels must be >= 1, got {self.levels}")
        _require(self.coarsest_points >= 10, f"coarsest_points must be >= 10, got {self.coarsest_points}")
        _require(0 < self.overlap <= 1, f"overlap must be in (0, 1], got {self.overlap}")
        _require(
            self.max_distance is None or self.max_distance > 0,
            f"max_distance must be positive or None, got {self.max_distance}",
        )
        _require(self.backend in BACKENDS, f"unknown backend {self.backend!r}; choose one of {BACKENDS}")
        _require(self.initial is None or isinstance(self.initial, Similarity), "initial must be a Similarity")

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
            "acceleration": False,
        }
        settings.update(overrides)
        return cls(**settings)  # type: ignore[arg-type]

    @classmethod
    def robust(cls, **overrides: object) -> RegistrationConfig:
        """Our settings for partial overlap (two scans, a scan in a map): 80 % trimming."""
        settings: dict[str, object] = {"overlap": 0.8}
        settings.update(overrides)
        return cls(**settings)  # type: ignore[arg-type]


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise ValueError(message)
