"""The plant's chambers: each actuator's pressure states, its kind's ``STATES`` in order
(:mod:`hydrogen.pressures`), and their rates, the kind's ``pressure_rates`` with the simulator's
smooth orifice law.
"""
from __future__ import annotations

from . import PlantState

__all__ = ["STATES", "PARAMETERS", "Symbolic"]


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


STATES = (
    PlantState("pc", "n_pressures", _units, "chamber pressures: each actuator's kind's states, Pa",
               lower=_bound(0), upper=_bound(1)),
)

#: β and c (the plant's inputs ``gamma1``, ``gamma2``) and each kind's constants are the model's.
PARAMETERS = ()


class Symbolic:
    """The chambers over SymPy."""

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
