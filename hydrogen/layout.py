"""Sizes, names and signal layouts of a generated model, from its manifest (plain data).

The one template context: the loop driver and its header (codegen), the ctypes structures of the
loop runner (runtime) and the export bundle are all built from :func:`loop_context`, which reads
only the manifest's ``model`` summary (written by :func:`model_summary` at generation). Imports
neither SymPy, CasADi nor numpy.
"""
from __future__ import annotations

import math

from . import diagram  # the controller's input slots: the loop's ports
from . import references  # the reference kinds' part of the configuration and their C
from .estimators import ESTIMATORS, estimator, switch_field  # the estimators' state, numbers and C
from .loop_logs import FORCES, LOGS, PLANT, SIGNAL, STATE  # the run's logs
from .names import NUMBERS  # the numbers input's name, part of the loop's layout
from .plant import (BLOCKS as PLANT_BLOCKS, block as plant_block, input_record, integrator,  # the plant's blocks
                    plant_inputs)
from .plant.supply import PRESSURE as SUPPLY_PRESSURE  # the supply pressure's one name
from .sensors import NOISE, NoiseChannel, noise_columns, noise_width  # the sensors' noise row

__all__ = ["NUMBERS", "SUPPLY_LOG", "MAX_DELAY", "PLANT_INPUTS", "predictor_model", "FK_TOL", "FK_MAX_ITER", "FK_MAX_COND", "FK_STATUS", "LU_PIVOT_MIN",
           "delay_split", "LOOP_CONFIG", "LOOP_STATE", "LOOP_SIGNALS", "model_summary", "slots",
           "robot_sizes", "plant_ports", "plant_sensors", "signal_fields", "supply_size", "loop_context", "log_rows", "plant_outputs", "loop_functions", "C_SIZES", "plant_offsets",
           "plant_size", "c_double", "config_fields", "struct_fields"]

#: The plant part logged as it is, where the plant has it: the supply pressure (its one name,
#: hydrogen.plant.supply.PRESSURE).
SUPPLY_LOG = SUPPLY_PRESSURE


#: Longest computation delay the loop's command ring buffer holds, control periods (a scenario's
#: ``delay`` is refused above it). A real-time target applies a command one period after the
#: measurement it came from; 8 leaves room for slower targets and delay-margin studies.
MAX_DELAY = 8

#: Forward kinematics (Newton's method on the generated leg kinematics, templates/loop.c.j2; the loop's
#: estimate and :meth:`hydrogen.dynamics.Dynamics.forward_kinematics` alike): tolerance on the cylinder
#: lengths (m), Newton steps, and the largest condition number (1-norm) of JL a step is taken with.
FK_TOL, FK_MAX_ITER, FK_MAX_COND = 1e-12, 50, 1e8

#: Outcomes of the C forward kinematics, in the order of their codes (0, 1, ...): the loop header's
#: ``<MODEL>_FK_<OUTCOME>`` enum is rendered from it. The last is the loop's estimate only (forward
#: kinematics never returns it): JL singular at the measured pose in the velocity solve, where the pose
#: was measured (joint encoders) or solved.
FK_STATUS = ("solved", "singular", "not_converged", "function_failed", "velocity_singular")

#: The loop's LU factorisation of JL (templates/loop.c.j2 ``lu_n``; the Python stages alike): a pivot not
#: above this in magnitude makes JL singular.
LU_PIVOT_MIN = 1e-12

#: The plant's inputs of numbers its blocks declare (``INPUT``: friction, valve), in the plant's order:
#: each a field of the loop's configuration and of its model of the plant (``rhs_params``).
PLANT_INPUTS = tuple(plant_block(b).INPUT for b in PLANT_BLOCKS if getattr(plant_block(b), "INPUT", None))


def predictor_model(summary: dict) -> dict:
    """The controller's own model in the delay predictor, from a manifest's model summary: each plant
    input's ideal numbers of one actuator (:attr:`hydrogen.plant.PlantInput.ideal`: no friction, the
    ideal valve: no lag, no overlap, no saturation). The C loop's ``PRED_<INPUT>`` arrays are rendered
    from it; the Python stages use it as is."""
    return {i.name: i.ideal for i in plant_inputs(summary)}


def delay_split(delay: float, h: float) -> tuple:
    """A computation delay of ``delay`` s at control period ``h`` s as (whole periods d, fraction φ of a
    period, 0 ≤ φ < 1): the command computed at t_k is applied from t_k + (d + φ) h. A delay within 1e-9
    of a period boundary is that boundary (1/512 s at 512 Hz is one period, not 0.999...)."""
    r = float(delay) / float(h)
    d = math.floor(r + 1e-9)
    frac = r - d
    return d, (0.0 if frac < 1e-9 else frac)


#: The closed loop's configuration, described once: groups of (field, C type, exported name, source),
#: each group with its comment. The C struct of the loop header, the runtime's ctypes mirror, the
#: exported programs' params.h and their fill (``p_fill_config``, for main.c and the FMUs) are rendered
#: from it, and the runtime (:class:`hydrogen.runtime.loop.LoopRunner`) fills the struct from it. C
#: types: ``double``, ``long long``, ``const double*`` (an array the caller owns), ``double[<n>]`` (an
#: array of the struct's own: an estimator's numbers), ``fn`` (a generated function), ``double**``, ``long long int*``, ``double*`` (its tables and work), ``slots``
#: (``long long[N_SLOTS]``). The exported name is the params.h constant that holds the value; the source
#: says where the value comes from: ``scenario.<field>`` a field of the run's scenario as it is, ``run.<name>``
#: a value :mod:`hydrogen.simulation.loop_config` derives for the run (None, with no exported name: the
#: program sets it: the controller's tables). A rig setting that is a scenario field is its declaration
#: on :class:`hydrogen.simulation.scenarios.Scenario`, a row here and its use in loop.c and
#: :class:`hydrogen.simulation.simulator.PythonStages`.
_REFERENCE = references.config_fields()


def _estimator_fields() -> tuple:
    """Each estimator's part of the configuration (hydrogen.estimators): its switch, then its numbers."""
    out = []
    for name in ESTIMATORS:
        mod = estimator(name)
        out.append((switch_field(name), "long long", f"P_{switch_field(name).upper()}", f"run.{switch_field(name)}"))
        out += [(f.name, f.ctype, f.macro, f"run.{f.name}") for f in mod.CONFIG]
    return tuple(out)


#: The sensors' group's comment: the length sensor's, then each estimator's (its CONFIG_DOC), a line each
#: after the first.
_SENSORS_DOC = ("sensors: each actuator's travel resolution quant_l (m or rad, its own unit; 0: none; rounded to its "
                "grid\n * after the noise); sensor_res, sensor_bias: each rig part's sensor's resolution (its unit, 0:\n"
                " * none) and constant offset, the sensed outputs' entries in order"
                + "".join(("; " if i == 0 else ";\n * ") + estimator(name).CONFIG_DOC for i, name in enumerate(ESTIMATORS)))

LOOP_CONFIG = (
    ("timing: control period h (s), plant RK4 sub-steps per control period (bound_stages != 0: the pressures\n"
     " * held within their bounds at every stage, else after each step), adaptation on for t >= t_adapt;\n"
     " * the command computed at period k is applied from t_k + (delay + delay_frac) h (delay 0..MAX_DELAY,\n"
     " * 0 <= delay_frac < 1, delay + delay_frac <= MAX_DELAY)",
     (("h", "double", "P_H", "run.h"), ("substeps", "long long", "P_SUBSTEPS", "scenario.substeps"),
      ("bound_stages", "long long", "P_BOUND_STAGES", "run.bound_stages"),
      ("t_adapt", "double", "P_T_ADAPT", "scenario.t_adapt"),
      ("delay", "long long", "P_DELAY_PERIODS", "run.delay_periods"),
      ("delay_frac", "double", "P_DELAY_FRACTION", "run.delay_fraction"))),
    ("plant (SI): true theta ({p_theta}), gamma1 = beta and gamma2 = beta c per cylinder,\n"
     " * {plant_inputs}",
     (("theta", "const double*", "P_THETA", "run.theta"), ("gamma1", "const double*", "P_GAMMA1", "run.gamma1"),
      ("gamma2", "const double*", "P_GAMMA2", "run.gamma2"),
      # each block's input of numbers (hydrogen.plant.plant_inputs), from the run's scenario and model
      *((name, "const double*", f"P_{name.upper()}", f"run.{name}") for name in PLANT_INPUTS))),
    (_SENSORS_DOC,
     (("quant_l", "const double*", "P_QUANTIZATION_L", "run.quantization_l"),
      ("sensor_res", "const double*", "P_SENSOR_RESOLUTION", "run.sensor_resolution"),
      ("sensor_bias", "const double*", "P_SENSOR_BIAS", "run.sensor_bias"),
      *_estimator_fields())),  # each estimator's switch and numbers (hydrogen.estimators)
    # the reference kinds' fields (hydrogen.references), each read from the run
    (_REFERENCE[0], tuple((name, ctype, macro, f"run.{name}") for name, ctype, macro in _REFERENCE[1])),
    ("controller: generated function, its argument/result tables, work vectors",
     (("ctrl", "fn", None, None), ("ctrl_arg", "double**", None, None), ("ctrl_res", "double**", None, None),
      ("ctrl_iw", "long long int*", None, None), ("ctrl_w", "double*", None, None))),
    ("with a state (n_xc > 0): its semi-implicit step, one call per period: arguments ctrl_arg's then\n"
     " * h, xc_lo, xc_hi (step_arg); results u (step_res[0] must be ctrl_res[0]) and the updated state.\n"
     " * The forward-Euler update takes the rate from the controller's own call (ctrl_res[1]).\n"
     " * slot: the loop's input slots in the controller's inputs; n_xc: the state size; xc_lo, xc_hi: its\n"
     " * projection bounds; xc_euler: 0 semi-implicit update, 1 forward Euler after the plant step",
     (("step", "fn", None, None), ("step_arg", "double**", None, None), ("step_res", "double**", None, None),
      ("step_iw", "long long int*", None, None), ("step_w", "double*", None, None),
      ("slot", "slots", "P_CTRL_SLOT", "run.slot"), ("n_xc", "long long", "P_N_XC", "run.n_xc"),
      ("xc_lo", "const double*", "P_XC_LO", "run.xc_lo"), ("xc_hi", "const double*", "P_XC_HI", "run.xc_hi"),
      ("xc_euler", "long long", "P_XC_EULER", "run.xc_euler"))),
    ("delay compensation (predict != 0, a scenario's predictor with a delay): the controller's inputs are\n"
     " * the state at t_k + (delay + delay_frac) h predicted from the measured one by the plant's model at\n"
     " * the controller's own parameters (theta, gamma1, gamma2 from xc at pred_theta_at, pred_gamma1_at,\n"
     " * pred_gamma2_at where >= 0, else pred_theta, pred_gamma1, pred_gamma2), ideal valve, no friction,\n"
     " * over the commands in flight (RK4, pred_substeps steps per period), and the reference at that time;\n"
     " * pred_x0: the plant state it starts from where it measures nothing (each part's declared initial value)",
     (("predict", "long long", "P_PREDICT", "run.predict"),
      ("pred_substeps", "long long", "P_PRED_SUBSTEPS", "scenario.predictor_substeps"),
      ("pred_theta", "const double*", "P_PRED_THETA", "run.pred_theta"),
      ("pred_gamma1", "const double*", "P_PRED_GAMMA1", "run.pred_gamma1"),
      ("pred_gamma2", "const double*", "P_PRED_GAMMA2", "run.pred_gamma2"),
      ("pred_theta_at", "long long", "P_PRED_THETA_AT", "run.pred_theta_at"),
      ("pred_gamma1_at", "long long", "P_PRED_GAMMA1_AT", "run.pred_gamma1_at"),
      ("pred_gamma2_at", "long long", "P_PRED_GAMMA2_AT", "run.pred_gamma2_at"),
      ("pred_x0", "const double*", "P_PRED_X0", "run.pred_x0"))),
    ("the description's numbers: bounds of each pressure state (Pa), the clip of the measurement and of\n"
     " * the plant; numbers: the input of every generated function of a library generated with the\n"
     " * description's numbers as inputs (the manifest's \"numbers\" names them; else one unused 0)",
     (("p_low", "const double*", "P_PRESSURE_LOW", "run.pressure_low"),
      ("p_high", "const double*", "P_PRESSURE_HIGH", "run.pressure_high"),
      ("numbers", "const double*", "P_NUMBERS", "run.numbers"))),
    ("supply (a robot with a supply state): supply_feedback != 0: the controller's ps input is the measured\n"
     " * (or predicted) supply pressure; 0: ps_nominal (Pa), the description's supply_pressure (a controller\n"
     " * assuming a constant supply)",
     (("supply_feedback", "long long", "P_SUPPLY_FEEDBACK", "run.supply_feedback"),
      ("ps_nominal", "double", "P_PS_NOMINAL", "run.ps_nominal"))),
    ("forward kinematics (Newton): tolerance (m), steps, largest condition number (1-norm) of JL",
     (("fk_tol", "double", "P_FK_TOL", "run.fk_tol"), ("fk_max_iter", "long long", "P_FK_MAX_ITER", "run.fk_max_iter"),
      ("fk_max_cond", "double", "P_FK_MAX_COND", "run.fk_max_cond"))),
)


#: The loop's state between calls, described once: (field, C type, size, comment). Sizes are products
#: of the loop header's sizes (``NQ`` coordinates, ``NL`` cylinders, ``NX`` plant states, ``NPC``
#: pressure states, ``MAX_DELAY``) and numbers; None: a scalar. The header's struct and the runtime's
#: ctypes mirror are rendered from it.
LOOP_STATE = (
    ("t", "double", None, "s"),
    ("k", "long long", None, "control periods done"),
    ("x", "double", ("NX",), "plant: {x_parts}"),
    ("q_meas", "double", ("NQ",), "last measured pose (Newton's warm start)"),
    # each estimator's state (hydrogen.estimators)
    *((estimator(name).STATE.name, "double", estimator(name).STATE.size, estimator(name).STATE.doc)
      for name in ESTIMATORS),
    ("u_hist", "double", ("MAX_DELAY", "NL"), "commands of past periods: ring, slot k % MAX_DELAY (0 at reset)"),
    ("u_app", "double", ("NL",), "commands the valves held over the last period, m (0 at reset): the\n"
     " * controller's u_applied input in its state update"),
    ("xc", "double*", None, "controller state, n_xc entries"),
    ("fk_info", "double", (4,), "the last failed forward kinematics or velocity solve (written when it fails): outcome\n"
     " * (<MODEL>_FK_...), residual (m), JL's condition number (1-norm), Newton steps"),
    ("fk_l", "double", ("NL",), "the cylinder lengths (m) forward kinematics failed for (q_meas: its last iterate)"),
)

def _check_unique() -> None:
    """Every field of the loop's configuration and state, and every ``params.h`` macro, named once: a
    block's declared name (an estimator's state or numbers, a plant block's input) that clashes with
    the loop's own or another's would give the C struct two members of one name."""
    config = [f for _, fields in LOOP_CONFIG for f in fields]
    macros = [f[2] for f in config if f[2]]
    # the exported params.h's own names (its start state, timing, tables) and each estimator number's
    # design for the rig's sensors beside it
    macros += [*_params_h_names(), *(f"{f.macro}_SENSOR" for n in ESTIMATORS for f in estimator(n).CONFIG)]
    for what, names in (("configuration field", [f[0] for f in config]), ("params.h name", macros),
                        ("state field", [f[0] for f in LOOP_STATE])):
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ImportError(f"the loop's {what} {', '.join(map(repr, twice))} is declared twice: an estimator "
                              "(hydrogen.estimators) or a plant block (hydrogen.plant) takes a name the loop or "
                              "another block has")


def _params_h_names() -> list:
    """The names the exported ``params.h`` template defines itself (``P_L0``, ``P_DURATION``, ...),
    read off ``templates/export_params.h.j2`` (none where the templates are not installed)."""
    import re

    from .resources import templates_dir
    path = templates_dir() / "export_params.h.j2"
    text = path.read_text() if path.is_file() else ""
    return sorted(set(re.findall(r"(?:#define|static const [\w ]+?\*?(?: const)?) (P_[A-Z0-9_]+)\b", text)))


_check_unique()

#: One control period's signals as the loop's stages hand them on (measure → estimate → reference →
#: control → plant step), described once like :data:`LOOP_STATE`. A program that has its own sensors
#: (the controller FMU) fills the measured fields and calls the stages from estimate on.
LOOP_SIGNALS = (
    ("t", "double", None, "time of the period's start, s"),
    ("l_true", "double", ("NL",), "true cylinder lengths, m"),
    ("l_meas", "double", ("NL",), "measured cylinder lengths (noise, resolution), m"),
    ("pc_meas", "double", ("NPC",), "measured pressures, Pa"),
    ("ps_meas", "double", ("NPS",), "measured supply pressure, Pa (a [supply] state's only)"),
    ("q_enc", "double", ("NQE",), "joint encoders' reading, rad or m (joint encoders only)"),
    ("ldot", "double", ("NL",), "cylinder rates: the selected estimator's, or the ideal rate sensor's, m/s"),
    ("qdot_meas", "double", ("NQ",), "measured velocities, JL^-1 ldot at the measured pose"),
    ("qd", "double", (4, "NQ"), "reference and its first three time derivatives"),
    ("u", "double", ("NL",), "spool commands computed this period, m"),
    ("u_held", "double", ("NL",), "spool commands the valves hold over the period's first delay_frac h, m"),
    ("u_app", "double", ("NL",), "spool commands applied over the rest of the period (computation delay), m"),
)


def struct_fields(description, p: str, sizes: dict, x_parts: str = "") -> list:
    """A struct description (:data:`LOOP_STATE`, :data:`LOOP_SIGNALS`) for the templates and the
    ctypes mirrors: ``[{"name", "type", "decl", "length", "comment"}]`` (``length``: the number of
    entries for ``sizes``, which maps the header's size names to numbers; None for a scalar;
    ``x_parts``: the plant state's parts, named in its comment)."""
    from markupsafe import Markup  # hydrogen's own declaration text (hydrogen.templating)

    out = []
    for name, ctype, size, comment in description:
        if size is None:
            decl, length = f"{ctype} {name}", None
        else:
            c_size = " * ".join(str(t) if isinstance(t, int) else f"{p.upper()}_{t}" for t in size)
            decl, length = f"{ctype} {name}[{c_size}]", 1
            for t in size:
                length *= t if isinstance(t, int) else sizes[t]
            if not length:  # a part the robot lacks (a constant supply's p_s): not declared
                continue
        out.append({"name": name, "type": ctype, "decl": Markup(decl), "length": length,
                    "comment": Markup(comment.replace("{x_parts}", x_parts).replace("\n * ", "\n     * "))})
    return out


def _inputs_comment(summary: dict) -> str:
    """The plant inputs' part of the configuration's comment: each input's numbers per actuator with
    their units (a cylinder's, or a joint actuator's), from the blocks' declarations."""
    from .actuators.declarations import ANGLE, LENGTH

    def unit(par):
        a, b = par.unit_of(LENGTH), par.unit_of(ANGLE)
        return a if a == b else f"{a} or {b}"

    return ",\n * ".join(f"{i.name} per actuator" + (f" ({i.doc})" if i.doc else "") + ": ["
                          + ", ".join(f"{par.name} {unit(par)}".rstrip() for par in i.parameters) + "]"
                          for i in plant_inputs(summary))


def config_fields(p: str, summary: dict) -> list:
    """The configuration's groups for the templates: ``[{"comment": parts, "fields": [{"name", "type",
    "decl", "value", "source", "array"}]}]``, with C declarations for model prefix ``p``; ``summary``: the
    manifest's model summary (the plant inputs' numbers in the comment)."""
    def decl(name, ctype):
        if ctype == "fn":
            return f"{p}_casadi_fn {name}"
        if ctype == "slots":
            return f"long long {name}[{p.upper()}_N_SLOTS]"
        if ctype.startswith("double["):  # an array of its own: double name[size]
            return f"double {name}{ctype.removeprefix('double')}"
        return f"{ctype} {name}"

    from markupsafe import Markup  # hydrogen's own comment text: written as it is (hydrogen.templating)

    # the comment's parts around {p_theta}: the template writes the (escaped) parameter names between
    inputs = _inputs_comment(summary)
    return [{"comment": [Markup(part.replace("{plant_inputs}", inputs).replace("\n * ", "\n     * "))
                         for part in comment.split("{p_theta}")],
             "fields": [{"name": n, "type": t, "decl": Markup(decl(n, t)), "value": v, "source": src,
                         "array": t.startswith("double[") or t == "slots"}
        for n, t, v, src in fields]} for comment, fields in LOOP_CONFIG]


def c_double(x) -> str:
    """A C double literal that reads back to exactly ``x`` (shortest round-trip repr)."""
    return repr(float(x))


#: The model summary's entries the plant's blocks decide (:func:`model_summary`): the structure
#: hash leaves them out (the plant's own hash covers the code that decides them).
PLANT_SUMMARY = ("plant", "plant_inputs")


def model_summary(model) -> dict:
    """What the manifest records about the model for the drivers and the runtime: sizes, names and
    kinds, the loop's structure. No number of the description: the loop takes those from its
    configuration (pressure bounds) or through the generated functions (forces, flows)."""
    from .plant import plant_layout
    from .pressures import n_pressures
    return {
        "name": model.name,
        "n": model.n, "m": model.n_cylinders, "p": model.n_theta,
        "coordinates": list(model.coordinate_names),
        "cylinders": [c.name for c in model.cylinders],
        "theta_names": list(model.theta_names),
        "kinds": [c.kind for c in model.cylinders], "n_pressures": n_pressures(model),
        "joint_encoders": bool(model.joint_encoders),
        # the plant state's parts in order (hydrogen.plant): name, size (a robot size's name), offset, entries
        # (and, only where it has one, an output's sensor noise setting: a shipped manifest stays as it was)
        "plant": [{"name": s.name, "size": s.size_name, "start": s.start, "entries": s.size, "output": s.output,
                   **({"noise": s.noise} if s.noise else {}),
                   **({"resolution": s.resolution} if s.resolution else {}),
                   **({"bias": s.bias} if s.bias else {})} for s in plant_layout(model)],
        # recorded only when on: the plant's input friction is wider, a robot without keeps its manifest
        **({"seal_friction": True} if model.seal_friction else {}),
        # each block's plant input and the parameters it takes (its width, whatever structure decides it)
        "plant_inputs": input_record(model),
    }


#: The loop header's C name of each robot size a plant state's size is given in (hydrogen.plant.SIZES).
C_SIZES = {"n": "NQ", "m": "NL", "n_pressures": "NPC", "supply": "NPS"}


def plant_offsets(summary: dict) -> dict:
    """``{part: C expression of its offset in x}`` ("0", "NQ", "2 * NQ + NPC") from a manifest's
    model summary: the sizes of the parts before it, each robot size counted once, in order."""
    out, before = {}, {}
    for part in summary["plant"]:
        terms = [C_SIZES[k] if c == 1 else f"{c} * {C_SIZES[k]}" for k, c in before.items()]
        out[part["name"]] = " + ".join(terms) or "0"
        before[part["size"]] = before.get(part["size"], 0) + 1
    return out


def plant_size(summary: dict) -> int:
    """Number of entries of the plant state x, from a manifest's model summary."""
    return sum(part["entries"] for part in summary["plant"])


def robot_sizes(summary: dict) -> dict:
    """The robot's sizes by the loop header's names (``NQ``, ``NL``, ``NPC``, ``NPS``; ``NQE`` the joint
    encoders, NQ where fitted, else 0), from a manifest's model summary: what a port's size
    (:mod:`hydrogen.diagram`), a signal's and a log's are counted in."""
    return {"NQ": summary["n"], "NL": summary["m"], "NPC": summary["n_pressures"], "NPS": supply_size(summary),
            "NQE": summary["n"] if summary["joint_encoders"] else 0}


def signal_fields(summary: dict) -> tuple:
    """One period's signals of a model (a manifest's model summary): :data:`LOOP_SIGNALS`, then each
    rig part's sensor's reading ``<output>_meas`` (:func:`plant_sensors`); the loop header's struct,
    its ctypes mirror and the logs' sources read it."""
    return LOOP_SIGNALS + tuple((f"{ch.name}_meas", "double", (ch.size,), f"measured {ch.doc} (its sensor: noise "
                                 f"{ch.setting}), {ch.unit}") for ch in plant_sensors(summary))


def _output_text(name: str) -> tuple:
    """(block, unit, doc) of the plant's output ``name`` as its block declares it (its unit "per entry"
    where a rule gives each entry its own; ``name`` itself as the doc of a state no block declares)."""
    for b in PLANT_BLOCKS:
        for st in getattr(plant_block(b), "STATES", ()):
            if st.name == name:
                return b, st.unit if isinstance(st.unit, str) else "per entry", st.doc
    return "?", "per entry", name


def plant_sensors(summary: dict) -> tuple:
    """The sensors of the plant's outputs that declare a noise (:attr:`hydrogen.plant.PlantState.noise`),
    from a manifest's model summary: each a :class:`hydrogen.sensors.NoiseChannel` named as the output
    (its channel of the noise row after the loop's own; the signals' ``<name>_meas``, its reading)."""
    out = []
    for part in plant_outputs(summary):
        if part.get("noise"):
            _, unit, doc = _output_text(part["name"])
            out.append(NoiseChannel(part["name"], C_SIZES[part["size"]], part["noise"], unit, doc))
    return tuple(out)


def _sensor_starts(sensed) -> list:
    """Where each sensed output's numbers start in the configuration's ``sensor_res`` and ``sensor_bias``: a C
    expression of the loop header's sizes ("0", "NL", "NL + NL")."""
    out, at = [], []
    for ch in sensed:
        out.append(" + ".join(at) or "0")
        at.append(ch.size)
    return out


def plant_ports(summary: dict) -> tuple:
    """Each of the plant's outputs that is not one of the loop's own ports (the supply pressure is:
    measured, with its noise) as a port a controller may read, from a manifest's model summary: its
    sensor's reading at the period's start (its true value unless it declares a noise), or the
    predicted one with a delay predictor; named as the output, sized in the robot's sizes, its C value
    in the control stage (``xs``: the plant state it sees)."""
    taken = {p.name for p in diagram.CONTROLLER_PORTS}
    offsets = plant_offsets(summary)
    out = []
    for part in plant_outputs(summary):
        name = part["name"]
        owner, unit, what = _output_text(name)
        if name in taken:
            if name != SUPPLY_PRESSURE:  # the supply pressure's port is its measurement; no other may hide
                raise ImportError(f"plant block {owner!r} declares the output {name!r}, the name of one of the "
                                  f"loop's ports ({', '.join(sorted(taken))}): a controller could not read it")
            continue
        at = "xs" if offsets[name] == "0" else f"xs + {offsets[name]}"
        if part.get("noise"):  # its sensor's reading, or the prediction from it
            at, sensor = f"c->predict ? {at} : s->{name}_meas", f"its sensor's reading, noise {part['noise']}"
        else:
            sensor = "its true value, an ideal sensor"
        out.append(diagram.Port(name, (C_SIZES[part["size"]],), unit, f"the plant's {what} ({sensor})", at))
    return tuple(out)


def slots(summary: dict) -> tuple:
    """The loop's input slots of a model (a manifest's model summary): the controller ports it has
    (:func:`hydrogen.diagram.slots`; the measured supply pressure where its plant has a supply state;
    the plant's other outputs, :func:`plant_ports`)."""
    return diagram.slots(robot_sizes(summary), plant_ports(summary))


def supply_size(summary: dict) -> int:
    """Entries of the supply state (1 where the supply is not constant, else 0): the measured supply
    pressure's, last in a noise row."""
    return sum(part["entries"] for part in summary["plant"] if part["name"] == SUPPLY_LOG)


def n_pressures(summary: dict) -> int:
    """Size of the pressure vector."""
    return summary["n_pressures"]


def loop_functions(summary: dict) -> tuple:
    """The generated functions the loop driver calls (an export or FMU compiles them with it)."""
    return ("leg_lengths", "leg_kinematics", "plant_rhs", "leg_force")


def plant_outputs(summary: dict) -> list:
    """The plant state's parts that are the plant's outputs (hydrogen.plant.PlantState.output: the
    supply pressure where it is a state, ...), from a manifest's model summary: each part's record."""
    # a manifest written before parts declared it: the supply pressure, the one output then
    return [p for p in summary["plant"] if p.get("output", p["name"] == SUPPLY_LOG)]


def log_rows(summary: dict) -> list:
    """Each log of the loop (:data:`hydrogen.loop_logs.LOGS`, then the plant's outputs) for a model (a
    manifest's model summary), in the log struct's order: ``{"name", "width", "doc", "kind", "field",
    "c_pointer", "c_count", "c_row"}``: ``width`` the columns (the controller state's: None, its size is
    the controller's); ``kind`` and ``field`` its source (:class:`hydrogen.loop_logs.LogRow`);
    ``c_pointer`` the C loop's source of a row in ``write_log`` (none for the forces), ``c_count`` its
    entries in C, ``c_row`` row k's offset. A log of a size the robot lacks is left out."""
    from markupsafe import Markup  # hydrogen's own C expressions (hydrogen.templating)
    sizes = robot_sizes(summary)
    offsets = plant_offsets(summary)
    signals = {name: size for name, _, size, _ in signal_fields(summary)}

    def entries(size):
        return math.prod(t if isinstance(t, int) else sizes[t] for t in size)

    rows = [(r.name, r.size, f"{r.doc}, {r.unit}", r.source) for r in LOGS]
    rows += [(p["name"], (C_SIZES[p["size"]],), _output_text(p["name"])[2], (PLANT, p["name"]))
             for p in plant_outputs(summary)]
    # each rig part's sensor's reading (hydrogen.plant.PlantState.noise): the signal the controller reads
    rows += [(f"{ch.name}_meas", (ch.size,), f"measured {ch.doc}, {ch.unit}", (SIGNAL, f"{ch.name}_meas"))
             for ch in plant_sensors(summary)]
    out = []
    for name, size, doc, (kind, field) in rows:
        if kind == SIGNAL and field not in signals or kind == PLANT and field not in offsets:
            what, have = ("signal", signals) if kind == SIGNAL else ("plant part", offsets)
            raise ImportError(f"the log {name!r} (hydrogen.loop_logs) reads the {what} {field!r}, which the loop "
                              f"has not got (its {what}s: {', '.join(have)})")
        if kind == STATE and field not in {f[0] for f in LOOP_STATE}:
            raise ImportError(f"the log {name!r} (hydrogen.loop_logs) reads the loop state's field {field!r}, which "
                              f"it has not got (its fields: {', '.join(f[0] for f in LOOP_STATE)})")
        if "NXC" in size:
            width, count = None, "c->n_xc"
        else:
            width, count = entries(size), " * ".join(map(str, size))
            # a log of a size the robot lacks, or of a signal it lacks (the encoders' reading without encoders)
            if not width or kind == SIGNAL and signals[field] is not None and not entries(signals[field]):
                continue
        scalar = kind == SIGNAL and signals[field] is None
        pointer = {SIGNAL: f"{'&' if scalar else ''}s->{field}", FORCES: "",
                   PLANT: "x" + ("" if offsets.get(field) == "0" else f" + {offsets.get(field)}")
                   }.get(kind, f"st->{field}")
        # hydrogen's own text: written as it is in the header's comment, never closing it
        out.append({"name": name, "width": width, "doc": Markup(doc.replace("*/", "* /")), "kind": kind, "field": field,
                    "c_pointer": Markup(pointer), "c_count": Markup(count),
                    "c_row": Markup("k" if count == "1" else f"{count} * k")})
    return out


def _port_writes(summary: dict) -> list:
    """The control stage's writes of the controller's inputs a model has (a manifest's model summary):
    each port's slot, C value and count (the loop driver's size names; the controller state's, its
    configured size)."""
    from markupsafe import Markup  # hydrogen's own C expressions (hydrogen.templating)

    def count(port):
        return " * ".join("c->n_xc" if t == "NXC" else str(t) for t in port.size)
    return [{"slot": p.name.upper(), "value": Markup(p.c_value), "count": Markup(count(p))}
            for p in diagram.ports(robot_sizes(summary), plant_ports(summary))]


def _estimator_context() -> list:
    """Each estimator's C for the loop templates: its switch, comment, update and start statements."""
    from markupsafe import Markup  # hydrogen's own C (hydrogen.templating)
    return [{"name": name, "switch": switch_field(name), "comment": Markup(estimator(name).C_COMMENT),
             "c_update": Markup(estimator(name).C_UPDATE), "c_start": Markup(estimator(name).C_START),
             "state": estimator(name).STATE.name, "doc": estimator(name).DOC,
             "label": getattr(estimator(name), "LABEL", f"the {name} estimator"),
             "config": [{"name": f.name, "macro": f.macro, "size": f.size} for f in estimator(name).CONFIG]}
            for name in ESTIMATORS]


def _any_estimator() -> str:
    """The C condition, on the configuration ``c``, that an estimator gives the rates ("0": none is there)."""
    terms = [f"c->{switch_field(name)}" for name in ESTIMATORS]
    return terms[0] if len(terms) == 1 else f"({' || '.join(terms)})" if terms else "0"


def loop_context(manifest: dict) -> dict:
    """Everything the loop templates and the ctypes structures need, from a manifest."""
    s = manifest["model"]
    n, m, name = s["n"], s["m"], s["name"]
    n_p = n_pressures(s)
    log_list = log_rows(s)
    nx = plant_size(s)
    # each part of x as the C loop writes it: a pointer offset ("x + NQ") and an index prefix ("x[NQ + i]")
    from markupsafe import Markup  # hydrogen's own C expressions (hydrogen.templating)
    offsets = plant_offsets(s)
    x_plus = {k: Markup("" if v == "0" else f" + {v}") for k, v in offsets.items()}
    x_index = {k: Markup("" if v == "0" else f"{v} + ") for k, v in offsets.items()}
    x_parts = ", ".join(part["name"].replace("_", " ") for part in s["plant"])
    nps = supply_size(s)
    # the sensors' noise row (hydrogen.sensors.NOISE): each channel's columns
    sensed = plant_sensors(s)  # and a rig part's output's sensor, after them
    channels = {ch.name: ch for ch in (*NOISE, *sensed)}
    noise = [{"name": k, "start": start, "count": count, "doc": channels[k].doc, "unit": channels[k].unit}
             for k, (start, count) in noise_columns(robot_sizes(s), bool(s["joint_encoders"]), sensed).items()]
    sizes = {**robot_sizes(s), "NX": nx, "MAX_DELAY": MAX_DELAY}
    ctx = {
        "model": name, "p": name, "P": name.upper(), "guard": f"{name.upper()}_LOOP_H",
        "n": n, "m": m, "nx": nx, "max_delay": MAX_DELAY,
        "x_plus": x_plus, "x_index": x_index, "x_parts": x_parts,
        # the plant's outputs: logged (write_log), and the plant FMU's outputs besides q, qdot, pc, ps
        "plant_outputs": [{"name": p["name"], "count": p["entries"], "size": C_SIZES[p["size"]]}
                          for p in plant_outputs(s)],
        "n_noise": noise_width(robot_sizes(s), bool(s["joint_encoders"]), sensed), "noise": noise,
        "n_sensed": sum(int(robot_sizes(s)[ch.size]) for ch in sensed),  # the entries of sensor_res
        # each sensed output: its part of x, its count, where its numbers start in sensor_res and
        # sensor_bias (the measure stage's reading)
        "plant_sensors": [{"name": ch.name, "count": Markup(ch.size), "start": Markup(start)}
                          for ch, start in zip(sensed, _sensor_starts(sensed))],
        "noise_comment": ", ".join(f"{ch['doc']} ({ch['unit']})" for ch in noise),
        "n_pressures": n_p, "three_way": n_p == m,
        "nps": nps,
        "parametric": NUMBERS in manifest,
        "encoders": bool(s["joint_encoders"]), "slots": slots(s), "ports": _port_writes(s),
        # a plant output a controller may read (plant_ports): the control stage's plant state xs
        "plant_ports": [{"name": pp.name, "count": Markup(" * ".join(map(str, pp.size))),
                         "source": Markup(f"s->{pp.name}_meas" if pp.name in {ch.name for ch in sensed}
                                          else f"st->x{x_plus[pp.name]}")} for pp in plant_ports(s)],
        # the run's logs (hydrogen.loop_logs): the log struct's fields and write_log's rows
        "logs": [(r["name"], "n_xc" if r["width"] is None else r["width"], r["doc"]) for r in log_list],
        "log_rows": log_list,
        "config": config_fields(name, s),
        "state": struct_fields(LOOP_STATE, name, sizes, x_parts), "signals": struct_fields(signal_fields(s), name, sizes),
        "p_theta": ", ".join(s["theta_names"]),
        # each plant input (hydrogen.plant.plant_inputs): its numbers per actuator and the predictor's
        "plant_inputs": [{"name": i.name, "width": i.width, "pred": ", ".join(map(c_double, i.ideal * m))}
                         for i in plant_inputs(s)],
        "fk_status": FK_STATUS, "lu_pivot_min": c_double(LU_PIVOT_MIN),
        # each reference kind's statements of the loop's reference function (hydrogen's own C)
        "reference_bodies": [Markup(body) for body in references.c_bodies()],
        # each estimator's statements of the estimate stage behind its switch (hydrogen's own C), and
        # the C expression of "an estimator gives the rates" (else the measure stage's ideal rate sensor)
        "estimators": _estimator_context(),
        "estimated": Markup(_any_estimator()),
        # the plant's integration (hydrogen's own C): RK4 holding each command, the pressures held within
        # their bounds, the sub-steps shared out around a command switch, the predictor's step count
        "integrator_functions": Markup(integrator.c_functions(x_index["pc"])),
        "integrator_period": Markup(integrator.C_PERIOD.substitute(failed=f"{name.upper()}_CTRL_FAILED")),
        "predictor_steps": Markup(integrator.C_PREDICTOR_STEPS),
    }
    return ctx
