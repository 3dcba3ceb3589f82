"""The plant's valves: each actuator's spool position and spool rate, and the valve law (rig-wide
parameters [τ_v, ω_v, ζ_v], the plant's input ``valve``), u the spool command (m):

- ω_v > 0: second-order servo-valve, spool̈ = ω_v² (u − spool) − 2 ζ_v ω_v spool̇ (ω_v rad/s, the
  natural frequency, where the spool lags the command by 90°);
- else τ_v > 0: first-order lag spool̇ = (u − spool)/τ_v (the spool rate state stays 0);
- else the ideal valve, spool = u (both spool states stay 0).

The chambers see the effective spool: the spool state with either valve model, else the command.
"""
from __future__ import annotations

import numpy as np

from . import PlantParameter, PlantState

__all__ = ["STATES", "PARAMETERS", "Symbolic", "Numeric"]

STATES = (
    PlantState("spool", "m", "m", "spool positions (0 with the ideal valve), m"),
    PlantState("spool_rate", "m", "m/s", "spool rates (0 unless the valve is second-order), m/s"),
)

#: The plant's input ``valve``, in order.
PARAMETERS = (
    PlantParameter("lag", "s", "valve first-order lag (used when the natural frequency is 0; 0: none)"),
    PlantParameter("omega", "rad/s", "second-order servo-valve natural frequency (0: none)"),
    PlantParameter("zeta", "", "second-order servo-valve damping (dimensionless)"),
)


class Symbolic:
    """The valve law over SymPy."""

    @staticmethod
    def states(model) -> dict:
        from ..symbolic.kinematics import rate_symbols
        m = model.n_cylinders
        return {"spool": rate_symbols("spool", m), "spool_rate": rate_symbols("spool_rate", m)}

    @staticmethod
    def parameters() -> tuple:
        """The symbols of :data:`PARAMETERS` (τ_v s, ω_v rad/s, ζ_v)."""
        from ..actuators.declarations import sp
        return sp.symbols("tau_valve omega_valve zeta_valve", real=True)

    @staticmethod
    def effective(spool, u, valve):
        """The spool position each chamber sees (m): the spool state with either valve model, else the
        command. One selection per actuator: each branch of a Piecewise costs CasADi two masked terms
        and a sum, so branches with the same value share one condition."""
        from ..actuators.declarations import sp
        tau_v, w_v, _ = valve
        second, lagged = sp.Gt(w_v, 0, evaluate=False), sp.Gt(tau_v, 0, evaluate=False)
        return sp.Matrix([sp.Piecewise((spool[i], sp.Or(second, lagged, evaluate=False)), (u[i], True),
                                       evaluate=False) for i in range(len(u))])

    @staticmethod
    def rates(spool, spool_rate, u, valve) -> dict:
        """``{"spool": spool̇, "spool_rate": spool̈}``: the spool rate is a sum of masked terms (exactly
        one non-zero)."""
        from ..actuators.declarations import sp
        tau_v, w_v, z_v = valve
        second, lagged = sp.Gt(w_v, 0, evaluate=False), sp.Gt(tau_v, 0, evaluate=False)
        lag_only = sp.And(sp.Not(second, evaluate=False), lagged, evaluate=False)
        m = len(u)
        spool_dot = sp.Matrix([sp.Piecewise((spool_rate[i], second), (0, True), evaluate=False)
                               + sp.Piecewise(((u[i] - spool[i]) / tau_v, lag_only), (0, True), evaluate=False)
                               for i in range(m)])
        spool_ddot = sp.Matrix([sp.Piecewise((w_v ** 2 * (u[i] - spool[i]) - 2 * z_v * w_v * spool_rate[i], second),
                                             (0, True), evaluate=False) for i in range(m)])
        return {"spool": spool_dot, "spool_rate": spool_ddot}


class Numeric:
    """The valve law over numpy (the same numbers as :class:`Symbolic`); ``valve`` = [τ_v, ω_v, ζ_v]."""

    @staticmethod
    def effective(spool, u, valve):
        tau_v, w_v, _ = (float(v) for v in valve)
        return np.asarray(spool, float) if (w_v > 0 or tau_v > 0) else np.asarray(u, float)

    @staticmethod
    def rates(spool, spool_rate, u, valve) -> dict:
        tau_v, w_v, z_v = (float(v) for v in valve)
        spool, spool_rate, u = (np.asarray(a, float) for a in (spool, spool_rate, u))
        if w_v > 0:
            return {"spool": spool_rate.copy(), "spool_rate": w_v ** 2 * (u - spool) - 2 * z_v * w_v * spool_rate}
        zero = np.zeros_like(spool)
        return {"spool": (u - spool) / tau_v if tau_v > 0 else zero, "spool_rate": zero.copy()}
