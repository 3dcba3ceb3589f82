"""The paper's actuator laws (56)-(59) under their former names: thin wrappers of
:mod:`hydrogen.actuators.three_way_cylinder`, where the laws are written (see its docstring); g0 is its ``Symbolic.g0``.

Spool position u in m, flow q_l in m³/s, pressures in Pa; ps = P_s, d the underlap, A the piston
(cap-side) area, a the rod-side annulus area, L the chamber length.
"""
from __future__ import annotations

from ..actuators import orifices as _orf
from ..actuators.three_way_cylinder import Symbolic as _tw

__all__ = [
    "valve_flow_unit", "valve_flow_unit_smooth", "chamber_pressure_rate", "leg_force",
    "f0", "valve_inverse_unit", "signed_sqrt_linearised", "orifice_roots",
]

signed_sqrt_linearised = _orf.signed_sqrt_linearised
orifice_roots = _tw.orifice_roots


def valve_flow_unit(u, pc, ps, d, clipped=False):
    """q_l / c of eq. (57) (m·√Pa); ``clipped``: drops clipped at 0."""
    return _tw.valve_flow(u, (pc,), {"supply_pressure": ps, "underlap": d}, clipped=clipped)


def valve_flow_unit_smooth(u, pc, ps, d, p_lin):
    """The plant's (57), orifice roots linear below ``p_lin`` Pa."""
    return _tw.valve_flow_smooth(u, (pc,), {"supply_pressure": ps, "underlap": d, "orifice_linear_below": p_lin})


def chamber_pressure_rate(l, ldot, q_l, A, L, beta):
    """ṗ_c = β (q_l − A l̇) / (A (l − L)), Pa/s."""
    return _tw.chamber_pressure_rate(l, ldot, q_l, {"piston_area": A, "chamber_length": L}, beta)


def leg_force(pc, ps, A, a):
    """f = p_c A − p_s a, N."""
    return _tw.force((pc,), {"piston_area": A, "supply_pressure": ps, "rod_area": a})


def f0(l, ldot, A, L):
    """f0 = −A l̇ / (l − L) of (59)."""
    return _tw.f0(l, ldot, None, {"piston_area": A, "chamber_length": L})


def valve_inverse_unit(w, pc, ps, d, eps):
    """Spool position u with q_l/c = w, inverting (57) over its three branches."""
    return _tw.flow_inverse(w, (pc,), {"supply_pressure": ps, "underlap": d}, eps)
