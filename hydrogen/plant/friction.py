"""The plant's friction: each actuator's seal friction, in its own unit (N on a cylinder, N m on a
rotary actuator), opposing its motion. No state; its parameters are the plant's input ``friction``,
:data:`PARAMETERS` per actuator in order.

The law is the Stribeck curve of Armstrong-Hélouvry (Armstrong-Hélouvry, Dupont, Canudas de Wit,
"A survey of models, analysis tools and compensation methods for the control of machines with
friction", Automatica 30(7), 1994) in the smooth form Simscape's friction blocks use, with the
pressure-dependent Coulomb level of Simscape Fluids' cylinder friction:

    F_c,eff = F_c + k_p S,   S = Σ |chamber force| (N or N m, :func:`Symbolic.seal_load`),
    f_fric  = (F_c,eff + (F_brk − F_c) exp(−(l̇ / v_st)²)) tanh(l̇ / v_s) + b l̇,

F_c the Coulomb force, F_brk ≥ F_c the breakaway force (the static friction peak, reached as
|l̇| ≫ v_s but ≪ v_st), v_st the Stribeck speed (the width of the dip from breakaway to Coulomb), b the
viscous coefficient, v_s the speed of the tanh smoothing through zero speed, k_p the dimensionless
pressure coefficient: the seals' squeeze rises with the chamber pressures, raising the Coulomb and
breakaway levels alike (the Stribeck excess F_brk − F_c is the given one). With F_brk = F_c and
k_p = 0 the law is f = F_c tanh(l̇ / v_s) + b l̇.

The Stribeck dip (breakaway, stribeck_speed) and the pressure load (pressure_coefficient) are
structure, like the valve's saturation: an actuator's plant has each only where its description
declares it (its ``friction`` table, :attr:`hydrogen.model.Cylinder.seal_terms`); a robot without
seal friction has today's plant, bit for bit, and its input ``friction`` is [F_c, b, v_s] per actuator
(:func:`parameters_of`). The numbers, those three and the seal's, are runtime inputs.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import ScenarioError
from ..setting import setting
from . import PlantParameter, structure_flag

__all__ = ["POSITION", "STATES", "INPUT", "PARAMETERS", "SCENARIO_SETTINGS", "SEAL", "TERMS", "LOWER", "KEYS", "parameters_of",
           "input_parameters", "table_problem", "check_table", "terms_of", "row", "actuator_row", "values", "Symbolic",
           "Numeric"]

#: Its place among the plant's blocks (:data:`hydrogen.plant.BLOCKS`): no state; its input is the first of the
#: blocks' inputs.
POSITION = 30

STATES = ()

#: The rig's friction, a scenario's setting (:mod:`hydrogen.scenario_settings`): every cylinder's,
#: under its description's friction table and the scenario's own per actuator.
SCENARIO_SETTINGS = {
    "friction": setting((0.0, 0.0, 1e-3), "N, N s/m, m/s", "per cylinder: Coulomb, viscous, tanh smoothing speed"),
}

#: The plant's input these numbers are (``plant_rhs``'s argument, the loop configuration's field).
INPUT = "friction"
#: Where the input's numbers come from (the loop header's comment).
INPUT_DOC = "in the actuator's own unit: its description's seal friction, else the rig's"

#: Per actuator, in order, each in the actuator's own unit (its kind's TRAVEL). The first three are
#: the rig setting ``friction = [F_c, b, v_s]``, in its order; the rest (:data:`SEAL`) are inputs only
#: of a robot with seal friction. Their ideal values are the controller's own model's: no friction
#: (the speeds only keep the arguments of tanh and exp finite).
PARAMETERS = (
    PlantParameter("coulomb", lambda t: t.force_unit, "Coulomb friction (F_c)", per_actuator=True, lower=0.0),
    PlantParameter("viscous", lambda t: f"{t.force_unit} s/{t.unit}", "viscous friction coefficient (b)",
                   per_actuator=True, lower=0.0),
    PlantParameter("smooth_speed", lambda t: f"{t.unit}/s", "speed of the tanh smoothing of the Coulomb "
                   "friction (v_s)", per_actuator=True, ideal=1.0, lower=0.0, strict=True),
    PlantParameter("breakaway", lambda t: t.force_unit, "breakaway (static) friction, >= Coulomb (F_brk)",
                   per_actuator=True, lower=0.0),
    PlantParameter("stribeck_speed", lambda t: f"{t.unit}/s", "Stribeck speed of the dip from breakaway to "
                   "Coulomb friction (v_st)", per_actuator=True, ideal=1.0, lower=0.0, strict=True),
    PlantParameter("pressure_coefficient", "", "pressure coefficient of the Coulomb friction on the chamber "
                   "forces' magnitude sum (k_p, dimensionless)", per_actuator=True, lower=0.0),
)

#: The parameters of the seal's structural terms: in the input ``friction`` only of a robot one of
#: whose actuators declares seal friction.
SEAL = ("breakaway", "stribeck_speed", "pressure_coefficient")

#: The structural terms an actuator's description may declare, each with the keys that declare it
#: (a value above the one that means none: breakaway above coulomb, pressure_coefficient above 0).
TERMS = {"stribeck": ("breakaway", "stribeck_speed"), "pressure": ("pressure_coefficient",)}

#: Each parameter's lowest value and whether it must exceed it (True) or may equal it, by name: the
#: checks of a friction table and the FMU's ranges (breakaway >= coulomb is checked where both are known).
LOWER = {p.name: (p.lower, p.strict) for p in PARAMETERS}

#: The keys of a seal friction table (an actuator's description's ``friction``, a rig's
#: ``actuators.<name>.friction``), in the actuator's own unit.
KEYS = ("coulomb", "breakaway", "stribeck_speed", "viscous", "pressure_coefficient", "smooth_speed")


def parameters_of(seal: bool) -> tuple:
    """The input ``friction``'s parameters per actuator: all of :data:`PARAMETERS` for a robot with seal
    friction (``seal``), else those outside :data:`SEAL` ([F_c, b, v_s], the input as it always was)."""
    return tuple(p for p in PARAMETERS if seal or p.name not in SEAL)


#: The rule of a friction row [F_c, b, v_s] (the rig's ``friction``, or an actuator's as a list).
ROW_RULE = "must be (Coulomb >= 0 N, viscous >= 0 N s/m, smoothing speed > 0 m/s)"


def row_ok(value) -> bool:
    """Whether ``value`` is a friction row [F_c >= 0, b >= 0, v_s > 0] of finite numbers (:data:`ROW_RULE`)."""
    try:
        fr = np.asarray(value, float)
    except (TypeError, ValueError):
        return False
    return fr.shape == (3,) and bool(np.all(np.isfinite(fr))) and fr[0] >= 0 and fr[1] >= 0 and fr[2] > 0


def check_actuator_setting(sc, name: str, value) -> bool:
    """Scenario ``sc``'s ``actuators.<name>.friction``: a seal friction table is checked here (its keys
    and ranges, the rest per model: :func:`check_table`; a :class:`ScenarioError` naming the key); a row
    [F_c, b, v_s] is the scenario's own ``friction`` field, checked as that (True)."""
    if isinstance(value, Mapping):
        check_table(sc, name, value, complete=False)
        return False
    return True


#: What a scenario may give per actuator for this block (``actuators.<name>.friction``), with its check.
ACTUATOR_SETTINGS = {"friction": check_actuator_setting}


def input_parameters(structure) -> tuple:
    """The input ``friction``'s parameters per actuator for a robot's ``structure`` (its model or its
    manifest's model summary): :func:`parameters_of` its seal friction."""
    return parameters_of(structure_flag(structure, "seal_friction"))


def table_problem(table, coulomb=None, complete=True):
    """The first fault of a seal friction table (``{key: value}``, :data:`KEYS`) as (key or None, what is
    wrong), or None. ``coulomb``: the Coulomb level the table's breakaway must reach when the table gives
    none (None: unknown yet). ``complete``: the table is all there is (a breakaway above the Coulomb
    level then needs its stribeck_speed); False: a part, merged later over another."""
    import math
    import numbers

    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        return None, f"unknown key(s) {unknown}; keys: {', '.join(KEYS)} (in the actuator's own unit)"
    for key, v in table.items():
        lo, strict = LOWER[key]
        ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or v < lo or (strict and v <= lo):
            return key, (f"must be a finite number {'>' if strict else '>='} {lo!r}, got {v!r} (in the "
                         "actuator's own unit)")
    coulomb = table.get("coulomb", coulomb)
    if "breakaway" in table and coulomb is not None:
        if table["breakaway"] < coulomb:
            return "breakaway", (f"must be >= coulomb ({coulomb!r}), got {table['breakaway']!r} (static friction "
                                 "is at least the sliding one)")
    if complete and table.get("breakaway", 0.0) > (coulomb or 0.0) and "stribeck_speed" not in table:
        return "stribeck_speed", ("must be given with a breakaway above coulomb (the width of the dip from "
                                  "breakaway to Coulomb, in the actuator's own unit per second)")
    return None


def check_table(sc, name: str, table, complete=True, sources=None):
    """A :class:`ScenarioError` naming ``actuators.<name>.friction.<key>`` of scenario ``sc`` for the first
    fault of seal friction table ``table`` (:func:`table_problem`); ``sources``: where each key's value
    came from, for the message (a key from the actuator's description, or the scenario's friction)."""
    problem = table_problem(table, complete=complete)
    if problem is not None:
        key, what = problem
        where = f"scenario '{sc.name}': actuators.{name}.friction"
        text = f"{where}.{key} {what}" if key else f"{where}: {what}"
        came = (sources or {}).get(key)
        raise ScenarioError(text + (f" ({key} from {came})" if came else ""))


def terms_of(table) -> tuple:
    """(stribeck, pressure): the structural terms a description's seal friction table declares (None:
    none): the Stribeck dip for a breakaway above its coulomb (0 if not given), the pressure load for a
    pressure_coefficient above 0. A value that means none is structure, as leakage's 0."""
    if not table:
        return (False, False)
    return (table.get("breakaway", 0.0) > table.get("coulomb", 0.0), table.get("pressure_coefficient", 0.0) > 0.0)


def row(coulomb, viscous, smooth_speed, breakaway=None, stribeck_speed=1.0, pressure_coefficient=0.0) -> tuple:
    """One actuator's parameters in :data:`PARAMETERS` order; breakaway None: the Coulomb force (no
    Stribeck dip, whatever the Stribeck speed)."""
    return (coulomb, viscous, smooth_speed, coulomb if breakaway is None else breakaway, stribeck_speed,
            pressure_coefficient)


def actuator_row(sc, c, seal: bool) -> tuple:
    """Actuator ``c``'s (a model's cylinder) friction numbers, its plant input's
    (:func:`parameters_of`: all six for a robot with seal friction, ``seal``), in its own
    unit: the scenario's ``actuators.<name>.friction`` (the list [F_c, b, v_s] or a seal friction table)
    over its description's friction table (``Cylinder.friction``) over the scenario's ``friction`` (a
    cylinder's; none on a joint actuator), key by key. The description's table applies where the
    scenario has friction on (its ``friction`` not zero, or the actuator's own given): an ideal plant
    stays frictionless. A :class:`ScenarioError` naming the actuator and
    the key for a value out of range, or one asking for a seal term its plant is generated without (a
    breakaway above coulomb, a pressure_coefficient above 0: structure, declared in its description)."""
    from ..actuators import actuator
    from ..actuators.declarations import LENGTH

    names = [par.name for par in parameters_of(False)]  # the list's [F_c, b, v_s]
    # a joint actuator's is none unless given (the smoothing speed only keeps tanh finite)
    base = sc.friction if actuator(c.kind).TRAVEL == LENGTH else (0.0, 0.0, sc.friction[2])
    own = sc.actuators.get(c.name, {}).get("friction")
    given = own is not None
    own = dict(zip(names, own)) if own is not None and not isinstance(own, Mapping) else dict(own or {})
    # the description's numbers are the seal's where the scenario has friction on (the rig's); a
    # scenario with none (an ideal plant) runs the actuator frictionless
    on = given or any(float(v) != 0.0 for v in sc.friction[:2])
    desc = dict(c.friction or {}) if on else {}
    table = {**dict(zip(names, base)), **desc, **own}
    sources = {k: ("its description" if k in desc else "the scenario's friction") for k in table if k not in own}
    check_table(sc, c.name, table, sources=sources)
    built = dict(zip(TERMS, c.seal_terms))
    for term, asked in zip(TERMS, terms_of(table)):
        if asked and not built[term]:
            key = TERMS[term][0]
            raise ScenarioError(
                f"scenario '{sc.name}': actuators.{c.name}.friction.{key} = {table[key]!r} asks for the seal "
                f"friction's {'Stribeck dip' if term == 'stribeck' else 'pressure load'}, which actuator "
                f"'{c.name}''s plant is generated without: declare it in the actuator's description "
                f"([[cylinders]] '{c.name}' friction = {{ {', '.join(TERMS[term])} }}), which builds it in")
    full = row(table["coulomb"], table["viscous"], table["smooth_speed"], table.get("breakaway"),
                        table.get("stribeck_speed", 1.0), table.get("pressure_coefficient", 0.0))
    return tuple(float(v) for v in full[:len(parameters_of(seal))])


def values(sc, model) -> np.ndarray:
    """The plant's friction input of every actuator of ``model`` in scenario ``sc``, (m, width):
    :func:`actuator_row` of each, in its own unit."""
    return np.array([actuator_row(sc, c, model.seal_friction) for c in model.cylinders], float).reshape(
        model.n_cylinders, len(input_parameters(model)))


def _excess(pressure_coefficient, seal_load, breakaway, coulomb, dip):
    """The level above F_c: k_p S + (F_brk − F_c) exp(−(l̇/v_st)²) (``dip`` the exponential), either layer."""
    return pressure_coefficient * seal_load + (breakaway - coulomb) * dip


class Symbolic:
    """The friction law over SymPy. In the plant (:mod:`hydrogen.symbolic.plant`) it adds each
    actuator's friction, opposed to its rate ``ldot``, to ``leg_force``, from its input ``friction``
    and, with a pressure load, the chamber forces of the actuator's kind's law."""

    READS = ("ldot", "laws", "pressures", "P", INPUT)
    #: each actuator's friction force (N or N m), for a block whose law needs it (a seal's heating)
    WRITES = ("friction_force",)
    ADDS = ("leg_force",)

    @staticmethod
    def outputs(c) -> None:
        from ..actuators.declarations import sp
        model = c.model
        names = [par.name for par in parameters_of(model.seal_friction)]
        k, fric, ldot = len(names), c[INPUT], c["ldot"]
        laws, p, P = c["laws"], c["pressures"], c["P"]
        out = []
        for i, a in enumerate(model.cylinders):
            par = dict(zip(names, fric[k * i:k * i + k]))
            stribeck, pressure = a.seal_terms  # the structural terms its description declares
            out.append(Symbolic.force(
                ldot[i], par["coulomb"], par["viscous"], par["smooth_speed"],
                (par["breakaway"], par["stribeck_speed"]) if stribeck else None,
                (par["pressure_coefficient"], Symbolic.seal_load(laws[i].chamber_forces(p[i], P[i])))
                if pressure else None))
        c.provide("friction_force", sp.Matrix(out))
        c.add("leg_force", [-f for f in out])

    @staticmethod
    def input(model):
        """The symbols of the plant's input ``friction`` of ``model``: :meth:`parameters` of its actuators."""
        return Symbolic.parameters(model.n_cylinders, model.seal_friction)

    @staticmethod
    def parameters(m: int, seal: bool = False):
        """The symbols of :func:`parameters_of` ``(seal)`` of ``m`` actuators, actuator after actuator."""
        from ..actuators.declarations import sp
        names = "F_coulomb_{i} b_viscous_{i} v_smooth_{i}" + (" F_breakaway_{i} v_stribeck_{i} k_pressure_{i}"
                                                               if seal else "")
        return sp.Matrix([s for i in range(m) for s in sp.symbols(names.format(i=i), real=True)])

    @staticmethod
    def seal_load(chamber_forces):
        """S = Σ |f_j| over an actuator's chamber forces (its kind's ``chamber_forces``), N or N m."""
        from ..actuators.declarations import sp
        return sp.Add(*[sp.Abs(f) for f in chamber_forces])

    @staticmethod
    def force(ldot, coulomb, viscous, smooth_speed, stribeck=None, pressure=None):
        """The friction force (torque) at rate ``ldot``, opposed to the motion by its user (the module
        docstring's law) with the structural terms given: ``stribeck`` = (F_brk, v_st), ``pressure`` =
        (k_p, S); None: the term is not in the plant (F_c tanh(l̇/v_s) + b l̇, today's expression)."""
        from ..actuators.declarations import sp
        smooth = sp.tanh(ldot / smooth_speed)
        if stribeck is None and pressure is None:
            return coulomb * smooth + viscous * ldot
        kp, load = pressure if pressure is not None else (0, 0)
        brk, vst, dip = (*stribeck, sp.exp(-(ldot / stribeck[1]) ** 2)) if stribeck is not None else (coulomb, 1, 0)
        # F_c tanh stays its own term, the excess level apart: the term-free sum's terms are untouched
        return coulomb * smooth + _excess(kp, load, brk, coulomb, dip) * smooth + viscous * ldot


class Numeric:
    """The friction law over numpy (the same numbers as :class:`Symbolic`), every term present."""

    @staticmethod
    def seal_load(chamber_forces):
        return sum(np.abs(np.asarray(f, float)) for f in chamber_forces)

    @staticmethod
    def force(ldot, coulomb, viscous, smooth_speed, breakaway, stribeck_speed, pressure_coefficient, seal_load):
        ldot = np.asarray(ldot, float)
        smooth = np.tanh(ldot / smooth_speed)
        return (coulomb * smooth + _excess(pressure_coefficient, seal_load, breakaway, coulomb,
                                           np.exp(-(ldot / stribeck_speed) ** 2)) * smooth + viscous * ldot)
