"""From an edit of hydrogen's own code to each shipped robot's first run: the part that uses it
generated again alone, against a whole generation, side by side in one run.

A developer adds a rig part (a viscous damper along each actuator: one module of ``hydrogen/plant``)
or edits the loop driver's template (a line added to ``templates/loop.c.j2``: what the drivers alone
are rendered from) in a copy of the package beside its committed generated code, after having built
and run the shipped robots (their compiled objects are in the cache, untimed). A fresh process then
builds the robot for a controller of ``CONTROLLERS`` and runs ``DURATION`` s of its first scenario,
two ways:

* **alone** (what hydrogen does): the committed folder is stale for the plant's function and the loop
  drivers only; the build's cache folder starts as its copy, the plant's function alone is derived
  (after the template edit nothing is: the drivers are rendered again), and the sources that did not
  change compile from the object store;
* **whole**: the same build into a new folder of its own (``generated=``), which derives every
  function, as every edit of the package did when one hash covered all of its code; unchanged sources
  compile from the object store all the same, so the difference is the derivation.

Reported: process wall and CPU seconds (the process and its compilers), the generation and the
compile (from the build's progress events), median of ``RUNS`` runs (1 with ``--quick``), and the
ratio whole / alone of the wall time.

Run: ``python benchmarks/bench_code_edit.py [--quick] [--json FILE]`` (about 3-6 minutes).
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

try:  # imported as benchmarks.bench_code_edit
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

CONTROLLERS = ("backstepping", "adaptive-robust")
DURATION = 0.05
RUNS = 2

#: The rig part added: a viscous damper along each actuator, force -c l̇ (N, or N m for a rotary
#: actuator), c from the scenario's ``damper_rate`` (0 by default: the runs move as without it).
DAMPER = '''\
"""A viscous damper along each actuator: force -c ldot (N or N m), c the scenario's damper_rate."""
from __future__ import annotations

import numpy as np

from ..setting import setting
from . import PlantParameter

POSITION = 9080
STATES = ()
INPUT = "damper"
PARAMETERS = (PlantParameter("rate", lambda t: f"{t.force_unit} s/{t.unit}", "damping (c)", per_actuator=True),)
SCENARIO_SETTINGS = {"damper_rate": setting(0.0, "N s/m", "every actuator's damper (0: none)", ">=0")}


def input_parameters(structure):
    return PARAMETERS


def values(sc, model):
    return np.array([[sc.damper_rate] for _ in model.cylinders], float)


class Symbolic:
    READS = ("ldot", INPUT)
    ADDS = ("leg_force",)

    @staticmethod
    def input(model):
        import sympy as sp
        return sp.Matrix([sp.Symbol(f"c_damper_{i}", real=True) for i in range(model.n_cylinders)])

    @staticmethod
    def outputs(c):
        rate, v = c[INPUT], c["ldot"]
        c.add("leg_force", [-rate[i] * v[i] for i in range(c.model.n_cylinders)])

    @staticmethod
    def derivatives(c):
        pass
'''


def add_damper(pkg: Path) -> None:
    (pkg / "hydrogen" / "plant" / "damper.py").write_text(DAMPER)


def edit_template(pkg: Path) -> None:
    path = pkg / "templates" / "loop.c.j2"
    path.write_text(path.read_text() + "/* edited: a line the drivers carry */\n")


EDITS = (("a rig part added", add_damper), ("the loop template edited", edit_template))

_RUN = """
import resource, time
t0 = time.perf_counter()
import hydrogen
from hydrogen.simulation.scenarios import scenario_names
model = hydrogen.load_model({name!r})
events = []
dyn = hydrogen.build(model, cache={cache!r}, progress=events.append, controllers=({controller!r},){generated})
hydrogen.simulate(scenario_names(model)[0], {controller!r}, dyn=dyn, duration={duration!r})
"""


def _package_copy(root: Path) -> Path:
    """hydrogen, its templates and its committed generated code copied under ``root/pkg``: a checkout
    whose code the benchmark edits."""
    pkg = root / "pkg"
    ignore = shutil.ignore_patterns("__pycache__", "*.so", "_templates", "_generated")
    for name in ("hydrogen", "templates", "generated"):
        shutil.copytree(common.REPO / name, pkg / name, ignore=ignore)
    return pkg


def run(quick: bool = False) -> dict:
    t0 = time.perf_counter()
    runs = 1 if quick else RUNS
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_code_edit_") as root:
        root = Path(root)
        for label, edit in EDITS:
            pkg = _package_copy(root / f"edit-{len(rows)}")
            env = {**common.python_env(), "PYTHONPATH": str(pkg)}
            warm = root / f"warm-{len(rows)}"
            for name in common.robots():  # the developer's earlier runs of the shipped robots (untimed)
                for c in CONTROLLERS:
                    common.run_python(_RUN.format(name=name, cache=str(warm), controller=c,
                                                  duration=DURATION, generated="") + common.BUILD_REPORT,
                                      env=env, cwd=pkg)
            edit(pkg)
            for name, c in ((name, c) for name in common.robots() for c in CONTROLLERS):
                for route in ("alone", "whole"):
                    def one(i):
                        cache = root / f"cache-{len(rows)}-{i}"
                        shutil.copytree(warm, cache)
                        own = f", generated={str(root / f'whole-{len(rows)}-{i}')!r}" if route == "whole" else ""
                        stdout, wall = common.run_python(_RUN.format(name=name, cache=str(cache), controller=c,
                                                                     duration=DURATION, generated=own)
                                                         + common.BUILD_REPORT, env=env, cwd=pkg)
                        shutil.rmtree(cache, ignore_errors=True)
                        return {**common.parse_keyed(stdout), "process_wall_s": wall}

                    row, rs = common.median_of_runs(runs, one, ("process_wall_s", "cpu_s", "generate_s", "compile_s"))
                    row.update(robot=name, edit=label, route=route, controller=c, runs=rs)
                    rows.append(row)
                alone, whole = rows[-2], rows[-1]
                rows.append({"robot": name, "edit": label, "route": "whole / alone", "controller": c,
                             "process_wall_s": whole["process_wall_s"] / alone["process_wall_s"],
                             "ratio": True})
    return {"rows": rows, "duration_s": DURATION, "runs": runs, "quick": quick,
            "wall_s": time.perf_counter() - t0, "machine": common.machine_info(), "cpus": os.cpu_count()}


def print_table(res: dict, checks: bool = False) -> None:
    f = common.seconds

    def cell(key):
        return lambda r: (f"{r[key]:.2f}x" if r.get("ratio") else f(key)(r)) if key in r else ""
    common.print_rows(
        f"An edit of hydrogen's code to a shipped robot's first run, warm cache; seconds (median of {res['runs']}):",
        [("robot", -14, lambda r: r["robot"]), ("edit", -25, lambda r: r["edit"]),
         ("controller", -16, lambda r: r["controller"]), ("route", -14, lambda r: r["route"]),
         ("wall", 7, cell("process_wall_s")), ("CPU", 6, cell("cpu_s")), ("generate", 9, cell("generate_s")),
         ("compile", 8, cell("compile_s"))],
        res["rows"], res["wall_s"], checks)


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
