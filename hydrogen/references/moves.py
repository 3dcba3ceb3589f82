"""Smooth point-to-point moves: each a minimum-jerk move of one coordinate by a distance, from a start
time over a duration, then held: q_d(t) = bias + Σ_k d_k s((t − t0_k) / T_k), s(τ) = 10τ³ − 15τ⁴ + 6τ⁵
for 0 ≤ τ ≤ 1 (0 before, 1 after), with its analytic derivatives up to the third. The reference of a
work cycle (a boom raised, a slew swung, a load set down) rather than a test signal: its velocity and
acceleration are zero at both ends, and several moves may overlap."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._table import RowTable, number

__all__ = ["KEY", "SYNTAX", "Reference"]

KEY = "moves"
SYNTAX = "[[coordinate, distance, start s, duration s], ...]"

#: The moves as rows (coordinate, distance, start, duration) of the loop's configuration.
TABLE = RowTable("n_moves", "moves", ("distance", "start s", "duration s"))
FIELDS, IDLE, sizes, axes = TABLE.fields, TABLE.idle, TABLE.sizes, TABLE.axes
COMMENT = "minimum-jerk moves over moves (coordinate, distance, start, duration > 0)"
C_BODY = """\
    {
        long long j;
        for (j = 0; j < c->n_moves; ++j) {
            double axis = c->moves[4 * j], d = c->moves[4 * j + 1];
            double t0 = c->moves[4 * j + 2], dur = c->moves[4 * j + 3];
            double tau, t2;
            int ax;
            if (!(axis >= 0 && axis < NQ) || !(dur > 0)) continue;  /* never index with an unchecked value */
            ax = (int)axis;
            if (t >= t0 + dur) {
                qd[ax] += d;
                continue;
            }
            if (t <= t0) continue;
            tau = (t - t0) / dur;
            t2 = tau * tau;
            qd[ax] += d * t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
            qd[NQ + ax] += d / dur * 30.0 * t2 * (1.0 + tau * (-2.0 + tau));
            qd[2 * NQ + ax] += d / (dur * dur) * 60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau));
            qd[3 * NQ + ax] += d / (dur * dur * dur) * 60.0 * (1.0 + tau * (-6.0 + 6.0 * tau));
        }
    }
"""


def _profile(tau):
    """(s, ds/dτ, d²s/dτ², d³s/dτ³) of the minimum-jerk profile at τ (arrays), inside 0 < τ < 1."""
    t2 = tau * tau
    return (t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau)), 30.0 * t2 * (1.0 + tau * (-2.0 + tau)),
            60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau)), 60.0 * (1.0 + tau * (-6.0 + 6.0 * tau)))


@dataclass(frozen=True)
class Reference:
    """q_d(t) = bias + Σ_k d_k s((t − t0_k) / T_k), per coordinate (minimum-jerk moves, then held).

    ``moves`` is a list of (coordinate index, distance m or rad, start s, duration s > 0).
    """

    bias: np.ndarray
    moves: tuple

    STEP_RESPONSE = False

    @classmethod
    def parse(cls, value, axis, bias):
        """From the description's ``[[coordinate, distance, start s, duration s], ...]``."""
        return cls(bias, tuple((axis(c), number(d), number(t0), number(dur)) for c, d, t0, dur in value))

    def _rows(self, t) -> list:
        """(q_d, q̇_d, q̈_d, q⃛_d) at the times of the array ``t``, each (k, n)."""
        t = np.atleast_1d(np.asarray(t, float))
        out = [np.tile(np.asarray(self.bias, float), (t.size, 1))] + [np.zeros((t.size, len(self.bias)))
                                                                      for _ in range(3)]
        for i, d, t0, dur in self.moves:
            out[0][t >= t0 + dur, i] += d
            inside = (t > t0) & (t < t0 + dur)
            for k, s in enumerate(_profile((t[inside] - t0) / dur)):
                out[k][inside, i] += d / dur ** k * s
        return out

    def __call__(self, t: float):
        """(q_d, q̇_d, q̈_d, q⃛_d) at time t (s), each (n,)."""
        return [r[0] for r in self._rows(t)]

    def positions(self, t) -> np.ndarray:
        """q_d at each time of the array ``t`` (k, n), vectorised."""
        return self._rows(t)[0]

    def velocities(self, t) -> np.ndarray:
        """q̇_d at each time of the array ``t`` (k, n), vectorised."""
        return self._rows(t)[1]

    def amplitude(self) -> np.ndarray:
        """Per-coordinate sum of the moves' distances (m or rad); the scale of the max-error percentages."""
        amp = np.zeros(len(self.bias))
        for i, d, _, _ in self.moves:
            amp[i] += abs(d)
        return amp

    def frequencies(self) -> tuple:
        """None: a move is not periodic."""
        return ()

    def check(self, fail, axis, finite) -> None:
        """Each move (axis, distance, start, duration) the C loop reads valid, else ``fail(field, what,
        value)``; ``axis(field, value)`` and ``finite(field, value)`` check one value."""
        TABLE.check(self.moves, fail, axis, finite)
        for j, (_, _, _, dur) in enumerate(self.moves):
            if not dur > 0:
                fail(f"reference.moves[{j}] duration", "must be > 0 s", dur)

    def config(self) -> dict:
        """Its values of FIELDS."""
        return TABLE.config(self.moves)
