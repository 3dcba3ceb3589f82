"""From an edit of a number in a robot's description to the next run finishing, by two routes.

For every shipped robot (``hydrogen.models()``) and the URDF-born leg (``common.URDF_LEG``), the
description is copied and one number edited:
gravity, 0.1 % lower (a number every description has; any other number takes the same route).
Each route then runs in a fresh Python process, timed from its start to the end of a short
``hydrogen.simulate`` (the robot's first scenario, ``backstepping``, ``DURATION`` s), building for
that controller as ``hydrogen simulate`` does:

* ``inputs``: ``hydrogen.build(edited)`` as by default (the numbers as inputs) on a cache that holds
  the build of the shipped description (made beforehand, not timed): the structure is the same, so
  the build only loads the libraries (checked: its progress events are "loaded" alone), then the C
  loop.
* ``constants``: ``hydrogen.build(edited, numbers="constants")``, numbers folded: the edited
  description is generated and compiled again (its cache holds nothing of it), then the C loop.

Reported per route: process wall seconds, and inside it the import, the build and the run; and the
ratio of the two walls. Median of ``RUNS`` runs (1 with ``--quick``).

Run: ``python benchmarks/bench_edit.py [--quick] [--json FILE]`` (about 1-2 minutes per robot).
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

try:  # imported as benchmarks.bench_edit
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

DURATION = 0.05
CONTROLLER = "backstepping"
RUNS = 3
ROUTES = ("inputs", "constants")

_RUN = """
import time
t0 = time.perf_counter()
import hydrogen
t1 = time.perf_counter()
model = hydrogen.load_model({toml!r})
events = []
dyn = hydrogen.build(model, cache={cache!r}, numbers={numbers!r}, progress=events.append, controllers=({controller!r},))
t2 = time.perf_counter()
r = hydrogen.simulate({scenario!r}, {controller!r}, dyn=dyn, duration={duration!r}, engine={engine!r})
t3 = time.perf_counter()
print("import_s", t1 - t0)
print("build_s", t2 - t1)
print("simulate_s", t3 - t2)
print("loaded_only", int([e.stage for e in events] == ["loaded"]))
print("periods", len(r.q))
"""


def edited_copy(name: str, folder: Path) -> Path:
    """A copy of robot ``name``'s description folder in ``folder`` with gravity 0.1 % lower; the TOML."""
    return common.copy_with_gravity(name, folder, lambda g: g * 0.999)


def run_robot(name: str, runs: int) -> dict:
    import hydrogen

    from hydrogen.simulation.scenarios import scenario_names

    model = hydrogen.load_model(name)
    scenario = scenario_names(model)[0]
    rows = {route: [] for route in ROUTES}
    with tempfile.TemporaryDirectory(prefix="bench_edit_") as root:
        root = Path(root)
        warm = root / "warm"
        hydrogen.build(model, cache=warm, numbers="inputs", controllers=[CONTROLLER])  # the shipped one, untimed
        for i in range(runs):
            for route in (ROUTES if i % 2 == 0 else ROUTES[::-1]):
                desc = root / f"desc-{route}{i}"
                desc.mkdir()
                toml = edited_copy(name, desc)
                cache = warm if route == "inputs" else root / f"cold{i}"
                stdout, wall = common.run_python(_RUN.format(
                    toml=str(toml), cache=str(cache), numbers=route, scenario=scenario, controller=CONTROLLER,
                    duration=DURATION, engine="c"))
                r = common.parse_keyed(stdout)
                r["process_wall_s"] = wall
                rows[route].append(r)
                if route == "constants":
                    shutil.rmtree(cache, ignore_errors=True)
    out = {"scenario": scenario, "controller": CONTROLLER, "duration_s": DURATION}
    for route, rs in rows.items():
        out[route] = {k: common.median(r[k] for r in rs) for k in ("process_wall_s", "import_s", "build_s",
                                                                    "simulate_s")}
        out[route]["loaded_only"] = all(r["loaded_only"] == 1 for r in rs)
        out[route]["runs"] = rs
    out["wall_ratio"] = out["constants"]["process_wall_s"] / out["inputs"]["process_wall_s"]
    return out


def run(quick: bool = False, models=None) -> dict:
    t0 = time.perf_counter()
    runs = 1 if quick else RUNS
    import hydrogen

    names = models or [*common.robots(), str(common.URDF_LEG)]
    robots = {hydrogen.load_model(name).name: run_robot(name, runs) for name in names}
    return {"robots": robots, "quick": quick, "runs": runs, "wall_s": time.perf_counter() - t0,
            "machine": common.machine_info()}


def print_table(res: dict) -> None:
    print(f"A numeric edit (gravity -0.1 %) to the end of a {DURATION:g} s run, fresh process; seconds "
          f"(median of {res['runs']}):")
    header = f"{'robot':<16} {'route':<10} {'wall':>7} {'import':>7} {'build':>7} {'run':>7}  build only loaded"
    print(header)
    print("-" * len(header))
    for name, r in res["robots"].items():
        for route in ROUTES:
            v = r[route]
            print(f"{name:<16} {route:<10} {v['process_wall_s']:>7.2f} {v['import_s']:>7.2f} {v['build_s']:>7.2f} "
                  f"{v['simulate_s']:>7.2f}  {v['loaded_only']}")
        print(f"{'':<16} constants / inputs: {r['wall_ratio']:.1f}x")
    print(f"whole benchmark {res['wall_s']:.1f} s")


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
