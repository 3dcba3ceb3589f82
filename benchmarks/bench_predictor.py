"""What the delay predictor costs: per control period of each robot's rig scenario (the first
``rig = true`` scenario of its description, its full-period delay), the C loop with the predictor off
and on (the scenario's ``predictor``), side by side in one run, for every controller; and the
predictor's work in CasADi instructions (its RK4 evaluations of the plant's model) against the
controller's own call.

Run: ``python benchmarks/bench_predictor.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import os
import statistics
import sys
from pathlib import Path

import hydrogen
from hydrogen.controllers import function_name
from hydrogen.layout import delay_split
from hydrogen.simulation.scenarios import scenario as named_scenario

try:  # imported as benchmarks.bench_predictor
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common


def _per_period(dyn, sc, controller, n, repeats):
    return statistics.median(common.c_loop_per_period(dyn, sc, controller, n) for _ in range(repeats))


def run_robot(name: str, quick: bool = False) -> dict | None:
    model = hydrogen.load_model(name)
    rig = common.rig_scenario(model)
    if rig is None:
        return None
    dyn = hydrogen.build(model)
    sc = named_scenario(rig, model)
    d, frac = delay_split(sc.delay, 1.0 / sc.control_rate)
    # RK4: 4 evaluations of the plant's model per step, the loop's steps over each whole period and the fraction
    evaluations = 4 * (sc.predictor_steps(1) * d + (sc.predictor_steps(frac) if frac else 0))
    n_rhs = _instructions(dyn, "plant_rhs")
    n, repeats = (2000, 3) if quick else (8000, 5)
    rows = {}
    for c in model.controllers:  # the controllers the robot lists
        off = _per_period(dyn, named_scenario(rig, model), c, n, repeats)
        on = _per_period(dyn, named_scenario(rig, model).with_overrides(predictor=True), c, n, repeats)
        rows[c] = {"off_us": off * 1e6, "on_us": on * 1e6, "added_us": (on - off) * 1e6, "ratio": on / off,
                   "controller_instructions": _instructions(dyn, function_name(c))}
    return {"model": name, "scenario": rig, "delay_periods": d + frac, "predictor_substeps": sc.predictor_substeps,
            "plant_rhs_instructions": n_rhs, "evaluations_per_period": evaluations,
            "predictor_instructions_per_period": n_rhs * evaluations, "controllers": rows}


def _instructions(dyn, fn_name):
    entry = next((e for e in dyn.library.manifest["functions"] if e["name"] == fn_name), None)
    return None if entry is None else entry.get("instructions")


def run(quick: bool = False) -> dict:
    out = {name: run_robot(name, quick) for name in common.robots()}
    return {"robots": {k: v for k, v in out.items() if v}, "quick": quick, "cores": os.cpu_count()}


def print_table(res):
    for r in res["robots"].values():
        print(f"{r['model']}: {r['scenario']} ({r['delay_periods']:g} periods of delay), predictor "
              f"{r['evaluations_per_period']} evaluations of plant_rhs ({r['plant_rhs_instructions']} instructions) "
              f"= {r['predictor_instructions_per_period']} instructions per period")
        print(f"{'controller':20} {'instr.':>8} {'off us':>9} {'on us':>9} {'added us':>9} {'ratio':>6}")
        for c, v in r["controllers"].items():
            print(f"{c:20} {v['controller_instructions'] or '-':>8} {v['off_us']:9.2f} {v['on_us']:9.2f} "
                  f"{v['added_us']:9.2f} {v['ratio']:6.2f}")
        print()


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
