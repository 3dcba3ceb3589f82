"""From an edit of a description's structure to its first run, with an empty cache.

An edit of structure (a joint, an actuator, an adapted parameter, a number that becomes 0 or ±1)
generates and compiles again; an edit of numbers does not (``bench_edit.py``). Cases, each in a
fresh Python process with a fresh cache, timed from the process start:

* every shipped robot (``hydrogen.models()``) with its gravity set to 0: a number becomes zero, which
  the derivation holds exact, so its structure changes and nothing committed or cached serves it;
* the spatial 3-DOF leg of ``bench_forms.py`` (``leg_description``), the class of a quadruped's leg;
* the planar chain of ``bench_scaling.py`` (``chain_description``) of each of ``CHAIN_NS`` links;
* the URDF-born leg (``common.URDF_LEG``: rpy joint origins, full inertias, nine adapted
  parameters, as users load a robot) to its first ``LEG_CONTROLLER`` run, by both routes side by side:
  the numbers as inputs (the default) and folded (``numbers="constants"``).

Each process builds for the controller it runs, as ``hydrogen simulate`` does (``hydrogen.build(...,
controllers=[CONTROLLER])``: the derivation of the core and of that controller alone, the rendering
and the core library's compile), then runs ``CONTROLLER`` for ``DURATION`` s of the first scenario (whose first use
compiles the library of the variant the scenario's gains run); a description with no scenario (the
leg) takes the controller's full variant instead, as a run with the composite law compiles it.
Reported: process wall and CPU seconds (the process and its compilers), the generation and the core
compile (from the build's progress events) and the first use; with the release checks, the target
wall time of each class. Median of ``RUNS`` runs (1 with ``--quick``).

Run: ``python benchmarks/bench_cold.py [--quick] [--json FILE]`` (about 4-5 minutes).
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

try:  # imported as benchmarks.bench_cold
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

CONTROLLER = "adaptive-robust"
#: The URDF-born leg's first run: the controller a new robot is tried with first.
LEG_CONTROLLER = "backstepping"
DURATION = 0.05
RUNS = 2
CHAIN_NS = (7, 12)
#: The wall-time target of each case's class, s (2 cores): a platform like the Stewart one, a spatial
#: 3-DOF leg, a 7-link chain, a 12-link chain (its first adaptive run: the project's own target, set
#: after the 7-link one's), a leg from a URDF (numbers as inputs; the folded route has none).
TARGETS = {"robot": 15.0, "leg": 30.0, "chain": 60.0, "long chain": 40.0, "urdf": 60.0}

_RUN = """
import json, resource, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {bench!r})
import hydrogen
from hydrogen.controllers import function_name
from hydrogen.model import model_from_dict
from hydrogen.simulation.scenarios import scenario_names
kind, arg = {kind!r}, {arg!r}
if kind == "robot":
    model = hydrogen.load_model(arg)
elif kind == "leg":
    from bench_forms import leg_description
    model = model_from_dict(leg_description())
else:
    from bench_scaling import chain_description
    model = model_from_dict(chain_description(int(arg)))
events = []
scenarios = scenario_names(model)
# as hydrogen simulate builds: for its controller, with the scenario's own gains over the description's
from hydrogen.simulation.scenarios import scenario as named_scenario
gains = {{{controller!r}: named_scenario(scenarios[0], model).gains.get({controller!r})}} if scenarios else None
dyn = hydrogen.build(model, cache={cache!r}, progress=events.append, numbers={numbers!r}, controllers=({controller!r},),
                     gains=gains)
t1 = time.perf_counter()
if scenarios:  # compiles the library of the variant the scenario's gains run, then runs
    hydrogen.simulate(scenarios[0], {controller!r}, dyn=dyn, duration={duration!r})
else:  # no scenario to run: the full variant's library, as a run with composite rates compiles it
    dyn.functions[function_name({controller!r})]
t2 = time.perf_counter()
stages = {{}}
for e in events:
    if e.stage in ("generated", "compiled"):
        stages.setdefault(e.stage, e.elapsed_s)
own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print("build_s", t1 - t0)
print("generate_s", stages.get("generated", 0.0))
print("core_compile_s", stages.get("compiled", 0.0))
print("first_use_s", t2 - t1)
print("ran", int(bool(scenarios)))
print("cpu_s", own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime)
"""


def structural_copy(name: str, folder: Path) -> Path:
    """A copy of robot ``name``'s description folder in ``folder`` with gravity 0; the TOML."""
    return common.copy_with_gravity(name, folder, lambda g: 0.0)


def cases(root: Path) -> list:
    """``(label, class, kind, argument, controller, numbers)`` of every case; robots' edited copies
    written under ``root``."""
    out = []
    for name in common.robots():
        folder = root / f"desc-{name}"
        folder.mkdir()
        out.append((f"{name}, gravity 0", "robot", "robot", str(structural_copy(name, folder)), CONTROLLER, "inputs"))
    out.append(("spatial 3-DOF leg", "leg", "leg", "", CONTROLLER, "inputs"))
    for n in CHAIN_NS:
        out.append((f"planar chain, n = {n}", "chain" if n < 10 else "long chain", "chain", str(n), CONTROLLER,
                    "inputs"))
    for numbers in ("inputs", "constants"):  # side by side: the default route and the folded one
        out.append((f"URDF leg, numbers as {numbers}", "urdf", "robot", str(common.URDF_LEG), LEG_CONTROLLER, numbers))
    return out


def run(quick: bool = False) -> dict:
    t0 = time.perf_counter()
    runs = 1 if quick else RUNS
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_cold_") as root:
        root = Path(root)
        for label, cls, kind, arg, controller, numbers in cases(root):
            def one(i):
                cache = root / f"cache-{len(rows)}-{i}"
                stdout, wall = common.run_python(_RUN.format(
                    bench=str(Path(__file__).resolve().parent), kind=kind, arg=arg, cache=str(cache),
                    controller=controller, duration=DURATION, numbers=numbers))
                shutil.rmtree(cache, ignore_errors=True)
                return {**common.parse_keyed(stdout), "process_wall_s": wall}

            row, rs = common.median_of_runs(runs, one, ("process_wall_s", "cpu_s", "generate_s", "core_compile_s",
                                                        "first_use_s"))
            target = TARGETS[cls] if numbers == "inputs" else None  # the folded route is shown beside it
            row.update(case=label, cls=cls, controller=controller, numbers=numbers, target_s=target,
                       ran=bool(rs[0]["ran"]), runs=rs,
                       within_target=None if target is None else row["process_wall_s"] < target)
            rows.append(row)
    return {"rows": rows, "controller": CONTROLLER, "duration_s": DURATION, "runs": runs, "quick": quick,
            "wall_s": time.perf_counter() - t0, "machine": common.machine_info()}


def print_table(res: dict, checks: bool = False) -> None:
    """The table; with ``checks`` (the project's release checks) each class's target and whether it holds."""
    f = common.seconds
    common.print_rows(
        f"A structural edit to the first run, fresh process and cache; seconds (median of {res['runs']}):",
        [("case", -32, lambda r: r["case"]), ("controller", -16, lambda r: r.get("controller", res["controller"])),
         ("wall", 7, f("process_wall_s")), ("CPU", 7, f("cpu_s")), ("generate", 9, f("generate_s")),
         ("core cc", 8, f("core_compile_s")), ("first use", 10, f("first_use_s"))],
        res["rows"], res["wall_s"], checks)


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
