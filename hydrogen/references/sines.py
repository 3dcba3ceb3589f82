"""A sum of sines about the neutral pose: q_d(t) = bias + Σ_k a_k sin(2π f_k t), per coordinate, with
its analytic derivatives up to the third (the paper's multi-sine references, section V)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["KEY", "SYNTAX", "Reference", "MultiSine"]

KEY = "sines"
SYNTAX = "[[coordinate, amplitude, Hz], ...]"

FIELDS = (("n_terms", "long long", "P_REF_N_TERMS"), ("terms", "const double*", "P_REF_TERMS"))
COMMENT = "sum of amplitude sin(2 pi f t) over terms (coordinate, amplitude, frequency)"
#: No term (C has no zero-length array: one row of zeros, its count 0).
IDLE = {"n_terms": 0, "terms": np.zeros(3)}
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


def sizes(values: dict) -> dict:
    """The number of entries each of its configuration arrays must hold, from the values."""
    return {"terms": 3 * max(int(values["n_terms"]), 1)}


def axes(values: dict) -> list:
    """The coordinate indices the C loop reads from the values (each term's)."""
    return [t[0] for t in np.reshape(values["terms"], (-1, 3))[: int(values["n_terms"])]]


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
        return cls(bias, tuple((axis(c), float(a), float(f)) for c, a, f in value))

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
        terms = self.terms
        if isinstance(terms, (str, bytes)) or not hasattr(terms, "__iter__"):
            fail("reference.terms", "must be a sequence of (axis, amplitude, frequency Hz)", terms)
        for j, term in enumerate(terms):
            if isinstance(term, (str, bytes)) or not hasattr(term, "__len__") or len(term) != 3:
                fail(f"reference.terms[{j}]", "must be (axis, amplitude, frequency Hz)", term)
            ax, amp, freq = term
            axis(f"reference.terms[{j}] axis", ax)
            finite(f"reference.terms[{j}] amplitude", amp)
            finite(f"reference.terms[{j}] frequency", freq)

    def config(self) -> dict:
        """Its values of FIELDS."""
        terms = tuple(self.terms)
        return {"n_terms": len(terms), "terms": np.array(terms, float).reshape(-1) if terms else np.zeros(3)}


#: Its former name (hydrogen.simulation.reference.MultiSine).
MultiSine = Reference
