"""One registration pipeline for the node and the offline bag mode: messages in, PairOutcome out.

``RegistrationPipeline.process(model_msg, data_msg)`` converts both clouds, checks frames,
registers (optionally warm-started from the previous estimate) and returns either
:class:`Registered` or :class:`Rejected` (with the reason). It never raises, whatever the input.
No rclpy import: messages are duck-typed (see ``pointcloud2``).

A registered pair carries the core's plausibility verdict (``Registered.reliable`` and
``reason``): an implausible result is reported, never used as a warm start. Only a reliable
result becomes the next pair's warm start; any rejection or unreliable result clears it, so one
garbage cloud cannot steer the pairs after it. (The core itself retries a warm start cold when
the warm-started result is not reliable or clearly worse than the track's last result, which
the pipeline passes it: a jump of the pose; the pipeline does not retry.) With ``motion_model``
constant_velocity the warm start is the last result moved on by the motion between the last two
(``frisicp_ros.stream.motion``).

Clouds are read with ``read_cloud``: finite points, the optional voxel grid (``voxel_size``, ``voxel_mode``),
then, for data clouds, the random cap (``max_points``). The model is not capped: it is read once
per model message and kept as a ``frisicp_core.PreparedModel`` at full resolution, so that every
pair against it reuses its trees, levels and normals, and a warm-started (or guessed) scan is
registered against the map around its predicted pose (``frisicp_core.window``). A latched map is
prepared once for the whole run. Memory: about 60 bytes per map point, more once a cold search
has described it (docs/node.md).

Data clouds are looked at for a depth camera's coarse depth steps now and then
(``frisicp_ros.stream.depth_check``); a registered pair carries the finding and its advice, and
where the model cloud comes in coarse steps too (frames of one camera), a pose the core calls
reliable is not, with the reason and what to do, until the clouds are averaged.

Frames: a configured ``model_frame``/``data_frame`` must match; in synchronized mode a stream's
frame must stay what it was at the last registered pair (else the pair is rejected; ``reset()``
accepts the new one); in latest_model mode a frame change only drops the warm start.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from frisicp_core import InitialGuess, PreparedModel, RegistrationResult, Similarity, register
from frisicp_core.depth_steps import DepthSteps
from frisicp_ros.stream.depth_check import DepthStepCheck, averaged_by_settings, depth_step_advice
from frisicp_ros.stream.messages import CloudLayoutLike, PointCloud2Like
from frisicp_ros.stream.motion import MotionModel, MotionTracker
from frisicp_ros.stream.pairing import PairingMode
from frisicp_ros.stream.pointcloud2 import CloudError, CloudPoints, read_cloud
from frisicp_ros.stream.settings import PipelineSettings, settings_from
from frisicp_ros.stream.stamps import time_ns

RejectedInput = Literal["model", "data", "pair"]


@dataclass(frozen=True)
class Timings:
    """Where a pair's time went (wall clock, the pipeline's thread)."""

    convert_seconds: float = 0.0  # PointCloud2 -> float64 points, data and (when not cached) model
    downsample_seconds: float = 0.0  # voxel grid and random cap, data and (when not cached) model
    register_seconds: float = 0.0  # frisicp_core.register
    register_cpu_seconds: float = 0.0  # the same call's CPU time (less than wall: others ran)

    @property
    def input_seconds(self) -> float:
        """Everything before the registration: conversion and down-sampling."""
        return self.convert_seconds + self.downsample_seconds


@dataclass(frozen=True)
class PairHeader:
    """Where a pair's outputs go: the data cloud's stamp and frame, the model cloud's frame.

    ``stamp`` is the data cloud's (sec, nanosec) exactly as received: outputs copy it, so a stamp
    that is not normalised (nanosec >= 1e9) is passed on as it came instead of overflowing or
    wrapping the 32-bit ``sec`` of the outputs.
    """

    stamp: tuple[int, int]
    model_frame: str
    data_frame: str
    dims: int

    @property
    def stamp_ns(self) -> int:
        return time_ns(*self.stamp)


@dataclass(frozen=True)
class Registered(PairHeader):
    """A registered pair. ``data_points``/``model_points``: how many points were registered (the
    model's: those of the window around the predicted pose when one was used).

    ``reliable`` False: the result failed the plausibility checks (``reason`` says which); it is
    reported but must not be published or used as a pose. ``depth_steps``: the shells the data
    stream's depth was last found in (``frisicp_ros.stream.depth_check``; None: none), and
    ``depth_step_advice`` what to do about them ("" when nothing); where the model came in coarse
    steps too, the core registered both clouds' averages (``result.depth_averaged``).
    """

    result: RegistrationResult
    data_points: int
    model_points: int
    timings: Timings
    depth_steps: DepthSteps | None = None
    depth_step_advice: str = ""

    @property
    def reliable(self) -> bool:
        return self.result.reliable

    @property
    def reason(self) -> str:
        return self.result.reason

    @property
    def warm_started(self) -> bool:
        """True when the result came from the warm start (False after the core's cold retry)."""
        return self.result.warm_started


@dataclass(frozen=True)
class Rejected(PairHeader):
    """A pair that produced no result: ``reason`` says why, ``input`` which side was bad
    ('model', 'data', or 'pair': frames, geometry, registration)."""

    reason: str
    input: RejectedInput
    timings: Timings = field(default_factory=Timings)


# What one (model, data) pair produced; tell them apart with isinstance (or ``match``).
PairOutcome = Registered | Rejected


class RegistrationPipeline:
    """Holds the settings, the converted model (cached per model message) and the warm start.

    Not thread-safe: exactly one thread may use it. Streams drive it through
    ``frisicp_ros.stream.loop``, which applies settings changes and resets from other threads
    between pairs.
    """

    def __init__(self, settings: PipelineSettings | None = None) -> None:
        self.settings = settings or settings_from({})
        self._motion = MotionTracker()  # the last consecutive reliable results
        self._track: RegistrationResult | None = None  # the last reliable result (jump detection)
        self._model_cache: tuple[PointCloud2Like, PreparedModel] | None = None
        self._frames: dict[str, str] = {}
        self._guess: InitialGuess | None = None
        self._depth_steps = DepthStepCheck()

    @property
    def previous(self) -> Similarity | None:
        """The last reliable result, which the next pair's warm start comes from (None: cold start)."""
        return self._motion.last

    def warm_start_for(self, stamp_ns: int) -> Similarity | None:
        """Where a pair stamped ``stamp_ns`` would start (None: cold): the last result, or with
        ``motion_model`` constant_velocity that result moved on by the last motion."""
        if not self.settings.warm_start:
            return None
        if self.settings.motion_model == MotionModel.NONE:
            return self.previous
        return self._motion.predict(stamp_ns)

    @property
    def guess(self) -> InitialGuess | None:
        """The initial guess the next registration will search around (None: none pending)."""
        return self._guess

    def guess_next(self, guess: InitialGuess | None) -> None:
        """Register the next pair cold, searching around ``guess`` (its sigmas bound the search)
        instead of from the warm start; later pairs track from that result as usual."""
        self._guess = guess

    def reset(self) -> None:
        """Forget the warm start, the cached model and the frames seen so far (not a pending
        guess: that is the user's latest word on where the data is)."""
        self._motion.reset()
        self._track = None
        self._model_cache = None
        self._frames = {}
        self._depth_steps.reset()

    def update_settings(self, settings: PipelineSettings) -> None:
        """New settings; anything they invalidate (point caps, voxels, dims) is forgotten."""
        old = self.settings
        if (
            settings.dims,
            settings.max_points,
            settings.voxel_size,
            settings.voxel_mode,
            settings.registration.seed,
        ) != (old.dims, old.max_points, old.voxel_size, old.voxel_mode, old.registration.seed):
            self.reset()
        self.settings = settings

    def process(self, model_msg: PointCloud2Like, data_msg: PointCloud2Like) -> PairOutcome:
        """The outcome of one pair; only a reliable result is kept as the next warm start."""
        header = pair_header(model_msg, data_msg, self.settings.dims)
        guessed = self._guess is not None
        try:
            outcome = self._process(header, model_msg, data_msg)
        except Exception as err:  # noqa: BLE001 - a stream must outlive any one pair
            # The conversions and the core reject bad input with reasons; anything else is a bug,
            # still reported per pair (with its type) instead of ending the stream.
            outcome = Rejected(**vars(header), reason=f"unexpected {describe(err)}", input="pair")
        if isinstance(outcome, Registered) and outcome.reliable:
            if guessed and self._guess is None:  # the guess was used: no velocity across it
                self._motion.reset()
            self._motion.update(header.stamp_ns, outcome.result.similarity)
            self._track = outcome.result
        else:
            self._motion.reset()  # a rejection or an implausible result: next pair starts cold
            self._track = None
        return outcome

    def _process(
        self, header: PairHeader, model_msg: PointCloud2Like, data_msg: PointCloud2Like
    ) -> PairOutcome:
        settings = self.settings
        frame_problem = self._check_frames(header.model_frame, header.data_frame)
        if frame_problem:
            return Rejected(**vars(header), reason=frame_problem, input="pair")
        try:
            model, model_read = self._model(model_msg)
        except CloudError as err:
            return Rejected(**vars(header), reason=f"model cloud: {err}", input="model")
        except ValueError as err:  # points the core cannot register against (degenerate, too few)
            return Rejected(**vars(header), reason=f"registration: {err}", input="model")
        try:
            data = self._read(data_msg)
        except CloudError as err:
            return Rejected(**vars(header), reason=f"data cloud: {err}", input="data")
        depth_steps = self._depth_steps.look(data.points, header.data_frame)
        advice = depth_step_advice(depth_steps, settings.voxel_mode, settings.voxel_size)
        # A pending guess replaces the warm start for this one registration (used up even when the
        # core refuses the pair: a guess is for the next registration, not for a later one).
        guess, self._guess = self._guess, None
        initial = None if guess is not None else self.warm_start_for(header.stamp_ns)
        config = replace(
            settings.registration,
            initial=initial,
            guess=guess,
            # Averaged by the settings already: not again (frisicp_ros.stream.depth_check).
            average_depth_steps=settings.registration.average_depth_steps
            and not averaged_by_settings(depth_steps, settings.voxel_mode, settings.voxel_size),
        )
        started, started_cpu = time.perf_counter(), time.thread_time()
        try:
            result = register(
                data.points,
                model,
                config,
                previous=self._track if initial is not None else None,
            )
        except ValueError as err:  # degenerate geometry, too few points, coordinates that overflow
            timings = _timings(model_read, data, started, started_cpu)
            return Rejected(**vars(header), reason=f"registration: {err}", input="pair", timings=timings)
        timings = _timings(model_read, data, started, started_cpu)
        self._frames = {"model": header.model_frame, "data": header.data_frame}
        # Averaged by the core (result.depth_averaged), the points registered are its finest level's.
        finest = result.levels[-1] if result.depth_averaged is not None and result.levels else None
        return Registered(
            **vars(header),
            result=result,
            data_points=len(data.points) if finest is None else finest.data_points,
            model_points=result.window_points or (len(model) if finest is None else finest.model_points),
            timings=timings,
            depth_steps=depth_steps,
            depth_step_advice=advice,
        )

    def _read(self, msg: CloudLayoutLike, capped: bool = True) -> CloudPoints:
        settings = self.settings
        cap = settings.max_points if capped else None
        return read_cloud(
            msg, settings.dims, cap, settings.registration.seed, settings.voxel_size, settings.voxel_mode
        )

    def _model(self, model_msg: PointCloud2Like) -> tuple[PreparedModel, CloudPoints | None]:
        """The model prepared for registration (frisicp_core.PreparedModel), once per message: in
        latest_model mode the same message serves every scan. Full resolution: ``max_points``
        caps data clouds only; a random cap of a 2,000,000-point map to 10,000 points kept one
        point in 200 of those a scan meets, and every pose against it was wrong (issue 19).
        Returns the read's costs (preparation counted as down-sampling) when it was read now;
        ``ValueError`` for points the core cannot register against."""
        if self._model_cache is not None and self._model_cache[0] is model_msg:
            return self._model_cache[1], None
        read = self._read(model_msg, capped=False)
        started = time.perf_counter()
        with np.errstate(all="ignore"):  # absurd coordinates are the core's to reject, with a reason
            prepared = PreparedModel(read.points, copy=False)  # the read's own array
        read = replace(read, downsample_seconds=read.downsample_seconds + time.perf_counter() - started)
        self._model_cache = (model_msg, prepared)
        return prepared, read

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
                if settings.pairing == PairingMode.SYNCHRONIZED:
                    return (
                        f"frame mismatch: {side} cloud is in '{frame}' but this {side} stream was in"
                        f" '{seen}' (synchronized pairing needs fixed frames; call ~/reset to accept)"
                    )
                self._motion.reset()
        return None


def _timings(model: CloudPoints | None, data: CloudPoints, started: float, started_cpu: float) -> Timings:
    reads = [data] if model is None else [model, data]
    return Timings(
        convert_seconds=sum(read.convert_seconds for read in reads),
        downsample_seconds=sum(read.downsample_seconds for read in reads),
        register_seconds=time.perf_counter() - started,
        register_cpu_seconds=time.thread_time() - started_cpu,
    )


def pair_header(model_msg: PointCloud2Like, data_msg: PointCloud2Like, dims: int) -> PairHeader:
    stamp = data_msg.header.stamp
    return PairHeader(
        stamp=(int(stamp.sec), int(stamp.nanosec)),
        model_frame=str(model_msg.header.frame_id),
        data_frame=str(data_msg.header.frame_id),
        dims=dims,
    )


def describe(err: BaseException) -> str:
    text = str(err).strip()
    return f"{type(err).__name__}: {text}" if text else type(err).__name__
