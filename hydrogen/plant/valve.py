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

from ..actuators.declarations import Parameter, Range
from ..errors import ScenarioError
from ..setting import setting
from . import PlantParameter, PlantState

__all__ = ["POSITION", "STATES", "INPUT", "PARAMETERS", "SCENARIO_SETTINGS", "VALVE_RESPONSE", "input_parameters", "values",
           "rig_response", "Symbolic", "Numeric", "WIDTH"]

#: Its place among the plant's blocks (:data:`hydrogen.plant.BLOCKS`): the spool states after the pressures; its
#: input after friction's.
POSITION = 40

STATES = (
    PlantState("spool", "m", "m", "spool positions (0 with the ideal valve), m"),
    PlantState("spool_rate", "m", "m/s", "spool rates (0 unless the valve is second-order), m/s"),
)

#: The plant's input these numbers are (``plant_rhs``'s argument, the loop configuration's field).
INPUT = "valve"
#: Where the input's numbers come from (the loop header's comment).
INPUT_DOC = "its datasheet valve, else the rig's"

#: The plant's input ``valve``, per actuator, in order. Their ideal values are the controller's own
#: model's valve: no lag, no overlap, no saturation (the spool is the command).
PARAMETERS = (
    PlantParameter("lag", "s", "valve first-order lag (used when the natural frequency is 0; 0: none)",
                   per_actuator=True, lower=0.0),
    # the sub-steps resolve the spool up to omega h / substeps = 1 (the scenario's check)
    PlantParameter("omega", "rad/s", "second-order servo-valve natural frequency (0: none)", per_actuator=True,
                   lower=0.0, upper=lambda sc: float(sc.control_rate) * int(sc.substeps)),
    PlantParameter("zeta", "", "second-order servo-valve damping (dimensionless)", per_actuator=True,
                   lower=0.0, strict=True),
    PlantParameter("overlap", "m", "spool overlap: the dead band |spool| <= overlap passes no flow (0: none)",
                   per_actuator=True, lower=0.0),
    PlantParameter("full_opening", "m", "spool travel at full opening, where the spool saturates (0: none)",
                   per_actuator=True, lower=0.0),
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

#: A datasheet valve: the keys of a description's ``valve`` table (an actuator's, or [hydraulics]'),
#: each with its unit, meaning and plausible range (the loader holds a value to it, naming this
#: module; the description table lists them from here). A key without a default is required, unless
#: :data:`DATASHEET_OPTIONAL` says what its absence means.
DATASHEET = (
    # through one edge: 0.01 L/min (a micro servo-valve) .. 600 m^3/min
    Parameter("rated_flow", "m^3/s", None, "flow through one metering edge at full opening with rated_drop "
              "across it (a servo-valve's rated flow)", range=Range("positive", 1e-7, 10.0)),
    # per metering edge: 0.1 bar .. 1000 bar
    Parameter("rated_drop", "Pa", None, "the pressure drop per metering edge of the rating (e.g. 3.5e6, 35 bar "
              "per edge)", range=Range("positive", 1e4, 1e8)),
    # at full opening: 1 um .. 10 cm
    Parameter("spool_travel", "m", None, "spool travel at full opening (the spool command's unit); the spool "
              "saturates there", range=Range("positive", 1e-6, 0.1)),
    # a slow proportional valve (0.1 Hz) .. 10 kHz
    Parameter("bandwidth_hz", "Hz", None, "the spool's response: −90° at this frequency (second order, natural "
              "frequency 2π f) with damping, else −45° (first order, time constant 1/(2π f))",
              range=Range("positive", 0.1, 1e4)),
    Parameter("damping", "", None, "the spool's second-order damping ratio, > 0", range=Range("positive", 1e-3, 10.0)),
    # a fraction of spool_travel: an edge must open before full opening (< 1); an underlap at most the travel
    Parameter("overlap", "", 0.0, "spool overlap, a fraction of spool_travel in (−1, 1): > 0 a dead band with no "
              "flow, < 0 an underlap", range=Range(None, -1.0, 1.0)),
)

#: The datasheet keys that may be left out though they have no default: what their absence means.
DATASHEET_OPTIONAL = {"damping": "none: first order"}

#: The datasheet keys a valve table must give.
DATASHEET_REQUIRED = tuple(p.name for p in DATASHEET if p.default is None and p.name not in DATASHEET_OPTIONAL)

#: The keys of a scenario's ``actuators.<name>.valve``: the spool's response, over the actuator's
#: datasheet valve's (or the rig's valve settings), key by key; its rating stays the description's.
VALVE_RESPONSE = ("bandwidth_hz", "damping")


def check_response(sc, name: str, table) -> bool:
    """A :class:`ScenarioError` naming ``actuators.<name>.valve[.<key>]`` of scenario ``sc`` unless ``table``
    is a table of :data:`VALVE_RESPONSE` keys, each a finite number within the range a description's
    valve holds it to (:data:`DATASHEET`, all > 0)."""
    from collections.abc import Mapping
    where = f"scenario '{sc.name}': actuators.{name}.valve"
    if not isinstance(table, Mapping) or not table:
        raise ScenarioError(f"{where}: expected a table {{ {', '.join(VALVE_RESPONSE)} }} (the spool's response), "
                            f"got {table!r}")
    unknown = sorted(set(table) - set(VALVE_RESPONSE))
    if unknown:
        raise ScenarioError(f"{where}: unknown key(s) {unknown}; a scenario sets the spool's response "
                            f"({', '.join(VALVE_RESPONSE)}): the rating (flow, drop, travel, overlap) is the "
                            "actuator's description's")
    declared = {p.name: p for p in DATASHEET}
    for key, v in table.items():
        q = declared[key]
        lo, hi = q.range.low, q.range.high
        unit = f" {q.unit}" if q.unit else ""
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or not lo <= v <= hi:
            raise ScenarioError(f"{where}.{key} must be a finite number in [{lo:.6g}, {hi:.6g}]{unit} "
                                f"(declared in {__name__}), got {v!r}")
    return False  # checked here


#: What a scenario may give per actuator for this block (``actuators.<name>.valve``), each with its check.
ACTUATOR_SETTINGS = {"valve": check_response}


def input_parameters(structure) -> tuple:
    """The input ``valve``'s parameters per actuator: all of :data:`PARAMETERS`, on every robot."""
    return PARAMETERS


def rig_response(sc) -> np.ndarray:
    """The rig's spool response [first-order lag s, natural frequency rad/s, damping] of a scenario."""
    return np.array([sc.valve_lag, 2 * np.pi * sc.valve_bandwidth_hz, sc.valve_damping], float)


def _own_response(sc, c, row: tuple) -> tuple:
    """Actuator ``c``'s valve row ``row`` ([lag s, ω rad/s, ζ, overlap m, full opening m]: its datasheet
    valve's, else the rig's) with the scenario's ``actuators.<name>.valve`` over its spool response:
    bandwidth_hz sets ω (second order: damping given, or the response it replaces is one) or else the
    lag 1/(2π f) (first order); damping alone changes a second-order spool's damping (ScenarioError
    where there is none)."""
    own = sc.actuators[c.name]["valve"]
    lag, omega, zeta, *geometry = row
    if "bandwidth_hz" not in own:
        if omega <= 0.0:
            raise ScenarioError(f"scenario '{sc.name}': actuators.{c.name}.valve.damping = {own['damping']!r} needs "
                                "a second-order spool to apply to (the actuator's valve has none here): give "
                                "bandwidth_hz too")
        return (0.0, omega, float(own["damping"]), *geometry)
    w = 2 * np.pi * float(own["bandwidth_hz"])
    if "damping" in own or omega > 0.0:  # second order: its damping given, or the response it replaces is one
        return (0.0, w, float(own.get("damping", zeta)), *geometry)
    return (1.0 / w, 0.0, zeta, *geometry)  # first order, as a datasheet valve without damping


def values(sc, model) -> np.ndarray:
    """The plant's valve input of every actuator of ``model`` in scenario ``sc``, (m, 5): [first-order
    lag s, natural frequency rad/s, damping, overlap m, full opening m] (:data:`PARAMETERS`). An
    actuator's datasheet valve (``Cylinder.valve``, the description's ``valve`` table) overrides the
    rig's valve settings for it where the scenario's valve is not ideal (a lag or a natural frequency
    set; in an ideal valve's scenario only its overlap and saturation stay); without one, the rig's
    apply as they are (no overlap, no saturation). A scenario's ``actuators.<name>.valve``
    (bandwidth_hz, damping) replaces the spool response so chosen for that actuator, in any scenario.
    ScenarioError where an actuator's natural frequency is too fast for the plant's sub-steps (the
    scenario's own rule for valve_bandwidth_hz)."""
    rig = (*rig_response(sc), 0.0, 0.0)
    dynamic = rig[0] > 0.0 or rig[1] > 0.0
    omega_max = next(p for p in PARAMETERS if p.name == "omega").upper_of(sc)
    rows = []
    for c in model.cylinders:
        own = getattr(c, "valve", None)
        row = rig if own is None else tuple(float(own[p.name]) for p in PARAMETERS)
        if sc.actuators.get(c.name, {}).get("valve"):  # the scenario's spool response for it, in any scenario
            row = _own_response(sc, c, row)
        elif own is not None and not dynamic:  # an ideal valve's scenario: the spool follows at once, its geometry stays
            row = (0.0, 0.0, *row[2:])
        if row[1] / omega_max > 1.0:  # the scenario's own rule for valve_bandwidth_hz, to the bit
            raise ScenarioError(f"scenario '{sc.name}': actuator '{c.name}': its valve's bandwidth_hz "
                                f"{row[1] / (2 * np.pi):.6g} Hz must be <= control_rate * substeps / (2 pi) = "
                                f"{omega_max / (2 * np.pi):.6g} Hz (raise substeps)")
        rows.append(row)
    return np.array(rows, float).reshape(len(rows), WIDTH)


class Symbolic:
    """The valve law over SymPy. In the plant (:mod:`hydrogen.symbolic.plant`) it gives the effective
    spool each actuator's chambers see, ``spool_eff`` (m, one intermediate), from the spool states,
    the command ``u`` and its input ``valve``, and moves the spool."""

    READS = ("spool", "u", INPUT)
    WRITES = ("spool_eff",)

    @staticmethod
    def outputs(c) -> None:
        # an intermediate: nesting its Piecewise inside the valve law's would make SymPy merge
        # conditions (slow, and ITE nodes)
        c.provide("spool_eff", Symbolic.effective(c["spool"], c["u"], c[INPUT],
                                                  [a.valve_limits for a in c.model.cylinders]), prefix="spool_eff")

    @staticmethod
    def derivatives(c) -> None:
        for name, value in Symbolic.rates(c["spool"], c["spool_rate"], c["u"], c[INPUT]).items():
            c.rate(name, value)

    @staticmethod
    def states(model) -> dict:
        from ..symbolic.kinematics import rate_symbols
        m = model.n_cylinders
        return {"spool": rate_symbols("spool", m), "spool_rate": rate_symbols("spool_rate", m)}

    @staticmethod
    def input(model):
        """The symbols of the plant's input ``valve`` of ``model``: :meth:`parameters` of its actuators."""
        return Symbolic.parameters(model.n_cylinders)

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
