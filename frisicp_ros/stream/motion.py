"""The warm start of a moving sensor: a constant-velocity prediction of the next similarity. No ROS.

Tracking starts each registration from an estimate of its answer. The previous answer is a good
start for a sensor at rest, but a sensor that moves between scans leaves it behind by one scan's
motion, and ICP then spends its iterations catching up (docs/node.md: a sensor at ~0.5 m/s
turning ~10°/s at 10 Hz). As in lidar odometry (KISS-ICP, LOAM), the sensor is assumed to keep
its velocity: with T1 the last result and T0 the one before (both map data into the model
frame), the data frame moved by D = T0^-1 T1 in the stamp gap between them; the next start is
T1 moved on by that velocity for the next gap.

Two details keep the prediction from adding noise where there is no motion:

- only the rigid part of D is a motion: the scale is the sensor's (or the map's), so a change of
  scale between two estimates is their noise and is not extrapolated;
- the velocity is smoothed (exponentially, weight :data:`SMOOTHING` for the newest motion): the
  difference of two noisy estimates is a noisy velocity, and extrapolating it raw would make
  the start of a sensor at rest sqrt(3) times worse than the last result itself.

The prediction is only a start: the registration corrects it, and the core retries an
implausible warm-started result cold. It needs increasing header stamps (a gap <= 0 or more than
:data:`MAX_GAP_RATIO` times the last one forgets the velocity and starts from the last result).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from frisicp_core import Similarity, axis_angle_rotation


class MotionModel(str, Enum):
    """How a warm start follows a moving sensor; the values are the ``motion_model`` parameter's."""

    CONSTANT_VELOCITY = "constant_velocity"  # the last result moved on by the recent velocity
    NONE = "none"  # the last result as it is


MOTION_MODELS: tuple[str, ...] = tuple(model.value for model in MotionModel)
SMOOTHING = 0.5  # weight of the newest motion in the velocity estimate
MAX_GAP_RATIO = 4.0  # a gap this many times the last one (missed scans, a pause): no prediction
MAX_TURN_RAD = np.pi / 2  # a turn this large between two results is no steady motion


@dataclass(frozen=True)
class Velocity:
    """Rigid motion of the data frame per second: rotation vector (3-D; the angle in 2-D) and
    translation, both in the data frame's units."""

    rotation: np.ndarray
    translation: np.ndarray


class MotionTracker:
    """Follows the reliable results of one stream and predicts the next warm start."""

    def __init__(self) -> None:
        self._last: tuple[int, Similarity] | None = None
        self._gap_ns = 0
        self._velocity: Velocity | None = None

    @property
    def last(self) -> Similarity | None:
        return None if self._last is None else self._last[1]

    def reset(self) -> None:
        self._last, self._gap_ns, self._velocity = None, 0, None

    def update(self, stamp_ns: int, similarity: Similarity) -> None:
        """A new reliable result for the data cloud stamped ``stamp_ns``."""
        if self._last is not None:
            last_stamp, last = self._last
            gap = stamp_ns - last_stamp
            rate = None
            if gap > 0 and (self._gap_ns <= 0 or gap < MAX_GAP_RATIO * self._gap_ns):
                rate = velocity_of(last.inverse() @ similarity, gap * 1e-9)
            if rate is None:
                self._velocity = None
            elif self._velocity is None:
                self._velocity = rate
            else:
                self._velocity = Velocity(
                    self._velocity.rotation + SMOOTHING * (rate.rotation - self._velocity.rotation),
                    self._velocity.translation + SMOOTHING * (rate.translation - self._velocity.translation),
                )
            self._gap_ns = gap
        self._last = (stamp_ns, similarity)

    def predict(self, stamp_ns: int) -> Similarity | None:
        """The warm start of the data cloud stamped ``stamp_ns`` (None before any result)."""
        if self._last is None:
            return None
        last_stamp, last = self._last
        gap = stamp_ns - last_stamp
        if self._velocity is None or gap <= 0 or gap >= MAX_GAP_RATIO * self._gap_ns:
            return last
        return last @ motion_of(self._velocity, gap * 1e-9, last.dim)


def velocity_of(motion: Similarity, seconds: float) -> Velocity | None:
    """The rigid part of ``motion`` per second (None for a turn beyond :data:`MAX_TURN_RAD` or
    above 3-D). The rotation is its rotation vector (exact); the translation is divided as it is,
    which for a screw motion is off by about angle x translation: sub-millimetre for a scan."""
    angle = motion.rotation_angle()
    if angle > MAX_TURN_RAD or motion.dim > 3:
        return None
    rotation = motion.rotation
    if motion.dim == 2:
        vector = np.array([np.arctan2(rotation[1, 0], rotation[0, 0])])
    else:
        # 2 sin(angle) times the axis; the angle from the trace is noisy near 0 (arccos), so an
        # exactly symmetric matrix can report a tiny angle with no axis: no rotation then.
        axis = np.array(
            [
                rotation[2, 1] - rotation[1, 2],
                rotation[0, 2] - rotation[2, 0],
                rotation[1, 0] - rotation[0, 1],
            ]
        )
        norm = float(np.linalg.norm(axis))
        vector = axis / norm * angle if norm > 1e-12 else np.zeros(3)
    return Velocity(vector / seconds, motion.translation / seconds)


def motion_of(velocity: Velocity, seconds: float, dim: int) -> Similarity:
    """The rigid motion of ``velocity`` kept up for ``seconds``."""
    vector = velocity.rotation * seconds
    if dim == 2:
        cos, sin = np.cos(vector[0]), np.sin(vector[0])
        rotation = np.array([[cos, -sin], [sin, cos]])
    else:
        angle = float(np.linalg.norm(vector))
        rotation = axis_angle_rotation(vector, angle) if angle > 1e-12 else np.eye(3)
    return Similarity(1.0, rotation, velocity.translation * seconds)
