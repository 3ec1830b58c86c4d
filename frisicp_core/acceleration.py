"""Anderson acceleration of the ICP fixed-point iteration (Pavlov et al. 2018, Zhang et al. 2021).

ICP is a fixed-point iteration T_{k+1} = G(T_k) (correspond, then solve in closed form) that
converges linearly, slowly when the error surface is flat (partial overlap, noise). Anderson
acceleration extrapolates from the last few (T_k, G(T_k)): with residuals f_k = G(T_k) - T_k in a
vector parametrisation x of T, it proposes

    x_{k+1} = G_k - sum_j gamma_j (G_j - G_{j-1}),   gamma = argmin ||f_k - sum_j gamma_j (f_j - f_{j-1})||.

The caller accepts a proposal only if it lowers the error; otherwise it takes the plain step and
calls :meth:`reset`, so the error never increases.

Parametrisation, relative to a reference similarity T0 = (s0, R0, t0) and the data centroid mu:
x = (log(s / s0), log(R R0^T) as an so(m) vector, (T(mu) - T0(mu)) / radius). Using where the
centroid lands instead of t decouples translation from rotation, and dividing by the model radius
makes the three blocks comparable, which the least-squares step above needs.
"""

from __future__ import annotations

import numpy as np

from .rotations import exp_rotation, log_rotation
from .similarity import FloatArray, Similarity


class AndersonAccelerator:
    """Proposes extrapolated similarities from the history of (T_k, G(T_k))."""

    def __init__(self, reference: Similarity, centroid: FloatArray, radius: float, memory: int = 5) -> None:
        self.reference = reference
        self.centroid = centroid
        self.radius = radius
        self.memory = memory
        self._anchor = reference.apply(centroid)
        self._iterates: list[FloatArray] = []
        self._residuals: list[FloatArray] = []

    def encode(self, sim: Similarity) -> FloatArray:
        # A cloud of no extent (radius 0, hostile input) encodes as inf/NaN, which the caller's
        # finiteness checks reject; numpy need not warn about it on the way.
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.concatenate(
                (
                    [np.log(sim.scale / self.reference.scale)],
                    log_rotation(sim.rotation @ self.reference.rotation.T),
                    (sim.apply(self.centroid) - self._anchor) / self.radius,
                )
            )

    def decode(self, x: FloatArray) -> Similarity:
        dim = self.centroid.shape[0]
        scale = self.reference.scale * float(np.exp(x[0]))
        rotation = exp_rotation(x[1:-dim], dim) @ self.reference.rotation
        landing = self._anchor + x[-dim:] * self.radius
        return Similarity._trusted(scale, rotation, landing - scale * rotation @ self.centroid)

    def propose(self, current: Similarity, step: Similarity) -> Similarity | None:
        """An accelerated successor of ``current`` given its plain step G(current); None until
        there is history to extrapolate from."""
        x = self.encode(current)
        g = self.encode(step)
        self._iterates.append(g)
        self._residuals.append(g - x)
        if len(self._residuals) > self.memory + 1:
            del self._iterates[0], self._residuals[0]
        if len(self._residuals) < 2:
            return None
        d_res = np.diff(np.array(self._residuals), axis=0).T
        d_its = np.diff(np.array(self._iterates), axis=0).T
        gamma, *_ = np.linalg.lstsq(d_res, self._residuals[-1], rcond=None)
        proposal = g - d_its @ gamma
        if not np.all(np.isfinite(proposal)):
            return None
        return self.decode(proposal)

    def reset(self) -> None:
        self._iterates.clear()
        self._residuals.clear()
