"""Initial guesses as ROS and command lines give them, converted to the core's ``InitialGuess``.

One conversion for the node (``~/initial_guess``, a geometry_msgs/PoseWithCovarianceStamped as
RViz's "2D Pose Estimate" sends on /initialpose), its bag replay, ``frisicp bag --initial`` and
``frisicp register --initial``:

- the pose (position, orientation) is (R, t) of the guessed similarity, model ~ s R data + t;
- the rotation's 1-sigma is the square root of the largest eigenvalue of the covariance's
  roll/pitch/yaw block, in degrees; the translation's of the x/y/z block (RViz sends 0.25 on x and
  y and 0.0685 on yaw: 0.5 m and 15 degrees);
- the scale is given separately (the node's ``initial_scale`` parameter, the command line's 8th
  value): known within :data:`KNOWN_SCALE_SIGMA` (1 %) unless told otherwise, or unknown (0 / not
  given), in which case the core searches it.

In 2-D (``dims`` 2) the guess is x, y and the yaw: the pose's rotation about z (roll and pitch are
dropped) and the x/y block and yaw variance of the covariance, as RViz sends them.

The command-line form (:func:`parse_initial`): ``--initial "x y z qx qy qz qw [scale]"`` and
``--initial-sigma ROT_DEG,TRANS[,SCALE]`` (SCALE relative, used only when a scale is given).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from frisicp_core import InitialGuess, Similarity
from frisicp_ros.stream.messages import PoseWithCovarianceStampedLike

# 1-sigma, relative, of a scale the user gives (``initial_scale``, --initial's 8th value): a known
# mounting or map scale, not a measurement. The core searches scales only when the scale is unknown.
KNOWN_SCALE_SIGMA = 0.01
POSE_FORMAT = "x y z qx qy qz qw [scale]"
SIGMA_FORMAT = "ROT_DEG,TRANS[,SCALE]"


def guess_from_pose(
    position: Sequence[float],
    orientation_xyzw: Sequence[float],
    covariance: Sequence[float] | np.ndarray,
    dims: int,
    scale: float | None = None,
    scale_sigma: float = KNOWN_SCALE_SIGMA,
) -> InitialGuess:
    """The core's guess for a pose with a ROS 6x6 covariance (x y z roll pitch yaw, row-major).

    ``scale`` None (or 0) is unknown. Raises ValueError naming what is wrong (non-finite values,
    a zero quaternion, a negative variance, a scale <= 0).
    """
    values = np.asarray(covariance, dtype=np.float64).reshape(-1)
    if values.size != 36:
        raise ValueError(f"a pose covariance has 36 values, got {values.size}")
    block = values.reshape(6, 6)
    rotation_deg, translation = _sigmas(block, dims)
    similarity = _similarity(position, orientation_xyzw, dims, scale or 1.0)
    known = scale is not None and scale != 0
    if known and not (math.isfinite(scale_sigma) and scale_sigma >= 0):
        raise ValueError(f"the scale's sigma must be finite and >= 0, got {scale_sigma}")
    return InitialGuess(similarity, rotation_deg, translation, scale=scale_sigma if known else None)


def guess_from_message(
    msg: PoseWithCovarianceStampedLike, dims: int, scale: float | None = None
) -> InitialGuess:
    """:func:`guess_from_pose` of a PoseWithCovarianceStamped (rclpy or rosbags)."""
    pose = msg.pose.pose
    p, q = pose.position, pose.orientation
    return guess_from_pose([p.x, p.y, p.z], [q.x, q.y, q.z, q.w], msg.pose.covariance, dims, scale)


def parse_initial(pose_text: str, sigma_text: str | None, dims: int) -> InitialGuess:
    """``--initial`` and ``--initial-sigma`` (module doc); ValueError says what is malformed."""
    numbers = _numbers(pose_text, "--initial", POSE_FORMAT)
    if len(numbers) not in (7, 8):
        raise ValueError(f'--initial takes 7 or 8 numbers, "{POSE_FORMAT}"; got {len(numbers)}')
    if sigma_text is None:
        raise ValueError(f"--initial needs --initial-sigma {SIGMA_FORMAT}: how far off the guess may be")
    sigmas = _numbers(sigma_text.replace(",", " "), "--initial-sigma", SIGMA_FORMAT)
    if len(sigmas) not in (2, 3):
        raise ValueError(f"--initial-sigma takes 2 or 3 numbers, {SIGMA_FORMAT}; got {len(sigmas)}")
    rotation_deg, translation = sigmas[0], sigmas[1]
    scale = numbers[7] if len(numbers) == 8 else None
    scale_sigma = sigmas[2] if len(sigmas) == 3 else KNOWN_SCALE_SIGMA
    # The covariance whose largest eigenvalues give these sigmas back.
    covariance = np.diag([translation**2] * 3 + [math.radians(rotation_deg) ** 2] * 3)
    return guess_from_pose(numbers[:3], numbers[3:7], covariance.reshape(-1), dims, scale, scale_sigma)


def describe_guess(guess: InitialGuess) -> str:
    """One line for logs: where the guess puts the data and how sure it is."""
    sim = guess.similarity
    scale = "unknown" if guess.scale is None else f"{sim.scale:.6g} (sigma {guess.scale:.1%})"
    position = ", ".join(f"{v:.4g}" for v in sim.translation)
    return (
        f"position ({position}) sigma {guess.translation:.3g}, rotation"
        f" {math.degrees(sim.rotation_angle()):.1f} deg sigma {guess.rotation_deg:.3g} deg, scale {scale}"
    )


def _numbers(text: str, option: str, form: str) -> list[float]:
    try:
        numbers = [float(word) for word in text.split()]
    except ValueError:
        raise ValueError(f'{option} takes numbers, "{form}"; got {text!r}') from None
    if not all(math.isfinite(n) for n in numbers):
        raise ValueError(f"{option} must be finite numbers, got {text!r}")
    return numbers


def _sigmas(covariance: np.ndarray, dims: int) -> tuple[float, float]:
    """(rotation sigma in degrees, translation sigma) from a ROS 6x6 pose covariance."""
    if not np.all(np.isfinite(covariance)):
        raise ValueError("the guess's covariance has NaN or infinite values")
    if dims == 2:
        position, rotation = covariance[:2, :2], covariance[5:, 5:]
    else:
        position, rotation = covariance[:3, :3], covariance[3:, 3:]
    if np.any(np.diag(position) < 0) or np.any(np.diag(rotation) < 0):
        raise ValueError("the guess's covariance has a negative variance")
    largest = [float(max(np.linalg.eigvalsh(0.5 * (b + b.T))[-1], 0.0)) for b in (rotation, position)]
    return math.degrees(math.sqrt(largest[0])), math.sqrt(largest[1])


def _similarity(
    position: Sequence[float], orientation_xyzw: Sequence[float], dims: int, scale: float
) -> Similarity:
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"the guess's scale must be positive, got {scale}")
    q = np.asarray(orientation_xyzw, dtype=np.float64)
    t = np.asarray(position, dtype=np.float64)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(t))):
        raise ValueError("the guess's pose has NaN or infinite values")
    norm = float(np.linalg.norm(q))
    if norm < 1e-9:
        raise ValueError("the guess's orientation is a zero quaternion")
    rotation = Similarity.from_quaternion(1.0, q / norm, t).rotation
    if dims == 2:
        yaw = math.atan2(rotation[1, 0], rotation[0, 0])  # the rotation about z; roll, pitch dropped
        turn = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        return Similarity(scale, turn, t[:2])
    return Similarity(scale, rotation, t)
