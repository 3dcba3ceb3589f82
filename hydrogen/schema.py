"""Every key of a robot description and every scenario field, with its unit, default and meaning:
the one definition the loader checks keys against (:mod:`hydrogen.model`) and the documentation's
reference table is rendered from (:func:`description_table`), so the two cannot disagree.

Scenario fields are declared once, with their defaults, units, meanings and checks, as the fields of
:class:`hydrogen.simulation.scenarios.Scenario` (:func:`hydrogen.simulation.scenarios.setting`); their
rows are rendered from those declarations.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from . import references
from .scenario_settings import actuator_keys

__all__ = ["Key", "REQUIRED", "DESCRIPTION_KEYS", "SCENARIO_TABLE_KEYS", "VARIANT_KEYS", "keys",
           "default", "description_table"]


class _Required:
    def __repr__(self):
        return "required"


#: The default of a key that must be given.
REQUIRED = _Required()


@dataclass(frozen=True)
class Key:
    """One description key: the ``table`` it sits in (``"top level"``, ``"[[links]]"``, ...), its
    name, its unit (SI), its default (:data:`REQUIRED`, a value, or a sentence in ``default_text``)
    and what it means."""

    table: str
    key: str
    unit: str
    meaning: str
    default: object = REQUIRED
    default_text: str = ""


_HYDRAULIC = (  # [hydraulics] gives them for every cylinder; a [[cylinders]] entry may override any
    ("piston_area", "m²", "A, control-chamber (cap side) area, > rod_area"),
    ("rod_area", "m²", "a, annulus area on the rod side, which is held at supply pressure"),
    ("chamber_length", "m", "L: the control chamber holds A (l − L); below the shortest length"),
    ("supply_pressure", "Pa", "P_s, supply pressure"),
    ("underlap", "m", "d, valve underlap (spool travel); 0 allowed"),
    ("flow_gain", "m²/(s √Pa)", "c of (57): q_l = c u √Δp"),
    ("bulk_modulus", "Pa", "β, oil bulk modulus"),
    ("orifice_linear_below", "Pa", "the simulated plant's orifice roots turn linear below this pressure drop"),
    ("stroke", "m", "[shortest, longest] pin-to-pin length"),
    ("leakage", "m³/(s Pa)", "c_l of (56): laminar leakage into the control chamber from the rod side at "
     "supply, Q = c_l (P_s − p_c); ≥ 0, 0: none (the paper's c_l ≈ 0)"),
)

def _three_way_default(key: str) -> str:
    """The default of a three-way cylinder's key as its kind declares it, else "required ..."."""
    from .actuators import actuator
    default = {p.name: p.default for p in actuator("three_way_cylinder").PARAMETERS}.get(key)
    return "required here or in [hydraulics]" if default is None else repr(default)


def _supply_keys() -> tuple:
    """The [supply] keys: ``kind`` and the supply block's parameters, from its own declarations
    (hydrogen/plant/supply.py)."""
    from .plant import supply
    takes = {name: [k for k in supply.KINDS if name in supply.NEEDS[k]] for name in
             (p.name for p in supply.PARAMETERS)}
    return (Key("[supply]", "kind", "", "\"constant\": each actuator's supply_pressure, fixed; \"pump\": a "
                "fixed-displacement pump with a relief valve; \"compensated_pump\": a pressure-compensated pump "
                "holding set_pressure, with a relief valve (Robot description page, Supply)",
                default=supply.DEFAULT_KIND),
            *(Key("[supply]", p.name, p.unit.replace("^3", "³"), f"{p.doc}; kind {' or '.join(takes[p.name])}",
                  default=p.default if p.default is not None else REQUIRED,
                  default_text="" if p.default is not None else
                  ("the actuators' bulk_modulus" if p.name == "bulk_modulus" else
                   "required with an accumulator" if p.name == "precharge_pressure" else "required"))
              for p in supply.PARAMETERS))


def _valve_keys() -> tuple:
    """A datasheet valve's keys, from the valve block's own declarations (hydrogen/plant/valve.py)."""
    from .plant import valve
    return tuple(Key("[[cylinders]] valve", p.name, p.unit.replace("^3", "³"), p.doc,
                     default=p.default if p.default is not None else
                     (None if p.name in valve.DATASHEET_OPTIONAL else REQUIRED),
                     default_text=valve.DATASHEET_OPTIONAL.get(p.name, "")) for p in valve.DATASHEET)


DESCRIPTION_KEYS = (
    Key("top level", "name", "", "the model's name: ASCII letters, digits and single underscores, "
        "starting with a letter (it names C symbols and files)"),
    Key("top level", "gravity", "m/s²", "gravity along −z of the base frame; 0 allowed"),
    Key("top level", "rigid_body_form", "", "the rigid body's code: \"closed\" (expanded link Jacobians, C "
        "from ∂D/∂q), \"staged\" (link poses as intermediate symbols, spatial algebra; revolute, prismatic and "
        "fixed joints only) or \"auto\", the one of fewer CasADi instructions, staged without counting for a "
        "tree with a rotated joint origin or a tilted axis above a moving joint (Code generation page); all give the same D, C, G, Y", default="auto"),
    Key("top level", "controllers", "", "the controllers generated for this robot (names of "
        "hydrogen.controllers.CONTROLLERS); a run, export or FMU of another is refused naming this key",
        default=None, default_text="all of hydrogen's controllers"),
    Key("top level", "urdf", "", "a URDF file for the tree, relative to the TOML file, instead of "
        "[[links]] and [[joints]]", default=None, default_text="none: the tree is [[links]]/[[joints]]"),
    Key("top level", "tree", "", "the [tree] table: which part of the tree is kept (below)", default=None,
        default_text="none: the whole tree"),
    Key("top level", "links", "", "the [[links]] tables (below)", default_text="required unless urdf"),
    Key("top level", "joints", "", "the [[joints]] tables (below)", default_text="required unless urdf"),
    Key("top level", "coordinates", "", "the [coordinates] table (below)"),
    Key("top level", "supply", "", "the [supply] table: what feeds the valves (below)", default=None,
        default_text="none: a constant supply pressure, each actuator's supply_pressure"),
    Key("top level", "hydraulics", "", "defaults for every cylinder's constants (the [[cylinders]] keys "
        "piston_area ... stroke)", default=None, default_text="none"),
    Key("top level", "cylinders", "", "the [[cylinders]] tables: one per coordinate"),
    Key("top level", "adaptation", "", "the [adaptation] table (below)"),
    Key("top level", "sensors", "", "the [sensors] table", default=None, default_text="none"),
    Key("top level", "control", "", "the [control] table", default=None, default_text="none"),
    Key("top level", "figures", "", "the [figures] table", default=None, default_text="none"),
    Key("top level", "gains", "", "[gains.<controller>] and [gains.common]: gains over the "
        "controllers' defaults (names: Controllers page)", default=None, default_text="none"),
    Key("top level", "rig", "", "the experiment-like rig: any scenario field (table below), the "
        "start of every scenario with rig = true", default=None, default_text="none"),
    Key("top level", "scenarios", "", "[scenarios.<name>] tables (below)", default=None, default_text="none"),
    Key("top level", "variants", "", "[variants.<name>] tables: scenario fields set over any scenario run as "
        "<scenario>.<name> (the rig's timing, say)", default=None, default_text="none"),
    Key("[[links]]", "name", "", "the link's name (letters, digits, single underscores)"),
    Key("[[links]]", "mass", "kg", "mass, > 0; 0 for a massless frame (a sensor, a tool point: no com, no inertia), "
        "as a URDF link without an inertial"),
    Key("[[links]]", "com", "m", "centre of mass in the link frame", default=[0.0, 0.0, 0.0]),
    Key("[[links]]", "inertia", "kg m²", "about the centre of mass, link axes: [Ixx, Iyy, Izz] or "
        "[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]; positive definite, triangle inequality (none for a massless frame)"),
    Key("[[joints]]", "name", "", "the joint's name"),
    Key("[[joints]]", "type", "", "revolute, continuous (read as revolute), prismatic, fixed or floating "
        "(six coordinates [x, y, z, ψ, θ, φ], R = Rz(φ) Ry(θ) Rx(ψ))"),
    Key("[[joints]]", "parent", "", "parent link; the link no joint moves is the fixed base (base frame, z up)"),
    Key("[[joints]]", "child", "", "child link"),
    Key("[[joints]]", "origin_xyz", "m", "joint origin in the parent frame", default=[0.0, 0.0, 0.0]),
    Key("[[joints]]", "origin_rpy", "rad", "joint orientation in the parent frame (roll, pitch, yaw)",
        default=[0.0, 0.0, 0.0]),
    Key("[[joints]]", "axis", "", "joint axis in the joint frame (normalised)", default=[0.0, 0.0, 1.0]),
    Key("[[joints]]", "limit", "rad or m; rad/s or m/s; N m or N", "{ lower, upper, velocity, effort } as URDF's "
        "<limit>: a reference beyond the position or velocity limit is refused before a run", default=None,
        default_text="none"),
    Key("[tree]", "base", "", "a link whose sub-tree alone is kept; it becomes the fixed base", default=None,
        default_text="the tree's root"),
    Key("[tree]", "locked", "rad or m", "{ joint = position }: revolute or prismatic joints held fixed (the "
        "other legs of a quadruped, a gripper)", default=None, default_text="none"),
    Key("[tree]", "drop", "", "[joint, ...]: fixed joints of the kept tree left out with every link below them "
        "(a sensor frame, a tool); of a URDF, what is left out is not checked", default=None, default_text="none"),
    Key("[[cylinders]]", "name", "", "the cylinder's name"),
    Key("[[cylinders]]", "from", "", "{ link, point }: the first pin"),
    Key("[[cylinders]]", "to", "", "{ link, point }: the second pin, on another link"),
    *(Key("[[cylinders]]", k, unit, what, default_text=_three_way_default(k)) for k, unit, what in _HYDRAULIC),
    Key("[[cylinders]] from/to", "link", "", "the link the pin is on"),
    Key("[[cylinders]] from/to", "point", "m", "the pin in that link's frame"),
    Key("[[cylinders]]", "linkage", "", "the rod end drives a revolute joint through a planar four-bar "
        "linkage (table below) instead of a pin 'to': the cylinder's base 'from' is on the joint's parent "
        "link, its rod end on the pin joining the rocker and the coupler", default=None,
        default_text="none: pinned from/to"),
    Key("[[cylinders]] linkage", "joint", "", "the revolute joint it drives (it needs position limits: "
        "the linkage must close, stay inside the stroke and pass no dead centre over them)"),
    Key("[[cylinders]] linkage", "rocker_pivot", "m", "the rocker's pivot on the joint's parent link, "
        "in that link's frame (an excavator's power link, pivoting on the stick)"),
    Key("[[cylinders]] linkage", "rocker", "m", "rocker length, pivot to the rod-end pin"),
    Key("[[cylinders]] linkage", "coupler", "m", "coupler length, rod-end pin to crank_pin (an "
        "excavator's bucket link)"),
    Key("[[cylinders]] linkage", "crank_pin", "m", "where the coupler pins on the driven (child) link, in "
        "its frame; all points in one plane normal to the joint axis"),
    Key("[[cylinders]] linkage", "branch", "", "1 or −1: the assembly, the rod-end pin to the left (1) or "
        "right of the line crank_pin → rocker_pivot, seen with the joint axis towards you"),
    Key("[[cylinders]]", "valve", "", "the actuator's valve from its datasheet (table below; in [hydraulics]: "
        "every actuator's without its own): its rating sets flow_gain (give one, not both) and its overlap "
        "the underlap; its spool response replaces the rig's valve settings for this actuator",
        default=None, default_text="none: flow_gain, underlap and the rig's valve settings"),
    *_valve_keys(),
    Key("[[cylinders]]", "friction", "the actuator's own: N or N m, m/s or rad/s", "the actuator's seal "
        "friction (table below; in [hydraulics]: every actuator's without its own, in each one's own unit): a "
        "breakaway above coulomb puts the Stribeck dip in its generated plant, a "
        "pressure_coefficient above 0 the seals' pressure load; its numbers replace the rig's friction for "
        "this actuator wherever a scenario has friction on (an ideal plant, friction zero, stays frictionless; "
        "a scenario's actuators.<name>.friction still overrides them key by key)",
        default=None, default_text="none: the rig's friction, no seal terms in the plant"),
    Key("[[cylinders]] friction", "coulomb", "N or N m", "sliding (Coulomb) friction F_c, >= 0",
        default=None, default_text="the rig's friction[0]"),
    Key("[[cylinders]] friction", "breakaway", "N or N m", "static friction F_brk at the start of motion, "
        ">= coulomb; above it: the Stribeck dip (structure)", default=None, default_text="coulomb: no dip"),
    Key("[[cylinders]] friction", "stribeck_speed", "m/s or rad/s", "v_st > 0: width of the dip from "
        "breakaway to Coulomb", default=None, default_text="required with breakaway above coulomb"),
    Key("[[cylinders]] friction", "viscous", "N s/m or N m s/rad", "viscous coefficient b, >= 0",
        default=None, default_text="the rig's friction[1]"),
    Key("[[cylinders]] friction", "pressure_coefficient", "", "k_p >= 0: the Coulomb and breakaway levels "
        "rise by k_p times the chamber forces' magnitude sum; above 0: the pressure load (structure)",
        default=0.0),
    Key("[[cylinders]] friction", "smooth_speed", "m/s or rad/s", "v_s > 0 of the tanh through zero speed",
        default=None, default_text="the rig's friction[2]"),
    *_supply_keys(),
    Key("[coordinates]", "names", "", "one distinct name per coordinate", default_text="the joints' names "
        "(a floating joint's as <joint>_x ... <joint>_phi)"),
    Key("[coordinates]", "neutral", "m, rad", "the neutral pose, about which scenario references are offsets"),
    Key("[adaptation]", "parameters", "", "θ: \"<link>.<p>\", p one of mass, mcx, mcy, mcz (kg m, link frame), "
        "Ixx, Ixy, Iyy, Ixz, Iyz, Izz (kg m², about the link origin)"),
    Key("[adaptation]", "theta_min", "SI of each parameter", "projection lower bounds; must contain the true values"),
    Key("[adaptation]", "theta_max", "SI of each parameter", "projection upper bounds"),
    Key("[adaptation]", "gamma1_min", "Pa", "lower bound of γ1 = β, > 0"),
    Key("[adaptation]", "gamma1_max", "Pa", "upper bound of γ1"),
    Key("[adaptation]", "gamma2_min", "Pa m²/(s √Pa)", "lower bound of γ2 = βc, > 0"),
    Key("[adaptation]", "gamma2_max", "Pa m²/(s √Pa)", "upper bound of γ2"),
    Key("[sensors]", "joint_encoders", "", "true: the pose is measured at the joints; false: by Newton's "
        "forward kinematics on the measured cylinder lengths", default=False),
    Key("[control]", "scale", "kg, kg m²", "per-coordinate inertia the default gains scale with",
        default=None, default_text="the diagonal of D at the neutral pose"),
    Key("[control]", "friction_compensation", "", "true: backstepping, adaptive-robust and adaptive-observer "
        "are generated with friction compensation in the force they track (known or adapted coefficients, "
        "gains friction_*; a deviation from the paper)", default=False),
    Key("[figures]", "nonlinear", "", "the controller the figures and their table call \"nonlinear\"",
        default="adaptive-robust"),
)

#: Keys of a [variants.<name>] table besides the scenario fields it sets over every scenario run as
#: ``<scenario>.<variant>`` (a rig's timing, say).
VARIANT_KEYS = (
    Key("[variants.<name>]", "label", "", "what the variant changes, appended to each scenario's caption",
        default_text="the variant's name"),
    Key("[variants.<name>]", "gains", "", "gains.<controller> tables: this variant's tuning, over the scenario's",
        default=None, default_text="none"),
    Key("[variants.<name>]", "formerly", "", "the names the variant was known by: <scenario>.<old name> "
        "(and --variant <old name>) still runs it, with a note naming the new name", default=None,
        default_text="none"),
)

#: Keys of a [scenarios.<name>] table besides the scenario fields.
SCENARIO_TABLE_KEYS = (
    Key("[scenarios.<name>]", "reference", "m, rad, Hz, s", f"{references.syntax()}; coordinates by name or index, "
        "offsets from neutral"),
    Key("[scenarios.<name>]", "rig", "", "start from the model's [rig] table", default=False),
    Key("[scenarios.<name>]", "gains", "", "gains.<controller> tables: this scenario's tuning", default=None,
        default_text="none"),
    Key("[scenarios.<name>]", "label", "", "caption in figures and tables", default_text="the scenario's name"),
    Key("[scenarios.<name>]", "paper", "%", "published max errors {coordinate: [nonlinear, P]}", default=None,
        default_text="none"),
    Key("[scenarios.<name>]", "tuned", "", "false: a rig scenario the gain searches, margins and rig "
        "distributions leave out (one no gain is chosen for, e.g. a motion that asks more oil than the pump "
        "gives); it runs as any other", default=True),
    Key("[scenarios.<name>], [rig], [variants.<name>]", "actuators",
        "the actuator's own: N or N m, m or rad", f"actuators.<actuator> = {{ {', '.join(actuator_keys())} }}: "
        "those settings for one actuator, in its own unit (a cylinder's length in m and force in "
        "N, a rotary vane's angle in rad and torque in N m); merged per actuator over [rig]'s. A cylinder "
        "without them takes the scenario's; a rotary actuator's friction is none unless given, and it must give "
        "its own quantization_l and noise_l where the scenario's are on. friction is [Coulomb, viscous, tanh "
        "speed] or a seal friction table { coulomb, breakaway, stribeck_speed, viscous, pressure_coefficient, "
        "smooth_speed } (the description's [[cylinders]] friction keys), merged key by key over the "
        "actuator's description's; it may not ask for a seal term the actuator's plant is built without. "
        "valve = { bandwidth_hz, damping } is the spool's response for that actuator (Hz, second order with "
        "damping or where the response it replaces is one, else first order), over its datasheet valve's or "
        "the rig's, in any scenario (the rating stays the description's)",
        default=None, default_text="none"),
)

_TABLES = {}
for _k in DESCRIPTION_KEYS + SCENARIO_TABLE_KEYS + VARIANT_KEYS:
    _TABLES.setdefault(_k.table, {})[_k.key] = _k


def keys(table: str) -> set:
    """The key names a description table accepts (e.g. ``keys("[[links]]")``)."""
    return set(_TABLES[table])


def default(table: str, key: str):
    """The default of ``key`` in ``table`` (a copy for lists); :data:`REQUIRED` when it has none."""
    value = _TABLES[table][key].default
    return list(value) if isinstance(value, list) else value


def _toml(value) -> str:
    if value is REQUIRED:
        return "required"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _row(table, key, unit, default_text, meaning) -> str:
    cells = (f"`{table}`", f"`{key}`", unit or "–", default_text, meaning)
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def _actuator_rows() -> list:
    """The [[cylinders]] keys of each actuator kind but the paper's, from the kinds' own declarations
    (hydrogen/actuators/<kind>.py): ``kind`` itself, then each kind's parameters and travel."""
    from .actuators import KINDS, actuator

    rows = [_row("[[cylinders]], [hydraulics]", "kind", "", '"three_way_cylinder"',
                 f"the actuator: {', '.join(KINDS)} (one module each in hydrogen/actuators/)")]
    for kind in KINDS[1:] if KINDS[0] == "three_way_cylinder" else KINDS:
        mod = actuator(kind)
        table = f"[[cylinders]] kind = {kind}"
        travel = mod.TRAVEL
        key, unit, what, ends = travel.key, travel.unit, travel.doc, travel.ends
        if mod.MOTION == "revolute":
            rows.append(_row(table, "joint", "", "required", "the revolute joint it turns (no from/to)"))
        if travel.limited:  # unlimited travel (a motor) has no range to give
            rows.append(_row(table, key, unit, "required", what))
        for par in mod.PARAMETERS:
            if par.name not in ends:
                rows.append(_row(table, par.name, par.unit.replace("^2", "²").replace("^3", "³"),
                                 "required" if par.default is None else repr(par.default), par.doc))
    return rows


def description_table() -> str:
    """Markdown: every description key and scenario field with its unit, default and meaning."""
    from .scenario_settings import part_of, settings
    lines = ["| table | key | unit | default | meaning |", "|---|---|---|---|---|"]
    for k in DESCRIPTION_KEYS + SCENARIO_TABLE_KEYS + VARIANT_KEYS:
        shown = k.default_text or ("none" if k.default is None else _toml(k.default))
        lines.append(_row(k.table, k.key, k.unit, shown, k.meaning))
    lines += _actuator_rows()
    for f in settings():  # each scenario field's row from its own declaration (Scenario)
        meta = f.metadata
        shown = meta["default_text"] or ("required (here or in [rig])" if f.default is dataclasses.MISSING
                                         else _toml(f.default))
        lines.append(_row("[scenarios.<name>], [rig], [variants.<name>]", f.name, meta["unit"], shown,
                          f"*{part_of(f.name)}*: {meta['meaning']}"))  # grouped by the part that reads it
    return "\n".join(lines) + "\n"
