"""The plant's chambers: each actuator's pressure states, its kind's ``STATES`` in order
(:mod:`hydrogen.pressures`), and their rates, the kind's ``pressure_rates`` with the simulator's
smooth orifice law.
"""
from __future__ import annotations

from . import PlantState

__all__ = ["POSITION", "STATES", "PARAMETERS", "Symbolic"]


def _units(model) -> list:
    from ..actuators import actuator
    return [s.unit for c in model.cylinders for s in actuator(c.kind).STATES]


def _bound(which: int):
    def rule(model):
        from ..pressures import bounds
        from .supply import ceiling
        out, top = bounds(model)[which], ceiling(model)
        # a supply state may rise above the actuators' supply_pressure, up to its relief: so may a chamber
        return out if which == 0 or top is None else [max(float(v), top) for v in out]
    return rule


#: Its place among the plant's blocks (:data:`hydrogen.plant.BLOCKS`): the pressures after the pose.
POSITION = 20

STATES = (
    PlantState("pc", "n_pressures", _units, "chamber pressures: each actuator's kind's states, Pa",
               lower=_bound(0), upper=_bound(1)),
)

#: β and c (the plant's inputs ``gamma1``, ``gamma2``) and each kind's constants are the model's.
PARAMETERS = ()


class Symbolic:
    """The chambers over SymPy. In the plant (:mod:`hydrogen.symbolic.plant`) it gives each actuator's
    kind's law (``laws``), constants (``P``, its supply pressure the supply's where that is a state)
    and pressure block (``pressures``), adds each actuator's force along its travel to ``leg_force``,
    and moves the pressures by the flows through the effective spool ``spool_eff``."""

    READS = ("pc", "supply_pressure")
    WRITES = ("laws", "P", "pressures")
    ADDS = ("leg_force",)

    @staticmethod
    def outputs(c) -> None:
        from ..actuators import actuator, baked_parameters
        from ..pressures import blocks
        cyl = c.model.cylinders
        laws = [actuator(a.kind).Symbolic for a in cyl]
        P = [baked_parameters(a) for a in cyl]
        ps = c["supply_pressure"]
        if ps is not None:  # a pump: every actuator's laws see the supply state in place of its constant
            P = [{**Pi, "supply_pressure": ps} for Pi in P]
        p = [tuple(c["pc"][a:b]) for a, b in blocks(c.model)]  # each actuator's pressure block
        c.provide("laws", laws)
        c.provide("P", P)
        c.provide("pressures", p)
        c.add("leg_force", [law.force(pi, Pi) for law, pi, Pi in zip(laws, p, P)])

    @staticmethod
    def derivatives(c) -> None:
        c.rate("pc", Symbolic.rates(c["laws"], c["l"], c["ldot"], c["pressures"], c["spool_eff"], c["gamma1"],
                                    c["gamma2"], c["P"])["pc"])

    @staticmethod
    def states(model) -> dict:
        from ..pressures import n_pressures
        from ..symbolic.kinematics import rate_symbols
        return {"pc": rate_symbols("pc", n_pressures(model))}

    @staticmethod
    def rates(laws, l, ldot, p, spool, gamma1, gamma2, P) -> dict:
        """``{"pc": ṗ}`` (Pa/s): per actuator i its kind's law ``laws[i]`` at length (angle) ``l[i]``,
        rate ``ldot[i]``, pressures ``p[i]`` (its block), effective spool ``spool[i]`` (m), β = γ1 and
        c = γ2/γ1, constants ``P[i]``; the orifice law linearised near Δp = 0 (smooth)."""
        from ..actuators.declarations import sp
        m = len(laws)
        return {"pc": sp.Matrix([rate for i in range(m) for rate in
                                 laws[i].pressure_rates(l[i], ldot[i], p[i], spool[i], gamma1[i],
                                                        gamma2[i] / gamma1[i], P[i], smooth=True)])}
