"""The plant's supply: the pressure p_s (Pa) every actuator's valve draws on, and its law.

The description's ``[supply]`` table (:class:`Supply`) gives its ``kind``:

- ``"constant"`` (the default): p_s is each actuator's ``supply_pressure``, a constant; no state, no
  law, nothing generated (today's plant);
- ``"pump"``: a fixed-displacement pump delivering Q_p = ``pump_flow`` (m³/s) at any pressure;
- ``"compensated_pump"``: a pressure-compensated pump holding ``set_pressure`` p_set up to its
  ``pump_flow``, its flow drooping steeply and smoothly near p_set:

      Q_pump = Q_p (1 + tanh((p_set − p_s)/Δ_c)) / 2,   Δ_c = :data:`COMPENSATOR_DROOP` p_set,

  full flow below p_set − 2Δ_c (96 %), none above p_set + 2Δ_c; a demand D < Q_p is held at
  p_s = p_set − Δ_c artanh(2D/Q_p − 1).

Either pump has a relief valve to tank, a smooth steep relief flow above ``relief_pressure`` p_r
that passes the pump's full flow at p_r (1 + :data:`RELIEF_OVERRIDE`) (the override of a real
relief valve):

      Q_relief = g_r w softplus((p_s − p_r)/w),   g_r = Q_p / (RELIEF_OVERRIDE p_r),
      w = :data:`RELIEF_WIDTH` RELIEF_OVERRIDE p_r,

i.e. ≈ g_r (p_s − p_r) above p_r + 3w, below 5 % of that slope under p_r − 3w (softplus(z) =
ln(1 + eᶻ), written max(z, 0) + ln(1 + e^−|z|), finite at any z).

The supply pressure is a plant state (:data:`STATES`, only where the kind is not constant) whose
rate is the net flow into the supply over its capacitance:

      ṗ_s = (Q_pump − Q_relief − D) / C(p_s),
      C(p_s) = V_h/β_s + [p_s > p_0] V_a p̄_0^{1/n} / (n p̄_s^{1 + 1/n}),

D the demand (m³/s): the sum of every actuator's flow from the supply (its kind's
``supply_flow``, its orifice law's supply edges); V_h = ``hose_volume`` (m³) with the oil's
``bulk_modulus`` β_s (Pa); an optional gas accumulator of ``accumulator_volume`` V_a (m³, 0: none),
``precharge_pressure`` p_0 (Pa) and ``polytropic_index`` n: its gas holds p̄ V_gas^n = p̄_0 V_a^n
(p̄ absolute: gauge + :data:`ATMOSPHERE`), so it holds oil V_a (1 − (p̄_0/p̄_s)^{1/n}) only when
p_s > p_0, and C's second term is that volume's slope. Tank pressure stays each actuator's
parameter. Plain data at import: the SymPy laws import SymPy when first used.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..actuators.declarations import BULK_MODULUS, SUPPLY_PRESSURE, VOLUME, Parameter, Range, sp
from . import PlantState

__all__ = ["KINDS", "DEFAULT_KIND", "NEEDS", "PRESSURE", "POSITION", "STATES", "entries", "nominal", "ceiling", "PARAMETERS", "ATMOSPHERE", "RELIEF_OVERRIDE",
           "RELIEF_WIDTH", "COMPENSATOR_DROOP", "Supply", "Laws", "Symbolic", "Numeric"]

#: The supply kinds a description may name; the default: a constant supply pressure.
KINDS = ("constant", "pump", "compensated_pump")
DEFAULT_KIND = "constant"

#: Pa: the atmosphere, added to gauge pressures in the accumulator's gas law (which needs absolute ones).
ATMOSPHERE = 101325.0
#: The relief valve passes the pump's full flow at relief_pressure (1 + RELIEF_OVERRIDE): 1 %, a
#: direct-acting relief's typical override.
RELIEF_OVERRIDE = 0.01
#: The relief's smoothing width, as a fraction of its override pressure.
RELIEF_WIDTH = 0.1
#: The compensated pump's droop Δ_c, as a fraction of set_pressure: its flow falls from 98 % to 2 %
#: over p_set ± 2Δ_c.
COMPENSATOR_DROOP = 0.01

#: The supply pressure's one name: the plant state's, its log column's and the controllers' input
#: port's (:mod:`hydrogen.diagram`), the FMU's output.
PRESSURE = "ps"

#: Its place among the plant's blocks (:data:`hydrogen.plant.BLOCKS`): the supply pressure last (a state only where
#: the supply is not constant).
POSITION = 50

STATES = (
    # it starts at the description's supply pressure (nominal); a plant output (logged, the FMU's)
    PlantState(PRESSURE, "supply", "Pa", "supply pressure (a state only where the supply is not constant), Pa",
               lower=0.0, initial=lambda model: [nominal(model)], output=True),
)

#: m³/s: a pump's flow, 1 mL/s (a micro pump) .. 10 m³/s (above the largest mining machines' pumps)
PUMP_FLOW = Range("positive", 1e-6, 10.0)

#: The ``[supply]`` keys besides ``kind``, each in its unit with its range (None default: required
#: by the kinds of :data:`NEEDS` that take it).
PARAMETERS = (
    Parameter("pump_flow", "m^3/s", None, "Q_p, the pump's flow (a compensated pump's largest)",
              range=PUMP_FLOW),
    Parameter("relief_pressure", "Pa", None, "p_r, where the relief valve opens", range=SUPPLY_PRESSURE),
    Parameter("set_pressure", "Pa", None, "p_set, the pressure a compensated pump holds", range=SUPPLY_PRESSURE),
    Parameter("hose_volume", "m^3", None, "V_h, the oil volume between pump and valves", range=VOLUME),
    Parameter("bulk_modulus", "Pa", None, "beta_s, the supply oil's bulk modulus (default: the actuators' "
              "bulk_modulus, when they share one)", range=BULK_MODULUS),
    Parameter("accumulator_volume", "m^3", 0.0, "V_a, the accumulator's gas volume at precharge (0: none)",
              range=Range("nonnegative", 0.0, 100.0), zero_is_structure=True),
    Parameter("precharge_pressure", "Pa", None, "p_0, the accumulator's gas precharge (gauge)",
              range=SUPPLY_PRESSURE),
    Parameter("polytropic_index", "", 1.4, "n of the gas law p V^n = const (1: isothermal, 1.4: adiabatic)",
              range=Range("positive", 1.0, 1.67)),
)

#: The keys each kind takes (the others are refused).
NEEDS = {
    "constant": (),
    "pump": ("pump_flow", "relief_pressure", "hose_volume", "bulk_modulus", "accumulator_volume",
             "precharge_pressure", "polytropic_index"),
    "compensated_pump": ("pump_flow", "set_pressure", "relief_pressure", "hose_volume", "bulk_modulus",
                         "accumulator_volume", "precharge_pressure", "polytropic_index"),
}


@dataclass(frozen=True)
class Supply:
    """A model's supply: its ``kind`` (:data:`KINDS`) and ``values``, its :data:`PARAMETERS` by name
    (SI; only the kind's :data:`NEEDS`, defaults filled in; ``precharge_pressure`` only with an
    accumulator)."""

    kind: str = DEFAULT_KIND
    values: Mapping = field(default_factory=dict)

    @property
    def constant(self) -> bool:
        """Whether p_s is each actuator's constant ``supply_pressure`` (no state)."""
        return self.kind == "constant"

    @property
    def accumulator(self) -> bool:
        """Whether it has an accumulator (its volume > 0)."""
        return float(self.values.get("accumulator_volume", 0.0)) > 0.0

    def numbers(self) -> dict:
        """``{"supply.<key>": value}`` of its numbers (SI)."""
        return {f"supply.{k}": float(v) for k, v in self.values.items()}


def entries(model) -> list:
    """What the supply state's entries belong to: ``["supply"]`` where the model's supply is not
    constant, else none (the plant has no supply state)."""
    supply = getattr(model, "supply", None)
    return [] if supply is None or supply.constant else ["supply"]


def nominal(model) -> float:
    """The description's supply pressure (Pa): the actuators' shared ``supply_pressure``, where a
    supply state starts and what a controller assuming a constant supply takes (``supply_feedback``
    false)."""
    return float(model.cylinders[0].supply_pressure)


def ceiling(model) -> float | None:
    """The highest supply pressure (Pa) a chamber is held to where the supply is a state: twice the
    relief's override above relief_pressure (the relief passes twice the pump's flow there), or the
    actuators' supply_pressure if higher; None for a constant supply."""
    if not entries(model):
        return None
    return max(model.supply.values["relief_pressure"] * (1 + 2 * RELIEF_OVERRIDE), nominal(model))


class _Ops:
    """The operations the supply law needs, in one layer: ``where(cond, a, b)``, ``gt``, ``tanh``,
    ``softplus``."""

    def __init__(self, name, where, gt, tanh, softplus):
        self.name, self.where, self.gt, self.tanh, self.softplus = name, where, gt, tanh, softplus


def _softplus_sympy(z):
    return sp.Max(z, 0) + sp.log(1 + sp.exp(-sp.Abs(z)))


def _softplus_numpy(z):
    z = np.asarray(z, float)
    return np.maximum(z, 0.0) + np.log1p(np.exp(-np.abs(z)))


_SYMPY = _Ops("sympy", lambda c, a, b: sp.Piecewise((a, c), (b, True), evaluate=False),
              lambda a, b: sp.Gt(a, b, evaluate=False), lambda z: sp.tanh(z), _softplus_sympy)
_NUMPY = _Ops("numpy", np.where, lambda a, b: np.asarray(a) > b, np.tanh, _softplus_numpy)


class Laws:
    """The supply's law in one layer; ``kind`` a :data:`KINDS` entry but "constant", ``S`` its
    values by name (numbers, or SymPy numbers or symbols), ``ps`` the supply pressure (Pa)."""

    #: In the plant (:mod:`hydrogen.symbolic.plant`): the supply pressure every actuator's laws see,
    #: ``supply_pressure`` (the state p_s, or None: each actuator's constant), moved by the demand of
    #: every actuator's valve (its kind's ``supply_flow``).
    READS = (PRESSURE,)
    WRITES = ("supply_pressure",)

    def __init__(self, ops):
        self.xp = ops

    def outputs(self, c) -> None:
        ps = c[PRESSURE]
        c.provide("supply_pressure", ps[0] if ps.rows else None)

    def derivatives(self, c) -> None:
        from ..symbolic.constants import baked
        from ..symbolic.kinematics import rate_symbols
        ps, model = c[PRESSURE], c.model
        if not ps.rows:
            c.rate(PRESSURE, ps)
            return
        laws, l, ldot, p, spool, g1, g2, P = (c[k] for k in ("laws", "l", "ldot", "pressures", "spool_eff", "gamma1",
                                                              "gamma2", "P"))
        # the valves' draw on the supply: an intermediate, so the supply's law takes one symbol
        c.provide("demand", sp.Matrix([sum(laws[i].supply_flow(l[i], ldot[i], p[i], spool[i], g2[i] / g1[i], P[i])
                                           for i in range(model.n_cylinders))]), prefix="plant_demand")
        S = {k: baked(v, f"supply.{k}") for k, v in model.supply.values.items()}
        c.rate(PRESSURE, sp.Matrix([self.rate(model.supply.kind, ps[0], c["demand"][0], S,
                                              model.supply.accumulator)]))

    @staticmethod
    def states(model) -> dict:
        """``{"ps": column of symbols}``: one p_s where the supply is not constant, else none."""
        from ..symbolic.kinematics import rate_symbols
        return {PRESSURE: rate_symbols(PRESSURE, len(entries(model)))}

    def pump_flow(self, kind, ps, S):
        """Q_pump (m³/s): a fixed displacement's Q_p, or the compensated pump's drooping flow."""
        if kind == "pump":
            return S["pump_flow"] + 0 * ps
        droop = COMPENSATOR_DROOP * S["set_pressure"]
        return S["pump_flow"] * (1 + self.xp.tanh((S["set_pressure"] - ps) / droop)) / 2

    def relief_flow(self, ps, S):
        """Q_relief (m³/s) to tank: g_r w softplus((p_s − p_r)/w) (module docstring)."""
        over = RELIEF_OVERRIDE * S["relief_pressure"]
        width = RELIEF_WIDTH * over
        return S["pump_flow"] / over * width * self.xp.softplus((ps - S["relief_pressure"]) / width)

    def capacitance(self, ps, S, accumulator: bool = False):
        """C(p_s) (m³/Pa): the hose's oil V_h/β_s, and with an ``accumulator`` (structure) the slope of
        the oil it holds, dV_oil/dp_s, where p_s > p_0."""
        out = S["hose_volume"] / S["bulk_modulus"]
        if accumulator:
            n, p0 = S["polytropic_index"], S["precharge_pressure"] + ATMOSPHERE
            pa = ps + ATMOSPHERE
            slope = S["accumulator_volume"] * p0 ** (1 / n) / (n * pa ** (1 + 1 / n))
            out = out + self.xp.where(self.xp.gt(ps, S["precharge_pressure"]), slope, 0 * ps)
        return out

    def rate(self, kind, ps, demand, S, accumulator: bool = False):
        """ṗ_s (Pa/s) at supply pressure ``ps`` with the valves drawing ``demand`` (m³/s)."""
        net = self.pump_flow(kind, ps, S) - self.relief_flow(ps, S) - demand
        return net / self.capacitance(ps, S, accumulator)

    def accumulator_oil(self, ps, S):
        """The oil the accumulator holds at ``ps`` (m³): V_a (1 − (p̄_0/p̄_s)^{1/n}) above p_0, else 0."""
        n, p0 = S["polytropic_index"], S["precharge_pressure"] + ATMOSPHERE
        held = S["accumulator_volume"] * (1 - (p0 / (ps + ATMOSPHERE)) ** (1 / n))
        return self.xp.where(self.xp.gt(ps, S["precharge_pressure"]), held, 0 * ps)


#: The law over SymPy (the derivation layer).
Symbolic = Laws(_SYMPY)
#: Its numpy twin (tested equal).
Numeric = Laws(_NUMPY)
