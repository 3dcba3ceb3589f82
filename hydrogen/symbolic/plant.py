"""The simulated plant: rigid bodies driven by the cylinders, chamber pressures (56)-(57).

The plant's blocks (:mod:`hydrogen.plant`) composed into one right-hand side: x is their states in
the layout's order (:func:`hydrogen.plant.plant_layout`: [q (n), q̇ (n), pressures (one block per
actuator, its kind's states: p_c of a three-way cylinder, p_A, p_B of a four-way one), spool (m),
spool rate (m), and the supply pressure p_s (Pa) where the supply is not constant]); input u = spool
command (m, metres). With a supply state every actuator's laws take p_s for their supply_pressure,
and p_s moves by :mod:`hydrogen.plant.supply`'s law under the demand of every valve's supply edges.
The valve law (:mod:`hydrogen.plant.valve`, input ``valve`` = [τ_v, ω_v, ζ_v, overlap, full opening] per
actuator) gives the spool the chambers see; the friction law (:mod:`hydrogen.plant.friction`, input
``friction`` = [F_c, b, v_s] per actuator in its own unit, and [F_brk, v_st, k_p] after them for a robot
with seal friction) opposes each actuator's motion; an actuator's Stribeck dip and pressure load only
where its description declares them.
"""
from __future__ import annotations

import sympy as sp

from ..actuators import actuator, baked_parameters
from ..plant import BLOCKS, block, chambers, friction, mechanics, supply, valve
from ..pressures import blocks
from .constants import baked
from .kinematics import leg_intermediates, rate_symbols
from .rigid_body import theta_symbols

__all__ = ["plant_rhs"]


def plant_rhs(model):
    """Symbols and right-hand side of the plant: returns (inputs, xdot, intermediates)."""
    m = model.n_cylinders
    states = {}
    for name in BLOCKS:
        states.update(block(name).Symbolic.states(model))
    q, qd, pc, spool, spool_rate = (states[k] for k in ("q", "qdot", "pc", "spool", "spool_rate"))
    u = rate_symbols("u", m)
    th = theta_symbols(model)
    g1, g2 = rate_symbols("gamma1", m), rate_symbols("gamma2", m)
    names = [par.name for par in friction.parameters_of(model.seal_friction)]
    fric = friction.Symbolic.parameters(m, model.seal_friction)
    valve_par = valve.Symbolic.parameters(m)
    x = sp.Matrix([s for name in BLOCKS for st in block(name).STATES for s in states[st.name]])
    cyl = model.cylinders
    laws = [actuator(c.kind).Symbolic for c in cyl]
    P = [baked_parameters(c) for c in cyl]
    ps = states[supply.PRESSURE]
    if ps.rows:  # a pump: every actuator's laws see the supply state in place of its constant
        P = [{**Pi, "supply_pressure": ps[0]} for Pi in P]
    p = [tuple(pc[a:b]) for a, b in blocks(model)]  # each actuator's pressure block

    l, JL, _, kin = leg_intermediates(model, q, qd, rates=False)  # the plant needs no J̇L
    ldot = rate_symbols("plant_ldot", m)
    ldot_value = JL * qd
    # The effective spool position is an intermediate symbol: nesting its Piecewise
    # inside the valve law's would make SymPy merge conditions (slow, and ITE nodes).
    spool_eff = rate_symbols("spool_eff", m)
    spool_eff_value = valve.Symbolic.effective(spool, u, valve_par, [c.valve_limits for c in model.cylinders])
    rates = valve.Symbolic.rates(spool, spool_rate, u, valve_par)
    f_leg = rate_symbols("plant_fleg", m)
    f_leg_value = sp.Matrix([laws[i].force(p[i], P[i]) - _friction(ldot[i], fric, i, names, cyl[i].seal_terms, laws[i], p[i], P[i])
                             for i in range(m)])
    mech, solve = mechanics.Symbolic.rates(model, q, qd, JL.T * f_leg, th)  # poses: in kin
    rates.update(mech)
    rates.update(chambers.Symbolic.rates(laws, l, ldot, p, spool_eff, g1, g2, P))
    demand = []
    if ps.rows:
        # the valves' draw on the supply: an intermediate, so the supply's law takes one symbol
        demand = [(rate_symbols("plant_demand", 1),
                   sp.Matrix([sum(laws[i].supply_flow(l[i], ldot[i], p[i], spool_eff[i], g2[i] / g1[i], P[i])
                                  for i in range(m))]))]
        values = model.supply.values
        S = {k: baked(v, f"supply.{k}") for k, v in values.items()}
        rates[supply.PRESSURE] = sp.Matrix([supply.Symbolic.rate(model.supply.kind, ps[0], demand[0][0][0], S,
                                                      model.supply.accumulator)])
    else:
        rates[supply.PRESSURE] = ps
    xdot = sp.Matrix([r for name in BLOCKS for st in block(name).STATES for r in rates[st.name]])
    inputs = [("x", x), ("u", u), ("theta", th), ("gamma1", g1), ("gamma2", g2), ("friction", fric),
              ("valve", valve_par)]
    return inputs, xdot, [*kin, (ldot, ldot_value), (f_leg, f_leg_value), (spool_eff, spool_eff_value), *demand,
                          *solve]


def _friction(ldot, fric, i: int, names: list, terms: tuple, law, p, P):
    """Actuator ``i``'s friction at rate ``ldot`` with the structural terms it declares, ``terms`` =
    (Stribeck dip, pressure load) (:attr:`hydrogen.model.Cylinder.seal_terms`); ``fric`` the input
    ``friction``, ``names`` per actuator, actuator after actuator."""
    k = len(names)
    par = dict(zip(names, fric[k * i:k * i + k]))
    stribeck, pressure = terms
    return friction.Symbolic.force(
        ldot, par["coulomb"], par["viscous"], par["smooth_speed"],
        (par["breakaway"], par["stribeck_speed"]) if stribeck else None,
        (par["pressure_coefficient"], friction.Symbolic.seal_load(law.chamber_forces(p, P))) if pressure else None)
