"""A sum of sines about the neutral pose: q_d(t) = bias + Σ_k a_k sin(2π f_k t), per coordinate, with
its analytic derivatives up to the third (the paper's multi-sine references, section V)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._table import RowTable, number

__all__ = ["KEY", "SYNTAX", "Reference", "MultiSine"]

KEY = "sines"
SYNTAX = "[[coordinate, amplitude, Hz], ...]"

#: The terms as rows (coordinate, amplitude, frequency) of the loop's configuration.
TABLE = RowTable("n_terms", "terms", ("amplitude", "frequency Hz"), key=KEY)
FIELDS, IDLE, sizes, axes = TABLE.fields, TABLE.idle, TABLE.sizes, TABLE.axes
COMMENT = "sum of amplitude sin(2 pi f t) over terms (coordinate, amplitude, frequency)"
C_BODY = """\
    {
        long long j;
        for (j = 0; j < c->n_terms; ++j) {
            double axis = c->terms[3 * j];
            double a = c->terms[3 * j + 1], w = TWO_PI * c->terms[3 * j + 2];
            double sn, co;
            int ax;
            if (!(axis >= 0 && axis < NQ)) continue;  /* never index with an unchecked value */
            ax = (int)axis;
            sn = sin(w * t);
            co = cos(w * t);
            qd[ax] += a * sn;
            qd[NQ + ax] += a * w * co;
            qd[2 * NQ + ax] -= a * w * w * sn;
            qd[3 * NQ + ax] -= a * w * w * w * co;
        }
    }
"""


@dataclass(frozen=True)
class Reference:
    """q_d(t) = bias + Σ_k a_k sin(2π f_k t), per coordinate.

    ``terms`` is a list of (coordinate index, amplitude m or rad, frequency Hz).
    """

    bias: np.ndarray
    terms: tuple

    STEP_RESPONSE = False

    @classmethod
    def parse(cls, value, axis, bias):
        """From the description's ``[[coordinate, amplitude, Hz], ...]``."""
        return cls(bias, tuple((axis(c), number(a), number(f)) for c, a, f in value))

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

    def frequencies(self) -> tuple:
        """The frequencies (Hz, as given) of the terms that move."""
        return tuple(f for _, a, f in self.terms if a)

    def check(self, fail, axis, finite) -> None:
        """Each term (axis, amplitude, frequency) the C loop reads valid, else ``fail(field, what,
        value)``; ``axis(field, value)`` and ``finite(field, value)`` check one value."""
        TABLE.check(self.terms, fail, axis, finite)
        for j, (_, _, f) in enumerate(self.terms):
            if f < 0:  # sin(−ωt) is a negative amplitude: a sign in the wrong column
                fail(f"reference.{KEY}[{j}] frequency", "must be >= 0 Hz (a negative amplitude reverses a term)", f)

    def config(self) -> dict:
        """Its values of FIELDS."""
        return TABLE.config(self.terms)


#: Its former name (hydrogen.simulation.reference.MultiSine).
MultiSine = Reference
