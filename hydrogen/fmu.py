"""FMI 2.0 co-simulation FMUs of the plant, a controller, or the whole closed loop.

:func:`export_fmu` writes one ``.fmu`` (a zip: ``modelDescription.xml``, ``sources/``,
``binaries/linux64/<modelIdentifier>.so`` and ``documentation/``) from the same generated C, the
same rendered loop driver and the same export context (:func:`hydrogen.export.export_context`, rendered
into ``sources/params.h``) as the C export. The FMU glue (``templates/fmu_glue.c.j2``) calls the loop
driver's stages (``<model>_loop.h``) one control period per call:

* **plant**: the plant stage ``<model>_plant_step`` holding the FMU input ``u``; RK4 sub-steps and
  pressure limits are the loop's own.
* **controller**: the stages from estimation on, on the measured inputs: ``<model>_estimate``
  (the scenario's estimator of the rates, such as the Kalman filter on the cylinder lengths, forward
  kinematics or joint encoders, velocities through JL), ``<model>_reference`` (or the q_d inputs), ``<model>_control`` and ``<model>_control_advance``.
  The lengths pass the length sensor's resolution (``<model>_sense_lengths``). Without an estimator
  (the ideal cylinder-rate sensor of the simulation scenarios) the measured cylinder rates are an
  input as well.
* **closed-loop**: the whole loop (``<model>_loop_run``), reproducing
  ``hydrogen.simulate(..., **scenario.noise_free())`` (every sensor's noise off).

So plant FMU + controller FMU (controller stepped first, then the plant, each over the same
period) is the closed loop, to rounding. The FMI headers come from fmpy's installed copy
(``fmpy/c-code``) at export time and are copied into ``sources/``; none is kept in this repository.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import re
import shutil
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from .controllers import ESTIMATE_BLOCKS
from .controllers.common import estimate_layout, theta_units as _theta_units
from .errors import CompilerError, FmuError, OutputPathError
from .layout import NUMBERS, SUPPLY_LOG
from .model import POSITIVE  # FMI's min is inclusive: "> 0" is min = the smallest positive double
from .plant import input_values, outputs as plant_outputs, plant_inputs, plant_layout, slot as plant_slot
from .plant.supply import PRESSURE as SUPPLY_PRESSURE, ceiling as supply_ceiling

__all__ = ["export_fmu", "PARTS", "fmi_headers_dir", "FMI_HEADERS"]

#: The parts an FMU can hold.
PARTS = ("plant", "controller", "closed-loop")
#: FMI 2.0 headers the glue includes, taken from fmpy's installed copy.
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
PLATFORM = "linux64"
#: A communication step may differ from a whole number of control periods by this fraction of one.
STEP_TOL = 1e-6
#: Fixed zip timestamp: the same export gives the same bytes.
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)

#: Units by name: SI base-unit exponents (FMI 2.0 BaseUnit attributes). gamma2 = beta c has
#: sqrt(Pa) in it: declared by name only (FMI exponents are integers).
UNITS = {
    "m": {"m": 1}, "rad": {"rad": 1}, "m/s": {"m": 1, "s": -1}, "rad/s": {"rad": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2}, "rad/s2": {"rad": 1, "s": -2}, "m/s3": {"m": 1, "s": -3},
    "rad/s3": {"rad": 1, "s": -3}, "Pa": {"kg": 1, "m": -1, "s": -2}, "N": {"kg": 1, "m": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1}, "N.m": {"kg": 1, "m": 2, "s": -2}, "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}, "s": {"s": 1}, "kg": {"kg": 1}, "kg.m": {"kg": 1, "m": 1},
    "kg.m2": {"kg": 1, "m": 2}, "m2.Pa0.5/s": None,
}
#: Plant parameters (inputs of plant_rhs besides x and u): per-entry names, units and what they are.
def _input_entries(inp, model) -> list:
    """The entries of plant input ``inp`` (:class:`hydrogen.plant.PlantInput`) of ``model``, actuator after
    actuator, each parameter in that actuator's own unit (its kind's TRAVEL)."""
    return [(_dotted(inp.name, c.name, par.name), par.unit_of(c.travel).replace(" ", "."),
             f"{par.doc} of actuator {c.name}") for c in model.cylinders for par in inp.parameters]


_REF_ORDERS = (("qd0", "q_d", "", "reference"), ("qd1", "q_d_dot", "/s", "reference velocity"),
               ("qd2", "q_d_ddot", "/s2", "reference acceleration"), ("qd3", "q_d_dddot", "/s3", "reference jerk"))


@dataclass
class Variable:
    name: str
    kind: str            # "p" parameter, "i" input, "o" output
    variability: str     # fixed, continuous, discrete
    description: str
    c_loc: str           # C lvalue of the value inside the instance
    ctype: str = "r"     # "r" Real, "b" Boolean
    unit: str | None = None
    start: object = None  # a float or bool (parameters and inputs), None for outputs
    vr: int = -1
    lo: float | None = None  # declared min and max (inclusive; None: unbounded); every Real must be finite
    hi: float | None = None

    @property
    def causality(self) -> str:
        return {"p": "parameter", "i": "input", "o": "output"}[self.kind]

    @property
    def c_min(self) -> str:
        return "-HUGE_VAL" if self.lo is None else c_double(self.lo)

    @property
    def c_max(self) -> str:
        return "HUGE_VAL" if self.hi is None else c_double(self.hi)

    @property
    def c_start(self):
        if self.start is None:
            return None
        if self.ctype == "b":
            return "fmi2True" if self.start else "fmi2False"
        return c_double(self.start)


def c_double(x) -> str:
    from .export import c_double as c_double
    return c_double(x)


def _what(c) -> str:
    """What actuator ``c`` is called in a variable's description: a cylinder (its coordinate a
    length), else an actuator (a joint actuator's angle)."""
    return "cylinder" if c.travel.quantity == "length" else "actuator"


def _c_limit(x) -> str:
    """An end of an actuator's travel range as C: a double literal, or ±INFINITY (math.h) for an
    actuator of unlimited travel, whose range then holds every value."""
    x = float(x)
    if np.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return c_double(x)


def _name_part(s: str) -> str:
    """One part of a structured FMI name: an identifier as is, anything else quoted."""
    import re
    if re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", s):
        return s
    return "'" + s.replace("\\", "\\\\").replace("'", "\\'") + "'"


def _pressure_states(model) -> list:
    """(variable prefix, (cylinder, what it is, what is measured)) of each pressure state, in the
    pressure vector's order: ``pc`` for a three-way cylinder (its control pressure), the kind's
    state names (``pA``, ``pB``) for another."""
    from .actuators import actuator
    out = []
    for c in model.cylinders:
        for st in actuator(c.kind).STATES:
            if c.kind == "three_way_cylinder":
                out.append(("pc", (c.name, "control (cap-side) chamber pressure", "control pressure")))
            else:
                out.append((st.name, (c.name, st.doc, st.doc)))
    return out


def _dotted(*parts) -> str:
    """A structured name from parts; a part may itself be dotted (link.parameter)."""
    out = []
    for p in parts:
        out += [_name_part(x) for x in str(p).split(".")]
    return ".".join(out)


def fmi_headers_dir() -> Path:
    """fmpy's installed copy of the FMI headers (``fmpy/c-code``), checked."""
    try:
        import fmpy
    except ImportError:
        raise FmuError("the FMU export takes the FMI 2.0 headers from fmpy, which is not installed: "
                       "pip install 'hydrogen[fmu]' (or pip install fmpy)") from None
    folder = Path(fmpy.__file__).parent / "c-code"
    missing = [h for h in FMI_HEADERS if not (folder / h).is_file()]
    if missing:
        raise FmuError(f"fmpy {getattr(fmpy, '__version__', '?')} at {folder} lacks the FMI headers {missing}; "
                       "reinstall fmpy")
    return folder


def _check_platform():
    if not (sys.platform.startswith("linux") and platform.machine().lower() in ("x86_64", "amd64")):
        raise FmuError(f"the FMU export builds binaries/{PLATFORM} only; this is {sys.platform} {platform.machine()}")


def _written_by_hydrogen(path: Path) -> bool:
    """Whether ``path`` is a regular file (not a link), an FMU whose model description names hydrogen
    as its generation tool: an earlier export, which a new one may replace. Only the description's
    first 4 kB are inflated; anything unreadable is not hydrogen's."""
    if path.is_symlink() or not path.is_file():
        return False
    try:
        with zipfile.ZipFile(path) as zf, zf.open("modelDescription.xml") as f:
            head = f.read(4096).decode("utf-8", "replace")
    except Exception:  # a damaged or foreign archive (zlib, EOF, format errors alike): never replaced
        return False
    return re.search(r'generationTool="hydrogen[ "]', head) is not None


def _check_out(out: Path) -> Path:
    from .outputs import check_output_file

    if out.suffix.lower() != ".fmu":
        raise OutputPathError(f"export --out {out}: an FMU file name ends with .fmu")
    out = check_output_file(out, "export --out")  # a folder or a non-file there is named as such
    if out.is_symlink() or (out.exists() and not _written_by_hydrogen(out)):
        raise OutputPathError(f"export --out {out}: already exists and is no FMU hydrogen wrote (a link is never "
                              "followed); nothing was written. Remove it or give a new file name")
    return out


def _periods(step, h) -> int:
    """The whole number of control periods in a communication step, or FmuError."""
    step = float(step)
    n = int(np.floor(step / h + 0.5)) if np.isfinite(step) and step > 0 else 0
    if n < 1 or abs(step - n * h) > STEP_TOL * h:
        raise FmuError(f"communication step {step!r} s is not a whole number of control periods of {h!r} s "
                       f"(the FMU advances whole periods: use n * {h!r} s)")
    return n


def _fmi_unit(unit: str):
    """A plant part's unit as an FMU variable's (None: dimensionless); spaces as FMI's dots."""
    return unit.replace(" ", ".") or None


def _has_supply(layout) -> bool:
    """Whether the plant has a supply state (a pump: its pressure is an output)."""
    return any(b.name == SUPPLY_LOG for b in layout)


def _coord_units(model):
    return list(model.coordinate_units)


def _part_range(part, j: int) -> dict:
    """The ``lo``/``hi`` of entry ``j`` of a plant part (a :class:`hydrogen.plant.Slot`): its declared
    range, None where unbounded."""
    lo, hi = part.lower[j], part.upper[j]
    return {"lo": float(lo) if np.isfinite(lo) else None, "hi": float(hi) if np.isfinite(hi) else None}


def _variables(part, dyn, p, ctx, fn, encoders, estimated):
    """The FMU's variables, in value-reference order, with their C locations in the instance."""
    model, sc, ctrl = dyn.model, p.sc, p.ctrl
    n, m = model.n, model.n_cylinders
    coords, cyls, cunits = list(model.coordinate_names), [c.name for c in model.cylinders], _coord_units(model)
    travels = [c.travel for c in model.cylinders]  # each actuator's coordinate and unit: its kind's TRAVEL
    pstates = _pressure_states(model)
    layout = plant_layout(model)
    x0_q, x0_pc = (p.x0[plant_slot(layout, k).slice] for k in ("q", "pc"))  # the start state's parts
    out = []

    def add(*a, **k):
        out.append(Variable(*a, **k))

    def add_array(a):
        for j, (nm, unit, what) in enumerate(a["entries"]):
            lo, hi = a["ranges"][j]
            add(nm, "p", "fixed", what, f"inst->{a['field']}[{j}]", unit=unit, start=a["values"][j], lo=lo, hi=hi)

    if part == "plant":
        for i, c in enumerate(cyls):
            add(_dotted("u", c), "i", "continuous", f"spool command of cylinder {c} (held over each period)",
                f"inst->u_in[{i}]", unit="m", start=0.0)
        for a in _plant_arrays(dyn, p):
            add_array(a)
        for i, c in enumerate(coords):
            add(_dotted("q_start", c), "p", "fixed", f"initial {c} (the scenario's)", f"inst->q_start[{i}]",
                unit=cunits[i], start=float(x0_q[i]))
        p_lo, p_hi = plant_slot(layout, "pc").lower, plant_slot(layout, "pc").upper
        for j, (nm, what) in enumerate(pstates):
            add(_dotted(f"{nm}_start", what[0]), "p", "fixed", f"initial {what[2]} of cylinder {what[0]} (holding "
                "the robot still at the start pose)", f"inst->pc_start[{j}]", unit="Pa", start=float(x0_pc[j]),
                lo=float(p_lo[j]), hi=float(p_hi[j]))
        if _has_supply(layout):  # from its lower bound to the highest the plant holds it to (the relief's)
            ps = plant_slot(layout, SUPPLY_LOG)
            add("ps_start", "p", "fixed", f"initial supply pressure ({model.supply.kind} of [supply]; the "
                "actuators' supply_pressure)", "inst->ps_start", unit="Pa", start=float(p.x0[ps.slice][0]),
                lo=float(ps.lower[0]), hi=float(supply_ceiling(model)))
        others = [b for b in plant_outputs(layout) if b.name != SUPPLY_LOG]  # a rig part's outputs
        for b in others:
            for j, e in enumerate(b.entries):
                add(_dotted(f"{b.name}_start", e), "p", "fixed", f"initial {b.doc} of {e}", f"inst->{b.name}_start[{j}]",
                    unit=_fmi_unit(b.units[j]), start=float(p.x0[b.slice][j]), **_part_range(b, j))
        for i, c in enumerate(coords):
            add(_dotted("q", c), "o", "continuous", f"coordinate {c}", f"inst->y_q[{i}]", unit=cunits[i])
        for i, c in enumerate(coords):
            add(_dotted("qdot", c), "o", "continuous", f"rate of {c}", f"inst->y_qdot[{i}]", unit=cunits[i] + "/s")
        for i, c in enumerate(cyls):
            add(_dotted("l", c), "o", "continuous", f"{travels[i].quantity} of {_what(model.cylinders[i])} {c}",
                f"inst->y_l[{i}]", unit=travels[i].unit)
        for i, c in enumerate(cyls):
            add(_dotted("ldot", c), "o", "continuous", f"rate of {_what(model.cylinders[i])} {c} (JL qdot)",
                f"inst->y_ldot[{i}]", unit=travels[i].rate_unit())
        for j, (nm, what) in enumerate(pstates):
            note = "; the rod side is at supply pressure" if nm == "pc" else ""
            add(_dotted(nm, what[0]), "o", "continuous", f"{what[1]} of cylinder {what[0]}{note}",
                f"inst->y_pc[{j}]", unit="Pa")
        if _has_supply(layout):
            add(SUPPLY_PRESSURE, "o", "continuous", f"supply pressure ({model.supply.kind} of [supply])", "inst->y_ps", unit="Pa")
        for b in others:
            for j, e in enumerate(b.entries):
                add(_dotted(b.name, e), "o", "continuous", f"{b.doc} of {e}", f"inst->y_{b.name}[{j}]",
                    unit=_fmi_unit(b.units[j]))
        return out, []

    # offsets of the controller's C arguments in ctrl_in (the export's table: the numbers too)
    offsets = np.cumsum([0] + [e["size"] for e in ctx["inputs"]]).tolist()
    at = {e["name"]: e["index"] for e in ctx["inputs"]}
    if part == "controller":
        l0 = dyn.leg_lengths(p.q0)
        for i, c in enumerate(cyls):
            add(_dotted("l", c), "i", "continuous", f"measured {travels[i].quantity} of {_what(model.cylinders[i])} "
                f"{c}", f"inst->l_in[{i}]", unit=travels[i].unit, start=float(l0[i]))
        for j, (nm, what) in enumerate(pstates):
            add(_dotted(nm, what[0]), "i", "continuous", f"measured {what[2]} of cylinder {what[0]}",
                f"inst->pc_in[{j}]", unit="Pa", start=float(x0_pc[j]))
        if _has_supply(layout):
            add(SUPPLY_PRESSURE, "i", "continuous", "measured supply pressure", "inst->ps_in", unit="Pa",
                start=float(p.x0[plant_slot(layout, SUPPLY_LOG).slice][0]))
        if encoders:
            for i, c in enumerate(coords):
                add(_dotted("q", c), "i", "continuous", f"joint encoder reading of {c}", f"inst->q_in[{i}]",
                    unit=cunits[i], start=float(p.q0[i]))
        if not estimated:
            for i, c in enumerate(cyls):
                add(_dotted("ldot", c), "i", "continuous", f"measured rate of {_what(model.cylinders[i])} {c} (the "
                    "scenario's ideal rate sensor: no estimator)", f"inst->ldot_in[{i}]",
                    unit=travels[i].rate_unit(), start=0.0)
        read = {o["name"] for o in ctx["read_outputs"]}  # a rig part's state the controller reads: an input
        for b in plant_outputs(layout):
            if b.name in read:
                for j, e in enumerate(b.entries):
                    read_how = " through its sensor's bias and resolution, applied here" if b.noise else ""
                    add(_dotted(b.name, e), "i", "continuous",
                        f"{b.doc} of {e}, true (the controller reads it{read_how})",
                        f"inst->{b.name}_in[{j}]", unit=_fmi_unit(b.units[j]), start=float(p.x0[b.slice][j]),
                        **_part_range(b, j))
        ref0 = sc.reference(0.0)
        for k, (slot, base, suffix, what) in enumerate(_REF_ORDERS):
            if slot not in fn.in_names:
                continue
            for i, c in enumerate(coords):
                add(_dotted(base, c), "i", "continuous", f"{what} of {c} (used when use_builtin_reference is false)",
                    f"inst->qd_in[{k * n + i}]", unit=cunits[i] + suffix, start=float(ref0[k][i]))
        add("use_builtin_reference", "p", "fixed", f"true: the scenario's reference ({sc.name}), computed inside; "
            "false: the q_d inputs", "inst->builtin_ref", ctype="b", start=True)
        for e in ctx["inputs"]:
            # unread (e.g. a lean controller's composite gains): no parameter; shared (the description's
            # numbers): the plant arrays' parameters, which the controller reads too
            if e["dynamic"] or e["unread"] or e["shared"]:
                continue
            off, rows, cols = offsets[e["index"]], e["rows"], e["cols"]
            value = np.reshape(np.asarray(ctrl.values[e["name"]], float), (rows, cols))
            for j in range(cols):
                for i in range(rows):
                    if rows * cols == 1:
                        nm, where = _name_part(e["name"]), ""
                    elif cols == 1:
                        nm, where = f"{_name_part(e['name'])}[{i + 1}]", f", entry {i + 1} of {rows}"
                    else:
                        nm = f"{_name_part(e['name'])}[{i + 1},{j + 1}]"
                        where = f", entry ({i + 1}, {j + 1}) of {rows}x{cols}"
                    lo, hi = _controller_input_range(e["name"], model, i + rows * j)
                    add(nm, "p", "fixed", f"controller {fn.name} input {e['name']}{where} (SI)",
                        f"inst->ctrl_in[{off + i + rows * j}]", start=float(value[i, j]), lo=lo, hi=hi)

    for a in _plant_arrays(dyn, p):  # the model's numbers: of the controller's model (and the plant's)
        if a["name"] == NUMBERS:
            add_array(a)
    # outputs of the controller and the closed loop
    if part == "closed-loop":
        for i, c in enumerate(coords):
            add(_dotted("q", c), "o", "discrete", f"coordinate {c} at the start of the period", f"inst->q_row[{i}]",
                unit=cunits[i])
        if "qd0" not in fn.in_names:
            raise FmuError(f"controller {fn.name} takes no reference qd0: the closed-loop FMU has no q_d to output")
        for i, c in enumerate(coords):
            add(_dotted("q_d", c), "o", "discrete", f"reference of {c}",
                f"inst->ctrl_in[{offsets[at['qd0']] + i}]", unit=cunits[i])
        if _has_supply(layout):
            add(SUPPLY_PRESSURE, "o", "discrete", f"supply pressure at the start of the period ({model.supply.kind} of "
                "[supply])", "inst->ps_row", unit="Pa")
    if fn.out_names[0] != "u":
        raise FmuError(f"controller {fn.name}'s first output is {fn.out_names[0]!r}, not the command u")
    for i, c in enumerate(cyls):
        add(_dotted("u", c), "o", "discrete", f"spool command of cylinder {c} for the period", f"inst->ctrl_out[{i}]",
            unit="m")
    xc_name = "xc_row" if part == "closed-loop" else "xc"
    # every block of the controller's state as it declares it (entry names, units); the parameter
    # estimates a controller does not adapt too, as the constants its own model holds
    held = {b.name: b for b in ctrl.layout}
    estimates = {b.name: b for b in estimate_layout(model)}
    fixed = dict(zip(ESTIMATE_BLOCKS, (p.theta0, p.gamma0[0], p.gamma0[1])))
    const = []
    for block in [held.get(b, estimates[b]) for b in ESTIMATE_BLOCKS] + [b for b in ctrl.layout
                                                                        if b.name not in ESTIMATE_BLOCKS]:
        sl = ctrl.slices.get(block.name)
        for i, (nm, unit) in enumerate(zip(block.entry_names(model), block.units(model))):
            if sl is not None:
                loc, desc = f"inst->{xc_name}[{sl.start + i}]", f"{block.role}: {nm.strip('[]')}"
            else:
                loc, desc = f"inst->est_const[{len(const)}]", f"{block.role}: {nm} (not adapted by this controller)"
                const.append(float(np.atleast_1d(fixed[block.name])[i]))
            name = f"{_name_part(block.name)}{nm}" if nm.startswith("[") else _dotted(block.name, nm)
            add(name, "o", "discrete", desc, loc, unit=unit)
    return out, const


def _number_variable(name: str) -> str:
    """The FMU variable of the description's number ``name`` (``link.mass``, ``joint.origin_xyz[0]``):
    ``numbers.<name>`` with an entry of an array as FMI writes it, 1-based (``origin_xyz[1]``)."""
    import re

    parts = []
    for part in name.split("."):
        m = re.match(r"^([A-Za-z_][A-Za-z0-9_]*)\[(\d+)\]$", part)
        parts.append(f"{m.group(1)}[{int(m.group(2)) + 1}]" if m else _name_part(part))
    return ".".join([NUMBERS, *parts])


def _plant_arrays(dyn, p):
    """One array per input of plant_rhs besides x and u: name, loop-config field, entries, values."""
    from .export import number_ranges
    model, sc = dyn.model, p.sc
    cyls = [c.name for c in model.cylinders]
    fn = dyn.functions["plant_rhs"]
    theta_units = _theta_units(model)
    known = {
        "theta": (model.theta, [(_dotted("theta", t), u, f"inertial parameter {t} (true value)")
                                for t, u in zip(model.theta_names, theta_units)]),
        "gamma1": (model.gamma[0], [(_dotted("gamma1", c), "Pa", f"beta (oil bulk modulus) of cylinder {c}")
                                    for c in cyls]),
        "gamma2": (model.gamma[1], [(_dotted("gamma2", c), "m2.Pa0.5/s", f"beta c (bulk modulus times valve flow "
                                     f"gain) of cylinder {c}") for c in cyls]),
    }
    values = input_values(sc, model)  # each block's input of numbers (friction, valve): its own rule
    known.update({i.name: (values[i.name].ravel(), _input_entries(i, model)) for i in plant_inputs(model)})
    ranges = _plant_ranges(model, sc)
    out = []
    for name, shape in zip(fn.in_names, fn.in_shapes):
        if name in ("x", "u"):
            continue
        size = int(shape[0]) * int(shape[1])
        if name not in known:
            raise FmuError(f"the plant takes an input '{name}' the FMU export does not know; extend hydrogen/fmu.py")
        values, entries = known[name]
        values = np.asarray(values, float).ravel(order="F")
        if values.size != size or len(entries) != size:
            raise FmuError(f"plant input '{name}' holds {size} numbers, the export has {values.size}")
        out.append({"name": name, "field": f"plant_{name}", "size": size, "entries": entries,
                    "values": [float(v) for v in values], "data": ", ".join(c_double(v) for v in values),
                    "ranges": ranges[name]})
    numbers = dyn.library.numbers
    if numbers is not None:  # the description's numbers, inputs of every generated function: by name
        names = dyn.library.manifest[NUMBERS]
        out.append({"name": NUMBERS, "field": f"plant_{NUMBERS}", "size": len(names),
                    # the variable's array index is FMI's, 1-based; the description's (and params.h's) 0-based
                    "entries": [(_number_variable(k), None, f"the description's number {k} (SI; FMI index from 1)"
                                 if "[" in k else f"the description's number {k} (SI)") for k in names],
                    "values": [float(v) for v in numbers], "data": ", ".join(c_double(v) for v in numbers),
                    "ranges": number_ranges(model, names)})
    return out


def _plant_ranges(model, sc) -> dict:
    """Per plant input, per entry, the (min, max) a value may take (None: unbounded), from the model and
    the scenario's own rules: the true theta and gamma inside the model's projection bounds (the model
    requires it, Lemma 1), friction and valve as the scenario checks them (the natural frequency no
    higher than the RK4 sub-steps resolve)."""
    m = model.n_cylinders
    return {
        "theta": [(float(a), float(b)) for a, b in zip(model.theta_min, model.theta_max)],
        "gamma1": [(float(model.gamma1_min), float(model.gamma1_max))] * m,
        "gamma2": [(float(model.gamma2_min), float(model.gamma2_max))] * m,
        # each plant input's parameters as their block declares them (the valve's natural frequency no
        # higher than the RK4 sub-steps resolve)
        **{i.name: [(_above(par.lower) if par.strict else par.lower, par.upper_of(sc)) for par in i.parameters] * m
           for i in plant_inputs(model)},
    }


def _above(lower):
    """FMI's (inclusive) min of a value that must exceed ``lower``: the next double up (None: none)."""
    return None if lower is None else float(np.nextafter(float(lower), np.inf))


def _controller_input_range(name: str, model, i: int):
    """(min, max) of entry ``i`` of a static controller input: the known true values (a controller
    without adaptation) inside the model's bounds, the gamma projection bounds and the references
    that scale the adaptation > 0 (Remark 3: gamma_2 > 0), each gain as the simulator checks it
    (>= 0, or > 0 for divisors and limits); the theta projection bounds only finite."""
    from .simulation.checks import gain_must_be_positive

    if name == "theta":
        return float(model.theta_min[i]), float(model.theta_max[i])
    if name in ("gamma1", "gamma2"):
        return float(getattr(model, f"{name}_min")), float(getattr(model, f"{name}_max"))
    if name in ("theta_min", "theta_max"):
        return None, None
    if name in ("gamma1_min", "gamma1_max", "gamma2_min", "gamma2_max", "gamma_ref", "theta_ref",
                "theta_row_scale"):
        return POSITIVE, None
    return (POSITIVE if gain_must_be_positive(name) else 0.0), None


def _model_description(ident, part, model_name, sc, controller, guid, variables, h, step, stop, sources, version,
                       doc):
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": f"{model_name} {part}", "guid": guid, "description": doc,
        "author": "hydrogen", "generationTool": f"hydrogen {version}", "variableNamingConvention": "structured",
        "numberOfEventIndicators": "0"})
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": ident, "needsExecutionTool": "false", "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "false", "maxOutputDerivativeOrder": "0", "canRunAsynchronuously": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "false",
        "canGetAndSetFMUstate": "false", "canSerializeFMUstate": "false", "providesDirectionalDerivative": "false"})
    files = ET.SubElement(cs, "SourceFiles")
    for s in sources:
        ET.SubElement(files, "File", {"name": s})
    used = sorted({v.unit for v in variables if v.unit})
    if used:
        units = ET.SubElement(root, "UnitDefinitions")
        for u in used:
            el = ET.SubElement(units, "Unit", {"name": u})
            if UNITS.get(u) is not None:  # a unit FMI exponents cannot spell (or a block's own): by name
                ET.SubElement(el, "BaseUnit", {k: str(e) for k, e in UNITS[u].items()})
    cats = ET.SubElement(root, "LogCategories")
    ET.SubElement(cats, "Category", {"name": "logStatusError", "description": "refused calls and failed steps"})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stopTime": repr(float(stop)),
                                              "stepSize": repr(float(step))})
    mv = ET.SubElement(root, "ModelVariables")
    for v in variables:
        attrs = {"name": v.name, "valueReference": str(v.vr), "description": v.description,
                 "causality": v.causality, "variability": v.variability}
        if v.kind == "p":
            attrs["initial"] = "exact"
        sv = ET.SubElement(mv, "ScalarVariable", attrs)
        t = {}
        if v.unit:
            t["unit"] = v.unit
        if v.lo is not None:
            t["min"] = repr(float(v.lo))
        if v.hi is not None:
            t["max"] = repr(float(v.hi))
        if v.start is not None:
            t["start"] = ("true" if v.start else "false") if v.ctype == "b" else repr(float(v.start))
        ET.SubElement(sv, "Real" if v.ctype == "r" else "Boolean", t)
    ms = ET.SubElement(root, "ModelStructure")
    outs = [i + 1 for i, v in enumerate(variables) if v.kind == "o"]
    if outs:
        o = ET.SubElement(ms, "Outputs")
        for i in outs:  # no direct feedthrough: an output after a step depends on inputs sampled before it
            ET.SubElement(o, "Unknown", {"index": str(i), "dependencies": ""})
        iu = ET.SubElement(ms, "InitialUnknowns")
        for i in outs:
            ET.SubElement(iu, "Unknown", {"index": str(i)})
    ET.indent(root, "  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _numbers_vr0(variables, ctx):
    """The value reference of the first of the description's numbers (they follow one another, in
    params.h's order), or None without them."""
    vrs = [v.vr for v in variables if v.c_loc.startswith(f"inst->plant_{NUMBERS}[")]
    if not vrs:
        return None
    if vrs != list(range(vrs[0], vrs[0] + len(ctx["numbers"]))):
        raise FmuError("the FMU's variables of the description's numbers are not params.h's, in order")
    return vrs[0]


def _guid(payload: dict) -> str:
    h = hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()
    return "{" + f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}" + "}"


def _compile(sources: dict, c_files, ident, toolchain, cache=None) -> bytes:
    """Compile ``c_files`` of ``sources`` (name -> bytes) into ``<ident>.so`` with hydrogen's toolchain
    (warnings as errors), in a scratch folder (the binary does not depend on where). The generated
    sources every export of the robot shares (its functions, the loop driver) are compiled once into
    the object store of the build cache ``cache`` (default :func:`~hydrogen.runtime.compiler.cache_root`),
    keyed by their bytes, headers and flags: exporting again (another part, scenario or gain) compiles
    only the glue and what changed. The glue (``c_files[0]``, its GUID and params.h new with every
    export's settings) is compiled for this export alone."""
    from .errors import CompilerError
    from .fileio import write_file
    from .runtime.compiler import Toolchain, compile_objects, link_shared, object_store

    tc = toolchain or Toolchain()
    # every header is included with "..." from the scratch folder: no search path needed, so the
    # objects can be stored (a -I flag would keep them out of the store)
    argv = [*tc.argv(), "-fvisibility=hidden"]
    store = object_store(cache)
    with tempfile.TemporaryDirectory(prefix="hydrogen-fmu-") as tmp:
        for name, data in sources.items():
            write_file(Path(tmp) / name, data)
        paths = [Path(tmp) / c for c in c_files]
        try:
            glue = compile_objects(paths[:1], Path(tmp), argv, tc.timeout, identity=tc.identity())
            shared = compile_objects(paths[1:], Path(tmp) / "shared", argv, tc.timeout, store=store,
                                     identity=tc.identity())
            lib = Path(tmp) / f"{ident}.so"
            link_shared(paths, [*glue, *shared], lib, argv, tc.timeout, store=store, identity=tc.identity(),
                        link_flags=("-Wl,-Bsymbolic",), cwd=tmp)
        except CompilerError as exc:  # name each source as the FMU holds it, not by the scratch folder
            raise CompilerError(str(exc).replace(f"{tmp}/", "sources/")) from None
        return lib.read_bytes()


_DOC = """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{title}</title></head>
<body>
<h1>{title}</h1>
<p>FMI 2.0 co-simulation FMU exported by hydrogen {version}: model <b>{model}</b>, scenario <b>{scenario}</b>{ctrl}.
Control period {h} s ({substeps} RK4 plant sub-steps per period). Binaries: {platform}; the C sources in
<code>sources/</code> rebuild it (in <code>sources/</code>:
<code>cc -std=c99 -O2 -fPIC -shared -fvisibility=hidden -I. *.c -o {ident}.so -lm</code>).</p>
<h2>What is inside</h2>
<p>{inside}</p>
<h2>Rules</h2>
<ul>
<li>The communication step must be a whole number of control periods ({h} s); any other step makes
fmi2DoStep return fmi2Error with a logged message, and nothing is done.</li>
<li>Parameters are fixed: set them before fmi2ExitInitializationMode.{start}</li>
<li>A Real parameter or input must be a finite number inside its declared min and max (the model's bounds
and the scenario's rules); fmi2SetReal refuses any other value with fmi2Error and a logged message naming
the variable and its range, and sets nothing (outputs keep their last values). The description's numbers
(<code>numbers.*</code>) have the description's own ranges. fmi2ExitInitializationMode checks them all
again{pose}, and that the numbers keep the order between a cylinder's constants (the rod's annulus area no
larger than the cap area, tank below supply pressure, ...), naming both.</li>
<li>With a stop time given to fmi2SetupExperiment (stopTimeDefined), a step that would end after it is
refused with fmi2Error, and nothing is done.</li>
<li>Controller + plant: step the controller first (inputs: the plant's outputs at t), then hand its u to the
plant and step the plant over the same interval. That order reproduces the closed loop.</li>
</ul>
<h2>Variables</h2>
<table border="1" cellpadding="3">
<tr><th>name</th><th>causality</th><th>unit</th><th>start</th><th>description</th></tr>
{rows}
</table>
<p>The FMI 2.0 headers in <code>sources/</code> are copied from fmpy {fmpy_version} (fmpy/c-code), Modelica Association,
2-Clause BSD license.</p>
</body></html>
"""

_INSIDE = {
    "plant": "The hydraulic robot: rigid-body dynamics, cylinders, valves, friction, integrated with the "
             "closed-loop driver's RK4 sub-steps; input the spool commands u (held over each period); outputs the "
             "coordinates and their rates, cylinder lengths and rates, control pressures.",
    "controller": "The controller with the loop's sensor path: inputs the measured cylinder lengths and "
                  "pressures{extra}; inside, the scenario's estimator of the rates (when it has one), {pose}, "
                  "velocities through JL, the reference (built in, or the q_d inputs), the controller and its "
                  "adaptation. u after a step is the command computed from the inputs sampled at the start of "
                  "that step.",
    "closed-loop": "The whole closed loop of the scenario (sensors, controller, plant), noise-free: it "
                   "reproduces hydrogen.simulate(..., noise_l=0, noise_p=0) with every other sensor's noise off "
                   "too (Scenario.noise_free()). Outputs at t = k h are the "
                   "simulator's log row k.",
}


def export_fmu(out, part, scenario=None, controller="adaptive-robust", model=None, duration=None, *,
               step=None, dyn=None, gains=None, generated=None, check_workspace=True, toolchain=None,
               numbers=None, progress=None, **overrides) -> Path:
    """Write an FMI 2.0 co-simulation FMU of ``part`` (``"plant"``, ``"controller"`` or ``"closed-loop"``).

    Parameters
    ----------
    out : path
        The ``.fmu`` file to write: a new file, or an FMU an earlier export of hydrogen's wrote
        (replaced whole; any other file there is refused and kept).
    part : str
        One of :data:`PARTS`.
    scenario, controller, model, duration, gains, numbers, progress, overrides
        As for :func:`hydrogen.export.export`: the scenario gives the control period, sub-steps, start
        values, reference and plant settings (noise is off: the FMU is noise-free). ``duration`` sets the
        DefaultExperiment stop time. The plant part ignores the controller.
    step : float, optional
        DefaultExperiment step size, s: a whole number of control periods (default: one period).
    dyn : Dynamics, optional
        Compiled dynamics to export from (default ``hydrogen.build(model)``).
    toolchain : hydrogen.runtime.compiler.Toolchain, optional
        Compiler and flags (default: ``$CC`` or cc, hydrogen's flags, warnings as errors).

    Returns
    -------
    Path of the written FMU.
    """
    from . import __version__
    from .layout import loop_functions
    from .export import (controller_entries, export_context, prepare_export, read_sources,
                         render_template)
    from .names import check_identifier

    if part not in PARTS:
        raise FmuError(f"unknown FMU part {part!r}: choose one of {', '.join(PARTS)}")
    out = _check_out(Path(out).absolute())
    _check_platform()
    headers_dir = fmi_headers_dir()
    dyn, sc, sc_name, p = prepare_export(model, dyn, scenario, controller, gains, duration, check_workspace,
                                         overrides, numbers, progress)
    overrides = dict(overrides)
    h = p.h
    n_step = _periods(h if step is None else step, h)

    model, mname = dyn.model, dyn.model.name
    manifest = dyn.library.manifest
    entries = {e["name"]: e for e in manifest["functions"]}
    ctrl_entries = controller_entries(manifest, p.ctrl)
    ctrl_entry = ctrl_entries[0]
    funcs = [entries[n] for n in loop_functions(manifest["model"])] + (ctrl_entries if part != "plant" else [])
    driver = f"{mname}_loop.c"
    if driver not in manifest.get("drivers", []):
        raise FmuError(f"export: the compiled dynamics have no loop driver {driver}; rebuild")
    gen_sources = [e["source"] for e in funcs] + [driver]
    gen_headers = [e["header"] for e in funcs] + [f"{mname}_loop.h"]
    files = read_sources(dyn, gen_sources + gen_headers, generated)

    ctx = export_context(dyn, p, sc_name, controller, f"{mname}_fmu", gen_sources, gen_headers, ctrl_entry["header"])
    params_h = render_template("export_params.h.j2", ctx).encode()

    encoders, estimated = bool(model.joint_encoders), p.estimate is not None  # else the rates are inputs
    fn = p.ctrl.fn
    variables, est_const = _variables(part, dyn, p, ctx, fn, encoders, estimated)
    names = [v.name for v in variables]
    dup = sorted({x for x in names if names.count(x) > 1})
    if dup:
        raise FmuError(f"FMU variable names {dup} are not unique")
    for i, v in enumerate(variables):
        v.vr = i
        if v.ctype == "r" and v.start is not None and not ((v.lo is None or v.start >= v.lo)
                                                          and (v.hi is None or v.start <= v.hi)):
            raise FmuError(f"FMU variable {v.name}: its start value {v.start!r} is outside its range "
                           f"[{v.lo}, {v.hi}] (from the model and the scenario)")

    ctrl_ident = controller.replace("-", "_")
    ident = f"{mname}_plant" if part == "plant" else f"{mname}_{ctrl_ident}_{part.replace('-', '_')}"
    check_identifier(ident, "FMU model identifier")
    header_bytes = {hname: (headers_dir / hname).read_bytes() for hname in FMI_HEADERS}
    guid = _guid({"part": part, "ident": ident, "params_h": hashlib.sha256(params_h).hexdigest(),
                  "files": {k: hashlib.sha256(v).hexdigest() for k, v in sorted(files.items())},
                  "headers": {k: hashlib.sha256(v).hexdigest() for k, v in sorted(header_bytes.items())},
                  "variables": [(v.name, v.kind, v.c_loc, v.start) for v in variables], "version": __version__})
    glue = render_template("fmu_glue.c.j2", dict(
        ctx, part=part, guid=guid, variables=variables, plant_arrays=_plant_arrays(dyn, p),
        est_const_size=len(est_const), est_const=", ".join(c_double(v) for v in est_const),
        encoders=encoders, estimated=estimated, numbers_vr0=_numbers_vr0(variables, ctx),
        stroke_min=", ".join(_c_limit(v) for v in model.leg_min),
        stroke_max=", ".join(_c_limit(v) for v in model.leg_max),
        travel_units=[c.travel.unit for c in model.cylinders],
        travel_words=[c.travel.range_word for c in model.cylinders],
        length_vrs=", ".join(str(v.vr) for v in variables if v.kind == "o" and v.c_loc.startswith("inst->y_l["))
        )).encode()

    src = {**{n: files[n] for n in gen_sources + gen_headers}, "params.h": params_h, "fmu.c": glue, **header_bytes}
    c_files = ["fmu.c", *gen_sources]
    binary = _compile(src, c_files, ident, toolchain, dyn.library.cache_root)

    stop = (p.n - 1) * h
    doc_line = {"plant": f"plant of {mname} (scenario {sc_name})",
                "controller": f"controller {controller} of {mname} with its sensor path (scenario {sc_name})",
                "closed-loop": f"closed loop of {mname}: {controller} on {sc_name}"}[part]
    md = _model_description(ident, part, mname, sc, controller, guid, variables, h, n_step * h, stop, c_files,
                            __version__, doc_line)
    import fmpy

    inside = _INSIDE[part].format(
        extra=(", the joint encoders" if encoders else "") + ("" if estimated else ", the cylinder rates"),
        pose="the joint encoders' pose" if encoders else "forward kinematics (Newton, warm-started)")
    rows = "\n".join(
        f"<tr><td>{_html(v.name)}</td><td>{v.causality}</td><td>{_html(v.unit or '')}</td>"
        f"<td>{'' if v.start is None else _html(str(v.start))}</td><td>{_html(v.description)}</td></tr>"
        for v in variables)
    doc = _DOC.format(title=_html(f"{mname} {part}"), version=__version__, ident=ident, model=mname,
                      scenario=_html(sc_name),
                      ctrl="" if part == "plant" else f", controller <b>{controller}</b>", h=repr(h),
                      substeps=sc.substeps, platform=PLATFORM, inside=inside, rows=rows,
                      start="" if part == "plant" else " The start time must be 0 (the reference is the scenario's).",
                      pose=", and that q_start puts every cylinder inside its stroke" if part == "plant" else "",
                      fmpy_version=getattr(fmpy, "__version__", "?"))

    entries_zip = {"modelDescription.xml": md, f"binaries/{PLATFORM}/{ident}.so": binary,
                   "documentation/index.html": doc.encode()}
    for name, data in src.items():
        entries_zip[f"sources/{name}"] = data
    return _write_zip(out, entries_zip)


def _html(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _write_zip(out: Path, entries: dict) -> Path:
    """The zip, written beside ``out`` and moved into place: over an FMU hydrogen wrote (checked again
    just before), else only where ``out`` still does not exist."""
    from .fileio import writing

    out.parent.mkdir(parents=True, exist_ok=True)
    with writing(out):
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    os.close(fd)
    try:
        with writing(out), zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
            for name in sorted(entries):
                info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = (0o755 if name.endswith(".so") else 0o644) << 16
                info.create_system = 3
                zf.writestr(info, entries[name])
        os.chmod(tmp, 0o644)
        if _written_by_hydrogen(out):  # an earlier export of hydrogen's (checked again now): replaced whole
            os.replace(tmp, out)
            return out
        try:
            os.link(tmp, out)  # fails if out appeared meanwhile: no other file is overwritten
        except FileExistsError:
            raise OutputPathError(f"export --out {out}: already exists; nothing was written") from None
        except OSError:
            if out.exists():
                raise OutputPathError(f"export --out {out}: already exists; nothing was written") from None
            shutil.move(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out
