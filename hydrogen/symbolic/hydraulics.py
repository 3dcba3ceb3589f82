"""Actuator dynamics of a three-way valve controlled cylinder (SymPy), Appendix A.

Per leg: control-chamber (cap side, area A) pressure p_c, rod side (area a) at
supply pressure p_s, leg force f = p_c A − p_s a (N, positive extends the leg).

Chamber volume convention (the paper's choice of q and l in (58)): the control
chamber volume is V(l) = A (l − L), with l the leg length and L the
``chamber_length`` of the model, smaller than the shortest leg so V stays
positive. Then (56) with c_l ≈ 0 gives

    ṗ_c = β / (A (l − L)) · (q_l − A l̇),   ḟ = A ṗ_c = γ1 f0 + γ2 g0,

with γ = [β, βc], f0 = −A l̇ / (l − L), g0 = q_l / (c (l − L)).
Spool position u in m, flow q_l in m³/s, pressures in Pa.
"""
from __future__ import annotations

import sympy as sp

__all__ = [
    "valve_flow_unit", "valve_flow_unit_smooth", "chamber_pressure_rate", "leg_force",
    "f0", "g0", "valve_inverse_unit", "signed_sqrt_linearised", "orifice_roots",
]


def orifice_roots(pc, ps):
    """√(p_s − p_c), √p_c with the pressure drops clipped at 0 (√Pa): the roots of (57) for a
    measured p_c, which noise can push outside [0, p_s]; inside, exactly the unclipped roots."""
    return sp.sqrt(sp.Max(ps - pc, 0)), sp.sqrt(sp.Max(pc, 0))


def valve_flow_unit(u, pc, ps, d, clipped=False) -> sp.Expr:
    """q_l / c of eq. (57): load flow per unit flow gain c (m·√Pa), three branches.

    ``clipped``: the roots of :func:`orifice_roots` (shared with :func:`valve_inverse_unit`), so a
    measured p_c outside [0, p_s] gives no root of a negative number; the model's own law
    (unclipped) otherwise, for p_c inside."""
    up, down = orifice_roots(pc, ps) if clipped else (sp.sqrt(ps - pc), sp.sqrt(pc))
    return _orifice_terms(u, d, up, down)


def _orifice_terms(u, d, up, down) -> sp.Expr:
    """(57)'s three branches as the sum of the two orifices' terms, each where its orifice is open
    (u ≥ −d: supply side, root ``up``; u ≤ d: return side, root ``down``): the same values as the
    three-branch form (a term plus an exact zero outside the underlap), for two masked terms
    instead of four and a sum."""
    return sp.Piecewise(((u + d) * up, sp.Not(sp.Lt(u, -d, evaluate=False), evaluate=False)),
                        (0, True), evaluate=False) \
        + sp.Piecewise(((u - d) * down, sp.Le(u, d, evaluate=False)), (0, True), evaluate=False)


def signed_sqrt_linearised(x, x_lin) -> sp.Expr:
    """sign(x)√|x|, replaced by x/√x_lin for |x| < x_lin (finite slope at 0, as hydraulic simulators do).

    Continuous at |x| = x_lin; used by the simulated plant only, never by a controller.
    """
    return sp.Piecewise(
        (x / sp.sqrt(x_lin), sp.Lt(sp.Abs(x), x_lin, evaluate=False)),
        (sp.sign(x) * sp.sqrt(sp.Abs(x)), True),
        evaluate=False,
    )


def valve_flow_unit_smooth(u, pc, ps, d, p_lin) -> sp.Expr:
    """Plant version of (57): the orifice roots turn linear below ``p_lin`` Pa of pressure drop.

    The pressure drops are signed, so a chamber pushed past p_s (or below 0) by an
    integration step flows back instead of taking the root of a negative number.
    """
    return _orifice_terms(u, d, signed_sqrt_linearised(ps - pc, p_lin), signed_sqrt_linearised(pc, p_lin))


def chamber_pressure_rate(l, ldot, q_l, A, L, beta) -> sp.Expr:
    """ṗ_c = β (q_l − A l̇) / (A (l − L)), Pa/s (eq. (56) with V = A (l − L), c_l = 0)."""
    return beta * (q_l - A * ldot) / (A * (l - L))


def leg_force(pc, ps, A, a) -> sp.Expr:
    """f = p_c A − p_s a, N; positive extends the leg."""
    return pc * A - ps * a


def f0(l, ldot, A, L) -> sp.Expr:
    """f0 = −A l̇ / (l − L) of (59), m²/s per m … so that γ1 f0 is in N/s."""
    return -A * ldot / (l - L)


def g0(l, q_l_unit, L) -> sp.Expr:
    """g0 = q_l / (c (l − L)) of (59), given q_l / c; γ2 g0 is in N/s."""
    return q_l_unit / (l - L)


def valve_inverse_unit(w, pc, ps, d, eps) -> sp.Expr:
    """Spool position u with q_l/c = w, inverting (57) over its three branches.

    (57) is continuous and increasing in u, so the branch is found from the
    flows at u = ±d. Pressure drops are clipped at ``eps`` Pa so no root of a
    negative number is taken and the outer branches never divide by zero.
    """
    # √max(Δp, eps) written as max(√max(Δp, 0), √eps): the same numbers (√ is monotone and
    # correctly rounded), with the roots a controller's g0 shares (orifice_roots)
    root_eps = sp.sqrt(sp.Float(eps))
    sp_up, sp_dn = (sp.Max(r, root_eps) for r in orifice_roots(pc, ps))
    w_hi = 2 * d * sp_up      # flow at u = +d
    w_lo = -2 * d * sp_dn     # flow at u = −d
    # evaluate=False: w may be a large controller expression; SymPy must not try to order it.
    return sp.Piecewise(
        (w / sp_up - d, sp.Gt(w, w_hi, evaluate=False)),
        (w / sp_dn + d, sp.Lt(w, w_lo, evaluate=False)),
        ((w - d * sp_up + d * sp_dn) / (sp_up + sp_dn), True),
        evaluate=False,
    )
