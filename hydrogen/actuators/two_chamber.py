"""The laws of a two-chamber actuator on a four-way valve, for any geometry (four-way cylinder, rotary).

Chambers A and B at pressures p_A, p_B; the actuator coordinate x (m or rad) grows as chamber A
fills: its volumes V_A(x), V_B(x) with dV_A/dx = a_A, dV_B/dx = −a_B, a_A and a_B the effective
areas (m², or m³/rad for a rotary actuator). Force (or torque) f = p_A a_A − p_B a_B.

Four-way valve, critically centred (d = 0) or underlapped by d (m): four metering orifices of
opening (u + d) (P→A, B→T, open for u ≥ −d) and (d − u) (A→T, P→B, open for u ≤ d), supply P_s and
tank P_t. Per unit flow gain c, the flow into A and the flow out of B are

    q_A/c = (u + d) √(P_s − p_A) [u ≥ −d] + (u − d) √(p_A − P_t) [u ≤ d],
    q_B/c = (u + d) √(p_B − P_t) [u ≥ −d] + (u − d) √(P_s − p_B) [u ≤ d],

and (56) for each chamber, with laminar leakage across the piston (C_i, A to B) and from each
chamber to tank (C_e), both in m³/(s Pa):

    ṗ_A = β (q_A − a_A ẋ − Q_A) / V_A,   ṗ_B = β (−q_B + a_B ẋ − Q_B) / V_B,
    Q_A = C_i (p_A − p_B) + C_e (p_A − P_t),   Q_B = −C_i (p_A − p_B) + C_e (p_B − P_t),

Q_A, Q_B the leakage out of each chamber. By the chain rule ḟ = a_A ṗ_A − a_B ṗ_B = β f0 + βc g0 with

    f0 = −ẋ (a_A²/V_A + a_B²/V_B) − (a_A/V_A) Q_A + (a_B/V_B) Q_B,
    g0 = (a_A/V_A) q_A/c + (a_B/V_B) q_B/c,

g0 piecewise linear and increasing in u, (u + d) S_hi [u ≥ −d] + (u − d) S_lo [u ≤ d] with
S_hi = (a_A/V_A) √(P_s − p_A) + (a_B/V_B) √(p_B − P_t), S_lo = (a_A/V_A) √(p_A − P_t) +
(a_B/V_B) √(P_s − p_B): the three-way law's form, so the same three-branch inverse applies.
The leakage is part of β f0: a known function of the measured pressures and x, times β, so the
controllers know it as they know the areas, and (59)'s form ḟ = γ1 f0 + γ2 g0, linear in γ, holds.
Without leakage f0 is the time derivative of Φ(x) = −a_A ln V_A + a_B ln V_B (with it, of Φ plus the
leakage's integral, which Φ leaves out). A leakage coefficient of 0 is structure (an exact 0 in the
derivation), so without leakage every law is the expression it was.

Equilibrium pressures for a force f: at rest (ẋ = 0) with the valve held still, both flows vanish at
the same spool; for |u| < d that gives ((u + d)/(d − u))² = (p_A − P_t)/(P_s − p_A) = (P_s − p_B)/(p_B − P_t),
so p_A + p_B = P_s + P_t (matched orifices) and p_A = (f + a_B (P_s + P_t)) / (a_A + a_B). A
critically centred valve holds any pair; the same pair is taken (the limit d → 0).

:class:`Laws` writes each law once over a layer (:data:`~hydrogen.actuators.orifices.SYMPY` or
:data:`~hydrogen.actuators.orifices.NUMPY`); a kind binds it to its geometry.
"""
from __future__ import annotations

from .declarations import (BULK_MODULUS, FLOW_GAIN, LEAKAGE, ORIFICE_LINEAR_BELOW, SUPPLY_PRESSURE, TANK_PRESSURE, UNDERLAP,
                           Parameter)

__all__ = ["Laws", "VALVE_PARAMETERS", "displacement_areas"]


class Laws:
    """The uniform actuator interface of a two-chamber kind in one layer.

    ``backend``: :data:`~hydrogen.actuators.orifices.SYMPY` or ``NUMPY``; ``areas(P)`` → (a_A, a_B);
    ``volumes(x, P)`` → (V_A, V_B) (m³). ``P`` holds ``supply_pressure``, ``tank_pressure``,
    ``underlap``, ``orifice_linear_below`` and the geometry's parameters. ``p`` is (p_A, p_B)."""

    def __init__(self, backend, areas, volumes):
        self.xp, self.areas, self.volumes = backend, areas, volumes

    # valve
    def valve_flows(self, u, p, P, smooth=False):
        """(q_A/c, q_B/c) (m·√Pa): drops clipped at 0 (a measured pressure outside [P_t, P_s]), or
        the plant's signed roots linear below ``orifice_linear_below`` (``smooth``)."""
        xp, (pa, pb) = self.xp, p
        ps, pt, d = P["supply_pressure"], P["tank_pressure"], P["underlap"]
        if smooth:
            lin = P["orifice_linear_below"]
            r = lambda drop: xp.smooth_root(drop, lin)  # noqa: E731
        else:
            r = xp.root
        return xp.terms(u, d, r(ps - pa), r(pa - pt)), xp.terms(u, d, r(pb - pt), r(ps - pb))

    def supply_flow(self, x, xdot, p, u, c, P, smooth=True):
        """The flow the valve draws from the supply (m³/s): its supply edges' terms of
        :meth:`valve_flows` (P→A open for u ≥ −d, P→B for u ≤ d), c times
        (u + d) r(P_s − p_A) [u ≥ −d] − (u − d) r(P_s − p_B) [u ≤ d]; ``x``, ``xdot``: unused (a
        two-chamber actuator returns its oil to tank)."""
        xp, (pa, pb) = self.xp, p
        ps, d = P["supply_pressure"], P["underlap"]
        r = (lambda drop: xp.smooth_root(drop, P["orifice_linear_below"])) if smooth else xp.root
        return c * (xp.terms(u, d, r(ps - pa), 0 * pa) - xp.terms(u, d, 0 * pb, r(ps - pb)))

    def force(self, p, P):
        """f = p_A a_A − p_B a_B (N, or N·m)."""
        aa, ab = self.areas(P)
        return p[0] * aa - p[1] * ab

    def leakage_flows(self, p, P):
        """(Q_A, Q_B), m³/s: the laminar leakage out of each chamber, across the piston
        (``leakage_internal`` C_i, from A to B) and to tank (``leakage_external`` C_e, each chamber):
        Q_A = C_i (p_A − p_B) + C_e (p_A − P_t), Q_B = −C_i (p_A − p_B) + C_e (p_B − P_t)."""
        (pa, pb), pt = p, P["tank_pressure"]
        ci, ce = P["leakage_internal"], P["leakage_external"]
        across = ci * (pa - pb)
        return across + ce * (pa - pt), -across + ce * (pb - pt)

    def chamber_forces(self, p, P):
        """(p_A a_A, −p_B a_B), N or N·m: each chamber's push (the seals' load), summing to the force."""
        aa, ab = self.areas(P)
        return p[0] * aa, -p[1] * ab

    def pressure_rates(self, x, xdot, p, u, beta, c, P, smooth=True):
        """(ṗ_A, ṗ_B), Pa/s, with the plant's smooth orifice law (``smooth``) or the clipped one, and
        the leakage (:meth:`leakage_flows`)."""
        (aa, ab), (va, vb) = self.areas(P), self.volumes(x, P)
        qa, qb = self.valve_flows(u, p, P, smooth)
        la, lb = self.leakage_flows(p, P)
        return beta * (c * qa - aa * xdot - la) / va, beta * (-c * qb + ab * xdot - lb) / vb

    def f0(self, x, xdot, p, P):
        """f0 = −ẋ (a_A²/V_A + a_B²/V_B) − (a_A/V_A) Q_A + (a_B/V_B) Q_B: β f0 is the force rate
        (N/s, or N·m/s) at a closed valve, the leakage's included."""
        (aa, ab), (va, vb) = self.areas(P), self.volumes(x, P)
        la, lb = self.leakage_flows(p, P)
        return -xdot * self.spring_rate(x, P) - aa / va * la + ab / vb * lb

    def g0(self, x, p, u, P):
        """g0 = (a_A/V_A) q_A/c + (a_B/V_B) q_B/c, drops clipped at 0."""
        (aa, ab), (va, vb) = self.areas(P), self.volumes(x, P)
        qa, qb = self.valve_flows(u, p, P)
        return aa / va * qa + ab / vb * qb

    def valve_inverse(self, y, x, p, P, eps):
        """The spool u with g0(x, p, u) = y, on every branch; each drop's root floored at √eps
        (``eps`` Pa) so the slopes stay positive."""
        xp, (pa, pb) = self.xp, p
        ps, pt = P["supply_pressure"], P["tank_pressure"]
        (aa, ab), (va, vb) = self.areas(P), self.volumes(x, P)
        ka, kb = aa / va, ab / vb
        s_hi = ka * xp.floor_root(ps - pa, eps) + kb * xp.floor_root(pb - pt, eps)
        s_lo = ka * xp.floor_root(pa - pt, eps) + kb * xp.floor_root(ps - pb, eps)
        return xp.inverse(y, P["underlap"], s_hi, s_lo)

    def spring_rate(self, x, P):
        """−∂f0/∂ẋ = a_A²/V_A + a_B²/V_B: β times it is the oil columns' stiffness."""
        (aa, ab), (va, vb) = self.areas(P), self.volumes(x, P)
        return aa * aa / va + ab * ab / vb

    def f0_potential(self, x, P):
        """Φ(x) = −a_A ln V_A + a_B ln V_B, whose time derivative is f0."""
        (aa, ab), (va, vb) = self.areas(P), self.volumes(x, P)
        return -aa * self.xp.log(va) + ab * self.xp.log(vb)

    def equilibrium_pressures(self, force, P):
        """(p_A, p_B) with force ``force`` and p_A + p_B = P_s + P_t (see the module docstring)."""
        aa, ab = self.areas(P)
        total = P["supply_pressure"] + P["tank_pressure"]
        pa = (force + ab * total) / (aa + ab)
        return pa, total - pa

    def force_range(self, P):
        """(lowest, highest) force with both pressures within [P_t, P_s]."""
        (aa, ab), ps, pt = self.areas(P), P["supply_pressure"], P["tank_pressure"]
        return pt * aa - ps * ab, ps * aa - pt * ab


#: The four-way valve's and the oil's parameters, the same for every two-chamber kind.
VALVE_PARAMETERS = (
    Parameter("supply_pressure", "Pa", None, "P_s", range=SUPPLY_PRESSURE),
    Parameter("tank_pressure", "Pa", 0.0, "P_t (gauge)", range=TANK_PRESSURE),
    UNDERLAP,
    Parameter("flow_gain", "m^2/(s sqrt(Pa))", None, "c: q = c opening sqrt(dp), each orifice", gamma=True,
              range=FLOW_GAIN),
    Parameter("bulk_modulus", "Pa", None, "beta, effective oil bulk modulus", gamma=True, range=BULK_MODULUS),
    ORIFICE_LINEAR_BELOW,
    Parameter("leakage_internal", "m^3/(s Pa)", 0.0, "C_i, laminar leakage across the piston, A to B: "
              "Q = C_i (p_A - p_B)", range=LEAKAGE, zero_is_structure=True),
    Parameter("leakage_external", "m^3/(s Pa)", 0.0, "C_e, laminar leakage from each chamber to tank: "
              "Q = C_e (p - P_t)", range=LEAKAGE, zero_is_structure=True),
)


def displacement_areas(P):
    """(D_m, D_m), m³/rad: the effective areas of a rotary kind of displacement D_m (``displacement``),
    whose torque is τ = D_m p_A − D_m p_B."""
    return P["displacement"], P["displacement"]
