"""Case families of the paper's protocol and the seeded perturbation of each case.

A *family* is a (data, model) pair whose data is already placed in the model frame, by the
true pose (a shape against itself, the bunny scans through bun.conf) or by a reference
placement (two different silhouettes, see :mod:`.reference`). A *case* perturbs the placed
data by a similarity G: scale s about the model centroid, a seeded rotation and translation.
The registration that undoes it, G^-1, is what every method is scored against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frisicp_core import FloatArray, Similarity, axis_angle_rotation

from .metrics import model_size

# The paper's 15 scale factors: s in [0.1, 3.0] with step 0.2.
PAPER_SCALES: tuple[float, ...] = tuple(round(0.1 + 0.2 * k, 1) for k in range(15))

# The seeded misplacement added to the scale (fixed before any result was seen): a rotation by
# an angle uniform in [0, MAX_ROTATION_DEG] (random sign in 2-D, random axis in 3-D) and a
# translation of TRANSLATION_FRACTION times the model size in a random direction.
MAX_ROTATION_DEG = 30.0
TRANSLATION_FRACTION = 0.1


@dataclass(frozen=True)
class Family:
    """One (data, model) pair with the data placed in the model frame."""

    name: str  # e.g. "deer 2→1"
    kind: str  # "2-D" or "3-D", the table it belongs to
    units: str  # of the coordinates: "px" or "mm"
    data: FloatArray
    model: FloatArray
    true_pose: bool  # False: the placement is a reference, not ground truth
    reference_rms: float | None = None  # symmetric RMS of the reference placement
    figure: str | None = None  # file name of a registration picture of this family, if one is drawn

    @property
    def dim(self) -> int:
        return int(self.model.shape[1])

    @property
    def size(self) -> float:
        return model_size(self.model)


@dataclass(frozen=True)
class Case:
    family: Family
    scale: float
    perturbation: Similarity  # data of the case = perturbation(family.data)

    @property
    def data(self) -> FloatArray:
        return self.perturbation.apply(self.family.data)

    @property
    def truth(self) -> Similarity:
        """The registration to find: maps the case's data back onto the placed data."""
        return self.perturbation.inverse()


def random_rotation(dim: int, max_degrees: float, rng: np.random.Generator) -> np.ndarray:
    """Rotation by an angle uniform in [0, max_degrees]; random sign (2-D) or axis (3-D)."""
    angle = np.radians(rng.uniform(0.0, max_degrees))
    if dim == 2:
        angle *= rng.choice((-1.0, 1.0))
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, -s], [s, c]])
    if dim != 3:
        raise ValueError(f"only 2-D and 3-D cases exist, got {dim}-D")
    return axis_angle_rotation(rng.normal(size=3), angle)


def perturbation(family: Family, scale: float, rng: np.random.Generator) -> Similarity:
    """G(x) = s R (x - c) + c + t with c the model centroid: the data scaled in place, turned, moved."""
    dim = family.dim
    rotation = random_rotation(dim, MAX_ROTATION_DEG, rng)
    direction = rng.normal(size=dim)
    shift = TRANSLATION_FRACTION * family.size * direction / np.linalg.norm(direction)
    centre = family.model.mean(axis=0)
    return Similarity.about(centre, scale, rotation, shift)


def make_cases(family: Family, scales: tuple[float, ...], seed: int) -> list[Case]:
    """One case per scale; a (family, scale) pair always gets the same perturbation for a seed."""
    cases = []
    for scale in scales:
        # Seeded by (seed, family, scale) so a subset run (--quick) reproduces the full run's cases.
        rng = np.random.default_rng([seed, _stable_hash(family.name), round(scale * 1000)])
        cases.append(Case(family, scale, perturbation(family, scale, rng)))
    return cases


def _stable_hash(text: str) -> int:
    """A hash that, unlike ``hash(str)``, is the same in every Python process."""
    return int.from_bytes(text.encode("utf-8"), "little") % (2**63)
