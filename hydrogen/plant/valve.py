"""The plant's valves: each actuator's spool position and spool rate, and the valve law, u the spool
command (m). Its parameters are per actuator (the plant's input ``valve``: [τ_v, ω_v, ζ_v, o, S] per
actuator, :data:`PARAMETERS`): an actuator's datasheet valve (the description's ``valve`` table) or
the rig's valve settings:

- ω_v > 0: second-order servo-valve, spool̈ = ω_v² (u − spool) − 2 ζ_v ω_v spool̇ (ω_v rad/s, the
  natural frequency, where the spool lags the command by 90°);
- else τ_v > 0: first-order lag spool̇ = (u − spool)/τ_v (the spool rate state stays 0);
- else the ideal valve, spool = u (both spool states stay 0).

The chambers see the effective spool: the spool state with either valve model, else the command;
held to the full opening ±S where S > 0 (the spool's saturation; 0: none), less the overlap o ≥ 0
(m of spool travel: no edge opens for |spool| ≤ o, the dead band; 0: none). Those two terms are in
the generated plant only for an actuator whose datasheet valve needs them (structure, baked). A dead band of o on a
critically centred edge pair is the orifice law with underlap −o (both give (|u| − o) sign(u) of
opening), so the kinds' orifice laws stay as they are.
"""
from __future__ import annotations

import numpy as np

from ..setting import setting
from . import PlantParameter, PlantState

__all__ = ["STATES", "PARAMETERS", "SCENARIO_SETTINGS", "Symbolic", "Numeric", "WIDTH"]

STATES = (
    PlantState("spool", "m", "m", "spool positions (0 with the ideal valve), m"),
    PlantState("spool_rate", "m", "m/s", "spool rates (0 unless the valve is second-order), m/s"),
)

#: The plant's input ``valve``, per actuator, in order.
PARAMETERS = (
    PlantParameter("lag", "s", "valve first-order lag (used when the natural frequency is 0; 0: none)",
                   per_actuator=True),
    PlantParameter("omega", "rad/s", "second-order servo-valve natural frequency (0: none)", per_actuator=True),
    PlantParameter("zeta", "", "second-order servo-valve damping (dimensionless)", per_actuator=True),
    PlantParameter("overlap", "m", "spool overlap: the dead band |spool| <= overlap passes no flow (0: none)",
                   per_actuator=True),
    PlantParameter("full_opening", "m", "spool travel at full opening, where the spool saturates (0: none)",
                   per_actuator=True),
)

#: The rig's valve, a scenario's settings (:mod:`hydrogen.scenario_settings`): the spool response of
#: every actuator without a datasheet valve, and of those with one where the scenario's valve is not ideal.
SCENARIO_SETTINGS = {
    "valve_lag": setting(0.0, "s", "first-order valve lag (0: none); exclusive with valve_bandwidth_hz", ">=0"),
    "valve_bandwidth_hz": setting(0.0, "Hz", "second-order servo-valve natural frequency (the spool lags 90° "
                                  "there); 0: none", ">=0"),
    "valve_damping": setting(0.7, "", "second-order valve damping ratio", "number"),
}

#: Numbers per actuator in the input ``valve``.
WIDTH = len(PARAMETERS)


class Symbolic:
    """The valve law over SymPy."""

    @staticmethod
    def states(model) -> dict:
        from ..symbolic.kinematics import rate_symbols
        m = model.n_cylinders
        return {"spool": rate_symbols("spool", m), "spool_rate": rate_symbols("spool_rate", m)}

    @staticmethod
    def parameters(m: int):
        """The symbols of :data:`PARAMETERS` of ``m`` actuators, [τ_v s, ω_v rad/s, ζ_v, o m, S m] per actuator."""
        from ..actuators.declarations import sp
        return sp.Matrix([s for i in range(m) for s in
                          sp.symbols(f"tau_valve_{i} omega_valve_{i} zeta_valve_{i} overlap_valve_{i} "
                                     f"opening_valve_{i}", real=True)])

    @staticmethod
    def effective(spool, u, valve, limits=None):
        """The spool opening each chamber sees (m): the spool state with either valve model, else the
        command; saturated at ±S, less the dead band o, for the actuators whose ``limits[i]`` =
        (saturation, dead band) asks for them (:attr:`hydrogen.model.Cylinder.valve_limits`, structure:
        a robot without a datasheet valve keeps the plain selection; its S = o = 0 would take away
        exactly 0, at some 11 % more plant instructions). One selection per actuator: each branch of a
        Piecewise costs CasADi two masked terms and a sum, so branches with the same value share one
        condition."""
        from ..actuators.declarations import sp
        out = []
        for i in range(len(u)):
            tau_v, w_v, _, o, s = valve[WIDTH * i:WIDTH * i + WIDTH]
            saturates, dead_band = limits[i] if limits is not None else (False, False)
            second, lagged = sp.Gt(w_v, 0, evaluate=False), sp.Gt(tau_v, 0, evaluate=False)
            pos = sp.Piecewise((spool[i], sp.Or(second, lagged, evaluate=False)), (u[i], True), evaluate=False)
            if saturates:
                pos = sp.Piecewise((sp.Min(sp.Max(pos, -s), s), sp.Gt(s, 0, evaluate=False)), (pos, True),
                                   evaluate=False)
            out.append(pos - sp.Min(sp.Max(pos, -o), o) if dead_band else pos)
        return sp.Matrix(out)

    @staticmethod
    def rates(spool, spool_rate, u, valve) -> dict:
        """``{"spool": spool̇, "spool_rate": spool̈}``: the spool rate is a sum of masked terms (exactly
        one non-zero)."""
        from ..actuators.declarations import sp
        spool_dot, spool_ddot = [], []
        for i in range(len(u)):
            tau_v, w_v, z_v = valve[WIDTH * i:WIDTH * i + 3]
            second, lagged = sp.Gt(w_v, 0, evaluate=False), sp.Gt(tau_v, 0, evaluate=False)
            lag_only = sp.And(sp.Not(second, evaluate=False), lagged, evaluate=False)
            spool_dot.append(sp.Piecewise((spool_rate[i], second), (0, True), evaluate=False)
                             + sp.Piecewise(((u[i] - spool[i]) / tau_v, lag_only), (0, True), evaluate=False))
            spool_ddot.append(sp.Piecewise((w_v ** 2 * (u[i] - spool[i]) - 2 * z_v * w_v * spool_rate[i], second),
                                           (0, True), evaluate=False))
        return {"spool": sp.Matrix(spool_dot), "spool_rate": sp.Matrix(spool_ddot)}


class Numeric:
    """The valve law over numpy (the same numbers as :class:`Symbolic`); ``valve``: [τ_v, ω_v, ζ_v, o, S]
    per actuator, flat (m × :data:`WIDTH`), the actuators' arrays of one length m."""

    @staticmethod
    def _split(valve):
        return np.asarray(valve, float).reshape(-1, WIDTH).T

    @staticmethod
    def effective(spool, u, valve):
        tau_v, w_v, _, o, s = Numeric._split(valve)
        pos = np.where((w_v > 0) | (tau_v > 0), np.asarray(spool, float), np.asarray(u, float))
        pos = np.where(s > 0, np.clip(pos, -s, s), pos)
        return pos - np.clip(pos, -o, o)

    @staticmethod
    def rates(spool, spool_rate, u, valve) -> dict:
        tau_v, w_v, z_v, _, _ = Numeric._split(valve)
        spool, spool_rate, u = (np.asarray(a, float) for a in (spool, spool_rate, u))
        second, lag_only = w_v > 0, (w_v <= 0) & (tau_v > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            lagged = np.where(lag_only, (u - spool) / np.where(lag_only, tau_v, 1.0), 0.0)
        return {"spool": np.where(second, spool_rate, 0.0) + lagged,
                "spool_rate": np.where(second, w_v ** 2 * (u - spool) - 2 * z_v * w_v * spool_rate, 0.0)}
