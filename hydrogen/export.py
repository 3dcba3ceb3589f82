"""Export one scenario and controller as a self-contained C99 program for a real-time target.

:func:`export` writes a folder holding copies of the generated C the closed
loop needs (inverse kinematics, leg Jacobian, plant, the chosen controller and
the loop driver rendered from ``templates/loop.*.j2``), a ``params.h`` with every
number of the run (controller gains and bounds in the controller's manifest
input order, matrices column-major; plant parameters; reference; timing;
the estimator's numbers; initial states), a ``main.c`` that runs the whole scenario with
the same C loop :func:`hydrogen.simulate` drives through ctypes, a
``Makefile``, a ``CMakeLists.txt``, a ``README.txt`` and an ``export.json``.

The exported program runs without sensor noise (noise is a simulator
feature): its tracking errors equal those of
``hydrogen.simulate(scenario, controller, **scenario.noise_free())`` to
rounding, because both call ``<model>_loop_run`` from the same sources with the
same numbers. In particular the estimator's numbers the program uses (the Kalman
gain) are the ones the simulator designs for the noise-free scenario; ``params.h``
also carries those designed for the scenario's sensor noise
(``P_<NUMBERS>_SENSOR``, selected by compiling with ``-DHG_SENSOR_<NUMBERS>``:
``-DHG_SENSOR_KF_GAIN`` for the Kalman gain) for use on the rig.

The folder is rendered into a hidden sibling and swapped in whole
(:func:`hydrogen.fileio.replace_dir`), so it is never half-written.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import tempfile
import textwrap
from pathlib import Path

import numpy as np

from .errors import HydrogenError, OutputPathError
from .diagram import SLOTS  # the loop's own ports: a plant output among them is measured
from .layout import NUMBERS, loop_functions
from .simulation.checks import MIN_WINDOW_SAMPLES  # the metric window's rule, which the program repeats

__all__ = ["export", "EXPORT_MANIFEST", "TEMPLATE_NAMES", "export_context", "render_template", "read_sources", "resolve_dyn",
           "sensor_estimate", "c_double", "c_doubles", "prepare_export", "controller_entries",
           "check_export_dir", "make_products"]

#: Metadata file written into every export folder (also marks a folder as an export).
EXPORT_MANIFEST = "export.json"
#: Keys of export.json that mark a folder as an earlier export (which may be replaced whole).
EXPORT_KEYS = ("program", "model_hash", "files")


def make_products(meta: dict) -> set:
    """What the export's own Makefile builds in the folder (``make clean`` removes exactly these): an
    earlier export holding them may be replaced. Anything else not in export.json is the user's."""
    files = meta.get("files") if isinstance(meta.get("files"), dict) else {}
    prog = meta.get("program")
    return {n[:-2] + ".o" for n in files if n.endswith(".c")} | ({prog} if isinstance(prog, str) else set())


def check_export_dir(out: Path, probe: bool = True) -> Path:
    """``out`` is new, empty, or an earlier export holding only its own files (unedited) and make's
    products; anything else is refused naming the files, before anything is written."""
    from .outputs import check_replaceable_dir
    return check_replaceable_dir(out, EXPORT_MANIFEST, EXPORT_KEYS, "an earlier hydrogen export", "export --out",
                                 probe=probe, products=make_products, hashes=True)


#: Templates (in the repository's templates/) rendered into the folder: template -> output name.
TEMPLATE_NAMES = {"export_params.h.j2": "params.h", "export_main.c.j2": "main.c",
                  "Makefile.j2": "Makefile", "CMakeLists.txt.j2": "CMakeLists.txt"}
#: Generated functions the loop driver calls (besides the controller).
LOOP_FUNCTIONS = ("leg_lengths", "leg_kinematics", "plant_rhs")  # a three-way robot's; see layout.loop_functions

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def c_double(x) -> str:
    """A C double literal that reads back to exactly ``x`` (shortest round-trip repr)."""
    x = float(x)
    if not np.isfinite(x):
        raise HydrogenError(f"export: cannot write the non-finite value {x} into params.h")
    return repr(x)


def c_doubles(a) -> str:
    """Comma-separated C double literals of ``a`` flattened column-major (CasADi's dense layout)."""
    flat = np.asarray(a, dtype=float)
    flat = flat.ravel(order="F") if flat.ndim > 1 else flat.ravel()
    return ", ".join(c_double(v) for v in flat)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def resolve_dyn(model, dyn, numbers=None, controller=None, progress=None):
    """The compiled dynamics to export: ``dyn``, or those of ``model`` (default robot when both are
    None) built with ``numbers`` (:func:`hydrogen.build`'s) for ``controller`` (a new structure
    derives that one alone), reporting to ``progress``; a ``model`` that differs from ``dyn``'s raises
    a ModelError (a ValueError)."""
    from .runtime.build import dynamics_for

    return dynamics_for("export", model, dyn, numbers=numbers, controller=controller, progress=progress)


def _candidate_folders(dyn, generated):
    """Generated folders that may hold the sources ``dyn`` was compiled from, most likely first."""
    from .runtime.build import generated_dir_for

    if generated is not None:
        return [Path(generated)]
    model = dyn.model
    mode = "constants" if dyn.library.numbers is None else "inputs"
    out = []
    lib_path = Path(dyn.library.path)
    if len(lib_path.parents) >= 3:  # <cache>/build/<key>/lib….so: the cache this library was built in
        out.append(generated_dir_for(model, lib_path.parents[2], mode))
    out.append(generated_dir_for(model, numbers=mode))
    seen, uniq = set(), []
    for f in out:
        if f not in seen:
            seen.add(f)
            uniq.append(f)
    return uniq


def read_sources(dyn, names, generated) -> dict:
    """Bytes of the generated files ``names``, exactly as the loaded library was compiled from them.

    Each file is checked against the SHA-256 the library's manifest recorded, so
    the export never mixes sources of another generation.
    """
    from contextlib import nullcontext

    from .fileio import recover_dir
    from .runtime import cachedir
    from .runtime.build import repo_generated_dir

    committed = (repo_generated_dir() / dyn.model.name).resolve()
    recorded = dyn.library.manifest.get("files", {})
    missing = [n for n in names if n not in recorded]
    if missing:
        raise HydrogenError(f"export: the compiled dynamics' manifest lists no {missing}; rebuild")
    tried = []
    for folder in _candidate_folders(dyn, generated):
        if not folder.is_dir():
            tried.append(f"{folder}: missing")
            continue
        # A cache folder is swapped by the generator under its lock; the committed one is only read
        # (the recorded hashes catch a file that changed): no lock, so no lock file in the checkout.
        mine = folder.resolve() != committed
        with cachedir.folder_lock(folder, current=True) if mine else nullcontext():
            if mine:
                recover_dir(folder)
            data, bad = {}, []
            for n in names:
                p = folder / n
                b = p.read_bytes() if p.is_file() else None
                if b is None or _sha256(b) != recorded[n]:
                    bad.append(n)
                else:
                    data[n] = b
        if not bad:
            return data
        tried.append(f"{folder}: {', '.join(bad)} differ from what the library was compiled from")
    raise HydrogenError("export: cannot find the generated sources of the loaded dynamics ("
                        + "; ".join(tried) + "). Rebuild with hydrogen.build() or pass generated=<folder>.")


def controller_entries(manifest: dict, ctrl) -> list:
    """Manifest entries of the generated functions the C loop calls: the controller, then, when it
    has a state, its semi-implicit step (the loop's state update; the forward-Euler update takes
    the rate from the controller's own call)."""
    entries = {e["name"]: e for e in manifest["functions"]}
    names = [ctrl.fn.name] + ([ctrl.step_fn.name] if ctrl.step_fn is not None else [])
    missing = [n for n in names if n not in entries]
    if missing:
        raise HydrogenError(f"export: the compiled dynamics' manifest lists no {missing}; rebuild")
    return [entries[n] for n in names]


def render_template(template: str, ctx: dict) -> str:
    """``template`` rendered with ``ctx`` through hydrogen's one escaping environment (:mod:`hydrogen.templating`)."""
    from .codegen.generate import TEMPLATES
    from .templating import render

    return render(template, ctx, TEMPLATES)


def _xc_blocks(ctrl, model) -> list:
    """The blocks of the controller's state as it declares them: name, C macro part, where it starts in
    xc, size, role, and its unit where it declares one unit for every entry (else the entries' units)."""
    out = []
    for block in ctrl.layout:
        units = [u for u in dict.fromkeys(block.units(model)) if u]
        out.append({"name": block.name, "macro": block.name.upper(), "start": ctrl.slices[block.name].start,
                    "size": block.size, "role": block.role, "unit": ", ".join(units)})
    return out


def _sensor_config(p) -> list:
    """Each estimator's numbers as the rig's sensors would have them (its design for the scenario with its
    noise, ``p.sensor_estimate``; zeros for an estimator the run does not use): params.h's
    ``P_<NUMBERS>_SENSOR``, which ``-DHG_SENSOR_<NUMBERS>`` fills the loop with."""
    from .estimators import ESTIMATORS, estimator
    est = p.sensor_estimate
    out = []
    for name in ESTIMATORS:
        values = est.config() if est is not None and est.name == name else {}
        for f in estimator(name).CONFIG:
            out.append({"name": f.name, "macro": f"{f.macro}_SENSOR", "guard": f"HG_SENSOR_{f.name.upper()}",
                        "size": f.size, "numbers": c_doubles(values.get(f.name, np.zeros(f.size)))})
    return out


def _estimator_settings(sc) -> str:
    """The selected estimator's own scenario settings with their values, for params.h's comment."""
    from .estimators import estimator, selected
    name = selected(sc)
    if name is None:
        return ""
    decl = estimator(name).SCENARIO_SETTINGS
    from markupsafe import Markup  # a C comment's text: ASCII, no "*/", written as it is

    def unit(text):  # m²/s³ as m^2/s^3 (another sign: no unit)
        text = text.replace("²", "^2").replace("³", "^3")
        return f" {text}" if text and text.isascii() else ""
    text = "".join(f"; {k} {getattr(sc, k)!r}{unit(d.metadata['unit'])}"
                   for k, d in decl.items() if k != getattr(estimator(name), "SWITCH", None))
    return Markup(text) if text.isascii() and "*/" not in text else text


def export_context(dyn, p, scenario_name, controller, prog, sources, headers, ctrl_header):
    """Everything the templates need, numbers already formatted as C literals."""
    from .layout import loop_context
    from .simulation.loop_config import Run, config_values

    model, sc, ctrl = dyn.model, p.sc, p.ctrl
    loop = loop_context(dyn.library.manifest)
    fn = ctrl.fn
    inputs = []
    shapes = dict(zip(fn.in_names, fn.in_shapes))
    for i, name in enumerate(fn.arg_names):  # the C argument table: the description's numbers too
        if not _IDENT.match(name):
            raise HydrogenError(f"export: controller input '{name}' is not a C identifier")
        shape = shapes.get(name, (len(dyn.library.numbers), 1) if name == NUMBERS else None)
        size = int(shape[0]) * int(shape[1])
        dynamic = name in loop["slots"]
        entry = {"index": i, "name": name, "rows": int(shape[0]), "cols": int(shape[1]), "size": size,
                 "dynamic": dynamic, "c_name": f"P_CTRL_{name}", "unread": name in getattr(fn, "unread_inputs", ()),
                 "shared": False}
        if name == NUMBERS:  # the loop configuration's P_NUMBERS: one definition for every function
            entry.update(c_name="P_NUMBERS", shared=True)
        elif not dynamic:
            if name not in ctrl.values:
                raise HydrogenError(f"export: controller '{controller}' input '{name}' has no value")
            value = np.reshape(np.asarray(ctrl.values[name], dtype=float), shape)
            entry["data"] = c_doubles(value)
        inputs.append(entry)
    # with a state: the semi-implicit step (the controller's inputs, h and the bounds), argument by name
    step = (controller_entries(dyn.library.manifest, ctrl)[1:] + [None])[0]
    own = {"h": "step_h", "xc_lo": "step_lo", "xc_hi": "step_hi"}
    step_args = [own.get(n) or f"ctrl_arg[{fn.arg_names.index(n)}]" for n, _, _ in step["inputs"]] if step else []
    n_xc = int(ctrl.xc.size)
    ref = sc.reference
    values = config_values(Run(dyn, sc, ctrl, p.h, p.estimate))
    return {
        "model": model.name, "P": model.name.upper(), "scenario": scenario_name, "controller": controller,
        "prog": prog, "sources": sources, "headers": headers, "ctrl_header": ctrl_header,
        "ctrl_c_name": fn.c_name, "loop_header": f"{model.name}_loop.h",
        "step_c_name": step["c_name"] if step else None, "step_header": step["header"] if step else None,
        "step_args": step_args,
        "n_periods": int(p.n), "duration": c_double(sc.duration), "control_rate": c_double(sc.control_rate),
        "metric_start": c_double(sc.metric_start), "min_window_samples": MIN_WINDOW_SAMPLES,
        "n": loop["n"], "m": loop["m"], "nx": loop["nx"], "three_way": loop["three_way"],
        "x_plus": loop["x_plus"], "x_index": loop["x_index"], "x_parts": loop["x_parts"],  # the plant state's parts
        "plant_outputs": loop["plant_outputs"],  # the plant's outputs (hydrogen.plant.PlantState.output)
        # the plant's outputs the controller reads by name (hydrogen.layout.plant_ports): the controller
        # FMU's inputs of them
        "read_outputs": [{**o, "sensed": o["name"] in {ch["name"] for ch in loop["plant_sensors"]}}
                         for o in loop["plant_outputs"] if o["name"] in fn.in_names and o["name"] not in SLOTS],
        "parametric": loop["parametric"], "lu_pivot_min": loop["lu_pivot_min"],  # the FMU's failure words
        "estimators": loop["estimators"],  # each estimator's state and its start in C
        "theta_names": ", ".join(model.theta_names),
        # the rig's design of the estimators' numbers, which -DHG_SENSOR_<NUMBERS> fills the loop with
        "sensor_config": _sensor_config(p),
        "estimator_doc": p.estimate.module.DOC if p.estimate is not None else "",
        "noise_l": c_double(sc.noise_l), "noise_p": c_double(sc.noise_p),
        "sensor_noise_l": c_double(p.sensor_noise_l), "sensor_noise_p": c_double(p.sensor_noise_p),
        "estimator_settings": _estimator_settings(p.sc),
        "inputs": inputs, "n_in": len(inputs), "in_total": sum(e["size"] for e in inputs),
        "outputs": [{"index": i, "name": nm, "rows": int(s[0]), "cols": int(s[1]), "size": int(s[0]) * int(s[1])}
                    for i, (nm, s) in enumerate(zip(fn.out_names, fn.out_shapes))],
        "out_total": sum(int(r) * int(c) for r, c in fn.out_shapes),
        "n_slots": len(loop["slots"]), "n_xc": n_xc, "xc_cap": max(n_xc, 1),
        "xc0": c_doubles(ctrl.xc if n_xc else np.zeros(1)),
        "xc_blocks": _xc_blocks(ctrl, model),
        "x0": c_doubles(p.x0), "q_meas0": c_doubles(p.q0), "l0": c_doubles(dyn.leg_lengths(p.q0)),
        "coords": model.coordinate_names,
        "config": _with_definitions(loop["config"], values, dyn.library.manifest.get(NUMBERS)),
        "coord_units": model.coordinate_units, "amplitude": c_doubles(ref.amplitude()),
        **_number_checks(dyn),
    }


def number_ranges(model, names) -> list:
    """(low, high) of each of the description's numbers ``names`` (None: unbounded): the description's
    own (:meth:`hydrogen.model.Model.number_ranges`), which the loader holds them to."""
    ranges = model.number_ranges()
    missing = [k for k in names if k not in ranges]
    if missing:
        raise HydrogenError(f"export: the compiled dynamics take the number '{missing[0]}', which model "
                            f"{model.name} does not give; rebuild")
    return [ranges[k] for k in names]


def _number_checks(dyn) -> dict:
    """What params.h needs to check the description's numbers (a library generated with them as
    inputs): each one's name and range (C literals; HUGE_VAL: unbounded), and the order rules between
    a cylinder's constants by index (:meth:`hydrogen.model.Model.number_orders`)."""
    if dyn.library.numbers is None:
        return {"numbers": [], "number_order": []}
    names = list(dyn.library.manifest[NUMBERS])
    at = {k: i for i, k in enumerate(names)}
    _check_number_names(names)
    ranges = number_ranges(dyn.model, names)
    for k, v, (lo, hi) in zip(names, dyn.library.numbers, ranges):
        if not ((lo is None or v >= lo) and (hi is None or v <= hi)):  # the loader holds them: never seen
            raise HydrogenError(f"export: the description's number '{k}' = {v!r} is outside its range [{lo}, {hi}]")
    numbers = [{"name": k, "min": "-HUGE_VAL" if lo is None else c_double(lo),
                "max": "HUGE_VAL" if hi is None else c_double(hi)} for k, (lo, hi) in zip(names, ranges)]
    order = [{"a": at[a], "b": at[b], "strict": int(strict), "why": why}
             for a, b, strict, why in dyn.model.number_orders() if a in at and b in at]
    return {"numbers": numbers, "number_order": order}


#: A number's name: a description's names (hydrogen.names.check_name: letters, digits, '_', '-'), dots
#: and brackets. It is written into a C comment as it is: nothing in it can end the comment.
_NUMBER_NAME = re.compile(r"^[A-Za-z0-9_.\[\]-]+$")


def _check_number_names(names):
    bad = [n for n in names if not _NUMBER_NAME.match(n)]
    if bad:
        raise HydrogenError(f"export: the description's number name {bad[0]!r} holds other characters than "
                            "names' (letters, digits, '_', '-'), dots and brackets")


def _numbers_definition(name: str, values, names: list) -> str:
    """The description's numbers as a C array, one per line with its name (a comment: checked to hold
    nothing but names' characters, dots and brackets, so no description text can end it)."""
    _check_number_names(names)
    rows = "\n".join(f"    {c_double(v)},  /* {k}: {n} */" for k, (v, n) in enumerate(zip(values, names)))
    return f"static const double {name}[{len(names)}] = {{\n{rows}\n}};"


def _with_definitions(config: list, values: dict, numbers: list | None = None) -> list:
    """The configuration's groups (:func:`hydrogen.layout.config_fields`) with each exported field's
    params.h definition: the value :func:`hydrogen.simulation.loop_config.config_values` gave it, as C99.
    ``numbers``: the names of the description's numbers (a library generated with them as inputs):
    their array is written one named entry a line, for a user to edit on the target."""
    from markupsafe import Markup  # numbers formatted here, names from hydrogen.layout: no user text

    def definition(f):
        name, ctype, v = f["value"], f["type"], values[f["name"]]
        if f["name"] == NUMBERS and numbers is not None:
            return _numbers_definition(name, v, numbers)
        if ctype == "double":
            return f"static const double {name} = {c_double(v)};"
        if ctype == "long long":
            return f"#define {name} {int(v)}LL"
        if ctype == "slots":
            return f"static const long long {name}[P_N_SLOTS] = {{ {', '.join(str(int(i)) for i in v)} }};"
        flat = np.asarray(v, float).ravel()
        return f"static const double {name}[{flat.size}] = {{ {c_doubles(flat)} }};"

    return [{**g, "fields": [{**f, "definition": Markup(definition(f)) if f["value"] else None}
                             for f in g["fields"]]} for g in config]


_README = """\
Closed loop of model {model}: scenario {scenario}, controller {controller}
Exported by hydrogen.export (hydrogen {version}). Plain C99, no dependency but libm.

Files
  main.c          sets up the controller's argument tables and the loop, runs the scenario
                  ({n} control periods of {h_ms} ms, {substeps} RK4 plant sub-steps each) and prints the
                  maximum absolute tracking error per coordinate over t >= {metric_start} s
                  (over the whole run when fewer than {min_window} periods are that late)
  params.h        every number of the run as C99 static const arrays (SI units, matrices
                  column-major): the controller's static inputs in its input order, plant
                  parameters, reference, timing, the estimator's numbers, initial states and bounds
  {loop_c}, {loop_h}
                  the closed-loop driver: sensors, estimator, forward kinematics,
                  reference, controller (zero-order hold), plant (RK4)
  {ctrl_files}
                  the controller, generated by CasADi: int {ctrl_name}(arg, res, iw, w, mem){rates_note}
  {other}
                  inverse kinematics, leg Jacobian and plant dynamics, generated by CasADi
  Makefile, CMakeLists.txt   build files; export.json   what was exported, with SHA-256 of each file

Build and run
  make && make run            (cc -O2 -std=c99 -ffp-contract=off -Wall -Wextra -Werror, links -lm)
  or: cmake -S . -B build && cmake --build build && ./build/{prog}

Output, one item per line:
  max_error <coord> <value> <unit>  <pct> % of amplitude  <value> mm|mrad
                              per coordinate: the max |q - q_d| in SI (m or rad), in % of the
                              reference amplitude ("-" where the reference does not move it) and
                              in mm or mrad, the figures 'hydrogen simulate' prints
  periods <n>                 control periods run
  status <code>               0 ok, 1 non-finite state, 2 forward kinematics failed, 3 a generated
                              function failed (the exit status is non-zero unless status is 0)
Before it runs, the program checks the description's numbers in params.h (P_NUMBERS, which may be
edited) against their ranges (P_NUMBER_MIN, P_NUMBER_MAX) and the order between a cylinder's
constants (P_NUMBER_ORDER); a number that breaks one is named on stderr, and the exit status is 2.

The program runs without sensor noise (every sensor's noise is a simulator feature; the
loop gets a NULL noise table). Its errors therefore equal those of
  hydrogen.simulate("{scenario}", "{controller}", model={model_arg}, {quiet}{extra})
to rounding.
{estimator_note}

On a real-time target, keep the controller call and its argument tables as main.c sets
them up, write the measured pose, rates, pressures (or leg lengths) and the reference into
the dynamic input buffers each period, and replace the simulated plant of the loop driver
by the valves and sensors.
"""


_STEP_NOTE = """
                  {step}: the loop's semi-implicit period in one call (state update, then
                  the command at the updated state)"""


def prepare_export(model, dyn, scenario, controller, gains, duration, check_workspace, overrides, numbers=None,
                   progress=None):
    """What an exported program (C folder or FMU) runs: ``(dyn, scenario, its name, the prepared run)``.

    The names are checked, as they are written into generated files; the run is prepared exactly
    as ``simulate(..., **scenario.noise_free())`` prepares it (exported programs run
    noise-free), and it keeps the scenario's sensor noise for the estimator's design meant for the rig.
    """
    from .errors import ScenarioError
    from .names import check_identifier, check_label
    from .simulation.scenarios import default_scenario_name, scenario as named_scenario
    from .estimators import estimate_for
    from .simulation.simulator import prepare_run

    dyn = resolve_dyn(model, dyn, numbers, controller if isinstance(controller, str) else None, progress)
    if scenario is None:
        scenario = default_scenario_name(dyn.model)
    sc = named_scenario(scenario, dyn.model) if isinstance(scenario, str) else scenario
    sc_name = getattr(sc, "name", None)
    # Both names are written into the Makefile, CMakeLists.txt, params.h and main.c (or the FMU).
    check_identifier(dyn.model.name, "export: model name")
    check_label(sc_name, "export: scenario name", error=ScenarioError)
    overrides = dict(overrides)
    sensor = sc.with_overrides(**overrides) if overrides else sc
    p = prepare_run(dyn, sc, controller, gains, duration, check_workspace,
                    {**overrides, **sensor.noise_free()})
    p.sensor_noise_l, p.sensor_noise_p = float(sensor.noise_l), float(sensor.noise_p)
    p.sensor_estimate = estimate_for(sensor, p.h)  # the estimator designed for the rig's noise
    return dyn, sc, sc_name, p


def sensor_estimate(p):
    """The estimator of the prepared export ``p``'s scenario designed for its sensors' noise
    (:class:`hydrogen.estimators.Estimate`), or None when it selects none."""
    return p.sensor_estimate


def _model_arg(model) -> str:
    """The ``model=`` argument that loads ``model`` again: a built-in's name, else its description's path."""
    from .model import is_shipped
    return repr(model.name if is_shipped(model) else str(model.source))


def export(out_dir, scenario=None, controller="adaptive-robust", model=None, duration=None, *,
           dyn=None, gains=None, generated=None, check_workspace=True, numbers=None, progress=None,
           **overrides) -> Path:
    """Write a self-contained C99 program of ``controller`` on ``scenario`` into ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Folder to write; replaced whole if it exists and is an earlier export (an existing
        folder that is not an export, and not empty, is refused).
    scenario, controller : str
        As for :func:`hydrogen.simulate`; the scenario defaults to the model's first one.
    model : Model, path or None
        The model (default: the packaged one); ignored when ``dyn`` is given.
    duration : float or None
        Simulated time, s (default: the scenario's).
    dyn : Dynamics, optional
        Compiled dynamics to export from (default ``hydrogen.build(model, numbers=numbers)``).
    numbers : "inputs", "constants" or None
        How ``model`` is built when ``dyn`` is not given (:func:`hydrogen.build`; None: its default).
    progress : callable, optional
        The build's progress callback (:func:`hydrogen.build`'s), where this call builds or compiles.
    gains : dict, optional
        Controller gain overrides, as for :func:`hydrogen.simulate`.
    generated : path, optional
        The generated folder ``dyn`` was built from, when it is not the default one.
    overrides
        Scenario fields (e.g. ``metric_start=0.5``). The program always runs without sensor
        noise: ``noise_l`` and ``noise_p`` only set the estimator's sensor-noise design kept in params.h.

    Returns
    -------
    Path of the written folder.
    """
    from . import __version__
    from .fileio import locked, replace_dir, write_file

    # Refused before anything is built or run: the folder must be new, empty or an earlier export.
    if not isinstance(out_dir, (str, os.PathLike)):
        raise OutputPathError(f"export: out_dir must be a folder's path (str or pathlib.Path), got "
                              f"{type(out_dir).__name__} {out_dir!r}"[:300])
    check_export_dir(Path(out_dir).absolute())
    dyn, sc, sc_name, p = prepare_export(model, dyn, scenario, controller, gains, duration, check_workspace,
                                         overrides, numbers, progress)
    overrides = dict(overrides)
    sensor = sensor_estimate(p)

    mname = dyn.model.name
    entries = {e["name"]: e for e in dyn.library.manifest["functions"]}
    ctrl_entries = controller_entries(dyn.library.manifest, p.ctrl)
    ctrl_entry = ctrl_entries[0]
    loop_funcs = loop_functions(dyn.library.manifest["model"])
    funcs = [entries[n] for n in loop_funcs] + ctrl_entries
    drivers = [d for d in dyn.library.manifest.get("drivers", []) if d == f"{mname}_loop.c"]
    if not drivers:
        raise HydrogenError(f"export: the compiled dynamics have no loop driver {mname}_loop.c; rebuild")
    sources = [e["source"] for e in funcs] + [drivers[0]]
    headers = [e["header"] for e in funcs] + [f"{mname}_loop.h"]
    files = read_sources(dyn, sources + headers, generated)

    prog = f"{mname}_{controller.replace('-', '_')}"
    ctx = export_context(dyn, p, sc_name, controller, prog, sources, headers, ctrl_entry["header"])
    rendered = {out: render_template(t, ctx) for t, out in TEMPLATE_NAMES.items()}
    if p.estimate is not None:
        fields = [f.name.upper() for f in p.estimate.module.CONFIG]
        estimator_note = (f"The estimator ({p.estimate.module.DOC}) still runs, with the numbers the simulator "
                       f"designs for the noise-free scenario ({', '.join('P_' + f for f in fields)}); compile "
                       f"with {' '.join('-DHG_SENSOR_' + f for f in fields)} to use "
                       f"{', '.join(f'P_{f}_SENSOR' for f in fields)}, designed for {p.sensor_noise_l:g} m "
                       "leg-length noise, on the rig.")
    else:
        estimator_note = "Leg rates come from the plant's exact rates (this scenario has no estimator)."
    quiet = p.sc.noise_free()  # every noise off, the actuators' own settings merged in
    extra = "".join(f", {k}={v!r}" for k, v in sorted(overrides.items()) if k not in quiet)
    if duration is not None:
        extra = f", duration={float(duration)!r}" + extra
    if gains:
        extra += ", gains=..."
    other = "\n                  ".join(f"{e['source']}, {e['header']}" for e in funcs[:len(loop_funcs)])
    ctrl_files = "\n                  ".join(f"{e['source']}, {e['header']}" for e in ctrl_entries)
    estimator_note = textwrap.fill(estimator_note, width=96)
    rendered["README.txt"] = _README.format(
        model=mname, scenario=sc_name, controller=controller, version=__version__, n=p.n,
        h_ms=f"{1e3 * p.h:.9g}", substeps=sc.substeps, metric_start=f"{p.sc.metric_start:g}",
        loop_c=drivers[0], loop_h=f"{mname}_loop.h", ctrl_files=ctrl_files,
        ctrl_name=ctrl_entry["c_name"], rates_note=_STEP_NOTE.format(step=ctrl_entries[1]["c_name"])
        if len(ctrl_entries) > 1 else "", other=other, prog=prog, extra=extra, estimator_note=estimator_note,
        quiet=", ".join(f"{k}={v!r}" for k, v in quiet.items() if v != {}), model_arg=_model_arg(dyn.model),
        min_window=MIN_WINDOW_SAMPLES)
    contents = {**{n: files[n] for n in sources + headers}, **{n: t.encode() for n, t in rendered.items()}}
    meta = {
        # 2: the run's estimator by name with its numbers (format 1 had the Kalman gain alone)
        "format": 2, "hydrogen_version": __version__, "model": mname, "model_hash": dyn.model.baked_hash(),
        "derivation_hash": dyn.library.manifest.get("derivation_hash"),
        "drivers_hash": dyn.library.manifest.get("drivers_hash"),
        "scenario": sc_name, "controller": controller, "program": prog,
        "n_periods": int(p.n), "control_period_s": float(p.h), "duration_s": float(p.sc.duration),
        "metric_start_s": float(p.sc.metric_start), "overrides": {k: _jsonable(v) for k, v in overrides.items()},
        "gains": {k: _jsonable(v) for k, v in (gains or {}).items()},
        # the run's estimator and its numbers, for the noise-free run and for the rig's sensors
        "estimator": None if p.estimate is None else p.estimate.name,
        "estimator_numbers": None if p.estimate is None else {k: v.tolist() for k, v in p.estimate.config().items()},
        "estimator_numbers_sensor": None if sensor is None else {k: v.tolist() for k, v in sensor.config().items()},
        "files": {n: _sha256(b) for n, b in sorted(contents.items())},
    }
    contents[EXPORT_MANIFEST] = (json.dumps(meta, indent=2, sort_keys=True) + "\n").encode()

    out = Path(out_dir).absolute()
    out.parent.mkdir(parents=True, exist_ok=True)
    with locked(out.with_name(f".{out.name}")):  # hidden lock file beside the folder
        check_export_dir(out, probe=False)  # again under the lock: nothing added meanwhile is deleted
        staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.new-", dir=out.parent))
        try:
            staging.chmod(0o755)
            for name, data in contents.items():
                write_file(staging / name, data)
            replace_dir(staging, out)
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
    return out


def _jsonable(v):
    a = np.asarray(v)
    return a.tolist() if a.dtype.kind in "fiub" else str(v)
