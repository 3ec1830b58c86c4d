"""Registration in units where the clouds are of order one, so any finite coordinates work.

ICP squares coordinates and distances, and float64 squares overflow above about 1.3e154 and
vanish below about 1.5e-154 (in sums over many points, sooner). Clouds in large or tiny units
(the bunny in metres times 1e80, or times 1e-300), or two clouds whose units differ by dozens of
orders of magnitude, once failed in the middle of a registration (an IndexError, "all points
are identical"). :func:`register <frisicp_core.register>` therefore registers ``data / u_d``
onto ``model / u_m`` and maps the result back:

    model ≈ s R data + t   <=>   model / u_m ≈ (s u_d / u_m) R (data / u_d) + t / u_m.

The units are powers of two, so dividing by them is exact in binary floating point (only the
exponent changes): the scaled problem is the given one, every number of the registration is
the given one's times a power of two, and the result maps back without rounding.

Which units (:meth:`Units.of`), from each cloud's magnitude M (its largest absolute coordinate):

- both M within [2^-64, 2^64] (5e-20 to 1.8e19): ``u_d = u_m = 1``, nothing changes;
- else, M_data / M_model within [2^-64, 2^64]: one unit for both, the power of two nearest to
  sqrt(M_data M_model). The clouds keep a shared frame, which the identity start and the
  in-place hypotheses of ``Initialization.SEARCH`` assume;
- else each cloud its own unit (its M as a power of two): clouds whose sizes differ by more
  than 1.8e19 share no frame to keep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .config import RegistrationConfig
from .result import IterationRecord, RegistrationResult
from .similarity import FloatArray, Similarity

# Magnitudes (and ratios of magnitudes) within 2^-SAFE_EXPONENT .. 2^SAFE_EXPONENT: squares of
# every distance a registration forms, even between poses far off, stay normal float64 numbers.
SAFE_EXPONENT = 64
# Clouds whose magnitudes differ by more than 2^this: the scale between them (within a factor of a
# few of the ratio) would leave float64's range (2^-1074 .. 2^1024).
_LARGEST_SCALE_EXPONENT = 1000


def magnitude_exponent(points: FloatArray) -> int:
    """e with 2^(e-1) <= max |coordinate| < 2^e (0 for all-zero points): the cloud's binary size."""
    largest = float(np.max(np.abs(points)))
    return math.frexp(largest)[1] if largest > 0 else 0


@dataclass(frozen=True)
class Units:
    """The powers of two the data and the model are divided by for the registration."""

    data: float = 1.0
    model: float = 1.0

    @classmethod
    def of(cls, data: FloatArray, model: FloatArray) -> Units:
        """The units for ``data`` and ``model`` (validated point sets; see the module doc)."""
        return cls.of_exponents(magnitude_exponent(data), magnitude_exponent(model))

    @classmethod
    def of_exponents(cls, data_exp: int, model_exp: int) -> Units:
        """The units for clouds of these :func:`magnitude_exponent` (a prepared model keeps its own)."""
        if max(abs(data_exp), abs(model_exp)) <= SAFE_EXPONENT:
            return cls()
        if abs(data_exp - model_exp) <= SAFE_EXPONENT:
            shared = math.ldexp(1.0, (data_exp + model_exp) // 2)
            return cls(shared, shared)
        if abs(model_exp - data_exp) > _LARGEST_SCALE_EXPONENT:
            raise ValueError(_beyond_float64(model_exp - data_exp))
        return cls(math.ldexp(1.0, data_exp), math.ldexp(1.0, model_exp))

    @property
    def unchanged(self) -> bool:
        return self.data == 1.0 and self.model == 1.0

    def scaled(self, data: FloatArray, model: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The clouds in these units (the arrays themselves when nothing changes)."""
        if self.unchanged:
            return data, model
        return data / self.data, model / self.model

    def scaled_data(self, data: FloatArray) -> FloatArray:
        """The data in these units (the array itself when its unit is 1)."""
        return data if self.data == 1.0 else data / self.data

    def config(self, config: RegistrationConfig) -> RegistrationConfig:
        """``config`` for the scaled clouds: the warm start and the initial guess carry units."""
        if self.unchanged or (config.initial is None and config.guess is None):
            return config
        initial = None if config.initial is None else self._scaled_pose(config.initial)
        guess = config.guess
        if guess is not None:
            guess = replace(
                guess,
                similarity=self._scaled_pose(guess.similarity),
                translation=guess.translation / self.model,
            )
        return replace(config, initial=initial, guess=guess)

    def _scaled_pose(self, pose: Similarity) -> Similarity:
        return Similarity(pose.scale * self.data / self.model, pose.rotation, pose.translation / self.model)

    def _restored_pose(self, pose: Similarity) -> Similarity:
        return Similarity(pose.scale * self.model / self.data, pose.rotation, pose.translation * self.model)

    def restore(self, result: RegistrationResult) -> RegistrationResult:
        """The result of the scaled clouds in the given units: similarity and errors (model units).

        Raises ``ValueError`` when the scale between the clouds is beyond float64 (clouds whose
        sizes differ by a factor of more than about 1e308).
        """
        if self.unchanged:
            return result
        sim = result.similarity
        scale = sim.scale * self.model / self.data
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(_beyond_float64(round(math.log2(self.model) - math.log2(self.data))))
        unit = self.model
        uncertainty = result.uncertainty
        if uncertainty is not None:
            # Log-scale and rotation are unitless; the displacement (the last m parameters) and the
            # centre are in model units.
            factors = np.ones(uncertainty.covariance.shape[0])
            factors[-sim.dim :] = unit
            uncertainty = replace(
                uncertainty,
                covariance=uncertainty.covariance * factors[:, None] * factors[None, :],
                centre=uncertainty.centre * unit,
            )
        competitor = result.competitor
        if competitor is not None:
            competitor = replace(competitor, similarity=self._restored_pose(competitor.similarity))
        fit = result.fit
        if fit is not None:
            fit = replace(
                fit,
                expected_residual=fit.expected_residual * unit,
                forward=replace(fit.forward, noise=fit.forward.noise * unit),
                backward=replace(fit.backward, noise=fit.backward.noise * unit),
            )
        return replace(
            result,
            uncertainty=uncertainty,
            competitor=competitor,
            fit=fit,
            similarity=Similarity(scale, sim.rotation, sim.translation * unit),
            rms=result.rms * unit,
            forward_rms=result.forward_rms * unit,
            backward_rms=result.backward_rms * unit,
            levels=tuple(replace(level, rms=level.rms * unit) for level in result.levels),
            history=tuple(_record_in(record, unit) for record in result.history),
        )


def _beyond_float64(exponent: int) -> str:
    return (
        f"the model's coordinates are about 1e{exponent * math.log10(2.0):+.0f} times the data's: the"
        " scale between the clouds is beyond float64's range (about 1e-308 to 1e308); express them in"
        " closer units"
    )


def _record_in(record: IterationRecord, unit: float) -> IterationRecord:
    return replace(
        record,
        rms=record.rms * unit,
        forward_rms=record.forward_rms * unit,
        backward_rms=record.backward_rms * unit,
    )
