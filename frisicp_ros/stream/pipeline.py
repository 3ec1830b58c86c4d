"""One registration pipeline for the node and the offline bag mode: messages in, PairOutcome out.

``RegistrationPipeline.process(model_msg, data_msg)`` converts both clouds, checks frames,
registers (optionally warm-started from the previous estimate) and returns a
:class:`PairOutcome` holding either the result or the reason the pair was rejected. It never
raises for bad input. No rclpy import: messages are duck-typed (see ``pointcloud2``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from frisicp_core import (
    ConvergenceCriteria,
    Initialization,
    Method,
    RegistrationConfig,
    RegistrationResult,
    Similarity,
    register,
)
from frisicp_ros.stream.pairing import PAIRING_MODES
from frisicp_ros.stream.pointcloud2 import CloudError, check_dims, cloud_to_points, stamp_ns

# Algorithm defaults follow the core's; config/frisicp.yaml repeats them (a test compares).
_CORE_DEFAULTS = RegistrationConfig()
# RegistrationConfig fields that are not parameters: warm start and NaN handling are the pipeline's.
NOT_PARAMETERS = ("initial", "drop_nonfinite", "criteria")


@dataclass(frozen=True)
class PipelineSettings:
    """The node's parameters as plain values (same names, same defaults as config/frisicp.yaml).

    Node options: ``dims`` (2 = x y only, planar scans), ``max_points`` (cap per cloud, random
    down-sampling above it; 0 = no cap), ``warm_start`` (start from the previous estimate),
    ``pairing``/``sync_tolerance`` (see ``pairing``), ``model_frame``/``data_frame`` (expected
    frame ids; empty = take the first cloud's), ``publish_aligned``.
    Algorithm options map 1:1 onto ``RegistrationConfig``/``ConvergenceCriteria``;
    ``max_distance`` 0 means None (no gating), since ROS parameters have no null.
    """

    dims: int = 3
    max_points: int = 20000
    warm_start: bool = True
    pairing: str = "latest_model"
    sync_tolerance: float = 0.05
    model_frame: str = ""
    data_frame: str = ""
    publish_aligned: bool = True
    method: str = _CORE_DEFAULTS.method.value
    levels: int = _CORE_DEFAULTS.levels
    coarsest_points: int = _CORE_DEFAULTS.coarsest_points
    max_iterations: int = _CORE_DEFAULTS.criteria.max_iterations
    relative_motion: float = _CORE_DEFAULTS.criteria.relative_motion
    relative_rmse: float = _CORE_DEFAULTS.criteria.relative_rmse
    coarse_relative_motion: float = _CORE_DEFAULTS.criteria.coarse_relative_motion
    overlap: float = _CORE_DEFAULTS.overlap
    max_distance: float = _CORE_DEFAULTS.max_distance or 0.0
    initialization: str = _CORE_DEFAULTS.initialization.value
    acceleration: bool = _CORE_DEFAULTS.acceleration
    seed: int = _CORE_DEFAULTS.seed
    backend: str = _CORE_DEFAULTS.backend

    def __post_init__(self) -> None:
        check_dims(self.dims)
        if self.max_points < 0:
            raise ValueError(f"max_points must be >= 0 (0 = no cap), got {self.max_points}")
        if self.pairing not in PAIRING_MODES:
            raise ValueError(f"pairing must be one of {', '.join(PAIRING_MODES)}, got {self.pairing!r}")
        if not self.sync_tolerance >= 0:
            raise ValueError(f"sync_tolerance must be >= 0, got {self.sync_tolerance}")
        if self.max_distance < 0:
            raise ValueError(f"max_distance must be >= 0 (0 = no gating), got {self.max_distance}")
        self.registration_config()  # the core validates its own options

    def registration_config(self, initial: Similarity | None = None) -> RegistrationConfig:
        """The core configuration; raises ValueError (with the core's reason) for bad options."""
        criteria = ConvergenceCriteria(
            max_iterations=self.max_iterations,
            relative_motion=self.relative_motion,
            relative_rmse=self.relative_rmse,
            coarse_relative_motion=self.coarse_relative_motion,
        )
        return RegistrationConfig(
            method=Method(self.method),
            levels=self.levels,
            coarsest_points=self.coarsest_points,
            criteria=criteria,
            overlap=self.overlap,
            max_distance=self.max_distance or None,
            initialization=Initialization(self.initialization),
            initial=initial,
            acceleration=self.acceleration,
            drop_nonfinite=False,  # cloud_to_points already dropped NaN/Inf points
            seed=self.seed,
            backend=self.backend,
        )

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    def updated(self, **changes: Any) -> PipelineSettings:
        """A validated copy with some values changed (ValueError names the bad one)."""
        return replace(self, **changes)


@dataclass(frozen=True)
class Timings:
    convert_seconds: float = 0.0  # both PointCloud2 -> numpy conversions
    register_seconds: float = 0.0  # frisicp_core.register


@dataclass(frozen=True)
class PairOutcome:
    """What one (model, data) pair produced. ``result`` is None exactly when ``rejection`` is set.

    ``stamp_ns``/``data_frame`` come from the data cloud, ``model_frame`` from the model cloud;
    outputs use them verbatim. ``rejected_input`` says which side was bad: 'model', 'data' or
    'pair' (frames, geometry, registration).
    """

    stamp_ns: int
    model_frame: str
    data_frame: str
    dims: int
    data_msg: Any
    result: RegistrationResult | None = None
    data_points: np.ndarray | None = None
    model_points: np.ndarray | None = None
    timings: Timings = field(default_factory=Timings)
    warm_started: bool = False
    rejection: str | None = None
    rejected_input: str | None = None

    @property
    def ok(self) -> bool:
        return self.result is not None


class RegistrationPipeline:
    """Holds the settings, the converted model (cached per model message) and the warm start.

    Not thread-safe by itself: the node calls ``process`` from its single worker thread and
    guards ``reset``/``settings`` changes with its own lock.
    """

    def __init__(self, settings: PipelineSettings | None = None) -> None:
        self.settings = settings or PipelineSettings()
        self._previous: Similarity | None = None
        self._model_cache: tuple[Any, np.ndarray] | None = None
        self._frames: dict[str, str] = {}

    @property
    def previous(self) -> Similarity | None:
        """The warm-start similarity the next pair would start from (None: cold start)."""
        return self._previous

    def reset(self) -> None:
        """Forget the warm start, the cached model and the frames seen so far."""
        self._previous = None
        self._model_cache = None
        self._frames = {}

    def update_settings(self, settings: PipelineSettings) -> None:
        """New settings; anything they invalidate (point caps, dims) is forgotten."""
        if (settings.dims, settings.max_points, settings.seed) != (
            self.settings.dims,
            self.settings.max_points,
            self.settings.seed,
        ):
            self.reset()
        self.settings = settings

    def process(self, model_msg: Any, data_msg: Any) -> PairOutcome:
        settings = self.settings
        outcome = PairOutcome(
            stamp_ns=stamp_ns(data_msg),
            model_frame=str(model_msg.header.frame_id),
            data_frame=str(data_msg.header.frame_id),
            dims=settings.dims,
            data_msg=data_msg,
        )
        frame_problem = self._check_frames(outcome.model_frame, outcome.data_frame)
        if frame_problem:
            return replace(outcome, rejection=frame_problem, rejected_input="pair")
        started = time.perf_counter()
        try:
            model_points = self._model_points(model_msg)
        except CloudError as err:
            return replace(outcome, rejection=f"model cloud: {err}", rejected_input="model")
        try:
            data_points = cloud_to_points(data_msg, settings.dims, settings.max_points, settings.seed)
        except CloudError as err:
            return replace(outcome, rejection=f"data cloud: {err}", rejected_input="data")
        converted = time.perf_counter()
        initial = self._previous if settings.warm_start else None
        try:
            result = register(data_points, model_points, settings.registration_config(initial))
        except Exception as err:  # noqa: BLE001 - a live node must outlive any one pair
            # ValueError: degenerate geometry, too few points. Anything else is a core bug; it is
            # still reported per pair (with its type) instead of killing the node's worker.
            self._previous = None
            reason = str(err) if isinstance(err, ValueError) else f"unexpected {type(err).__name__}: {err}"
            return replace(
                outcome,
                rejection=f"registration: {reason}",
                rejected_input="pair",
                timings=Timings(converted - started, time.perf_counter() - converted),
            )
        timings = Timings(converted - started, time.perf_counter() - converted)
        # A diverged estimate would poison the next start: only a converged one is kept.
        self._previous = result.similarity if result.converged else None
        self._remember_frames(outcome.model_frame, outcome.data_frame)
        return replace(
            outcome,
            result=result,
            data_points=data_points,
            model_points=model_points,
            timings=timings,
            warm_started=initial is not None,
        )

    def _model_points(self, model_msg: Any) -> np.ndarray:
        """Convert the model once per message: in latest_model mode it is reused for every scan."""
        if self._model_cache is not None and self._model_cache[0] is model_msg:
            return self._model_cache[1]
        settings = self.settings
        points = cloud_to_points(model_msg, settings.dims, settings.max_points, settings.seed)
        self._model_cache = (model_msg, points)
        return points

    def _check_frames(self, model_frame: str, data_frame: str) -> str | None:
        """Frame ids must match the configured ones, and in synchronized mode stay constant.

        In latest_model mode a new frame on either side is accepted (a new map, a new sensor)
        but the warm start, which relates the old frames, is dropped.
        """
        settings = self.settings
        for side, frame, expected in (
            ("model", model_frame, settings.model_frame),
            ("data", data_frame, settings.data_frame),
        ):
            if expected and frame != expected:
                return f"frame mismatch: {side} cloud is in '{frame}', expected '{expected}' ({side}_frame)"
            seen = self._frames.get(side)
            if seen is not None and frame != seen:
                if settings.pairing == "synchronized":
                    return (
                        f"frame mismatch: {side} cloud is in '{frame}' but this {side} stream was in"
                        f" '{seen}' (synchronized pairing needs fixed frames; call ~/reset to accept)"
                    )
                self._previous = None
        return None

    def _remember_frames(self, model_frame: str, data_frame: str) -> None:
        self._frames = {"model": model_frame, "data": data_frame}
