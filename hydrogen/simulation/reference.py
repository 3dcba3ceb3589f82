"""Reference trajectories q_d(t) with analytic derivatives up to third order (generalized coordinates, SI)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MultiSine", "Step"]


@dataclass(frozen=True)
class MultiSine:
    """q_d(t) = bias + Σ_k a_k sin(2π f_k t), per coordinate.

    ``terms`` is a list of (coordinate index, amplitude, frequency Hz).
    """

    bias: np.ndarray
    terms: tuple

    def __call__(self, t: float):
        """(q_d, q̇_d, q̈_d, q⃛_d) at time t (s), each (n,)."""
        n = len(self.bias)
        out = [np.array(self.bias, float), np.zeros(n), np.zeros(n), np.zeros(n)]
        for i, a, f in self.terms:
            w = 2 * np.pi * f
            s, c = np.sin(w * t), np.cos(w * t)
            out[0][i] += a * s
            out[1][i] += a * w * c
            out[2][i] -= a * w * w * s
            out[3][i] -= a * w ** 3 * c
        return out

    def positions(self, t) -> np.ndarray:
        """q_d at each time of the array ``t`` (k, n), vectorised."""
        t = np.asarray(t, float)
        out = np.tile(np.asarray(self.bias, float), (t.size, 1))
        for i, a, f in self.terms:
            out[:, i] += a * np.sin(2 * np.pi * f * t)
        return out

    def velocities(self, t) -> np.ndarray:
        """q̇_d at each time of the array ``t`` (k, n), vectorised."""
        t = np.asarray(t, float)
        out = np.zeros((t.size, len(self.bias)))
        for i, a, f in self.terms:
            w = 2 * np.pi * f
            out[:, i] += a * w * np.cos(w * t)
        return out

    def amplitude(self) -> np.ndarray:
        """Per-coordinate sum of amplitudes (m or rad); the scale of the max-error percentages."""
        amp = np.zeros(len(self.bias))
        for i, a, _ in self.terms:
            amp[i] += abs(a)
        return amp


@dataclass(frozen=True)
class Step:
    """q_d = bias + height e_axis for t ≥ t_step (a raw step, derivatives zero, as in Fig. 8)."""

    bias: np.ndarray
    axis: int
    height: float
    t_step: float

    def __call__(self, t: float):
        q = np.array(self.bias, float)
        if t >= self.t_step:
            q[self.axis] += self.height
        n = q.size
        return [q, np.zeros(n), np.zeros(n), np.zeros(n)]

    def positions(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        out = np.tile(np.asarray(self.bias, float), (t.size, 1))
        out[t >= self.t_step, self.axis] += self.height
        return out

    def velocities(self, t) -> np.ndarray:
        """Zero (a raw step has no derivative but at the step itself, which the loop never samples)."""
        return np.zeros((np.asarray(t, float).size, len(self.bias)))

    def amplitude(self) -> np.ndarray:
        amp = np.zeros(len(self.bias))
        amp[self.axis] = abs(self.height)
        return amp
