"""The rig's control period at the shipped plant integration against the former one, side by side.

The rig scenarios integrate the plant with the sub-step count the open-loop replay found enough
(``bench_local_error.py``) and hold each pressure within its bounds at every RK4 stage
(``pressure_bounds = "stage"``), and the delay predictor with the RK4 step count its own replay found
enough (``predictor_substeps``); they formerly ran :data:`FORMER` (8 sub-steps, the pressures
clipped after each step only, 4 predictor steps per period). For each shipped robot's rig scenario and variant (``<scenario>.<variant>``)
and every controller the robot lists, over noise seeds :data:`SEEDS`, three runs per seed in a row in
one process: at the former settings, at the scenario's own (shipped) and at a reference of
:data:`REFERENCE` sub-steps and predictor steps (the shipped bounds).

Reported per scenario: the C loop's µs per control period (``loop_wall_s`` over its periods; median
over seeds and controllers), former and shipped, and their ratio; each reported error (the max
tracking error in % of each moving coordinate's reference amplitude, median and worst over the
seeds) as a deviation from the reference's, former and shipped, the largest over the controllers
(percentage points). The adaptive runs are chaotic on the rig (``rig_seeds.py``), so even the former
settings deviate from the reference by more than their integration error: a controller is
**chaotic** there when the former's runs differ from the reference's by more than :data:`TOLERANCE`
point on some seed. The shipped settings **keep** a controller's errors when their deviation is
within :data:`TOLERANCE` point, or, for a chaotic one, within the former's deviation where that is
larger (the seeds resolve no less). ``bench_local_error.py`` gives the integration's own error,
without the loop.

Run: ``python benchmarks/bench_rig_period.py [--quick] [--workers W] [--json FILE]`` (about 5
minutes on 2 cores; ``--quick``: the first rig scenario of the first robot, its first controller, one
seed, 1 s).
"""
from __future__ import annotations

import math
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import hydrogen
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.simulator import Batch

try:  # imported as benchmarks.bench_rig_period
    from . import common
    from .bench_integrator import deviation, rig_scenarios
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common
    from bench_integrator import deviation, rig_scenarios

#: The plant's and the predictor's integration the rig scenarios ran before (scenario fields).
FORMER = {"substeps": 8, "pressure_bounds": "step", "predictor_substeps": 4}
#: The reference's sub-steps, and the seeds.
REFERENCE, SEEDS = 64, (0, 1, 2, 3, 4)
QUICK_REFERENCE, QUICK_SEEDS, QUICK_DURATION = 16, (0,), 1.0
#: The shipped settings keep an error within this many percentage points of the reference's (or the
#: former's deviation, where that is larger).
TOLERANCE = 0.1
ROUTES = ("former", "shipped", "reference")


def _errors(res) -> dict:
    return {c: v for c, v in res.metrics["max_error_pct"].items() if v is not None}


def measure(dyn, scenario: str, controller: str, seeds, reference: int, duration=None) -> dict:
    """The runs of one scenario and controller at each route over ``seeds``, in a row per seed: for
    each route {"errors": {coordinate: [% per seed]}, "failed": {seed: message}, "us": [µs per period
    per completed seed]}."""
    batches = {"former": Batch(dyn, scenario, controller, duration=duration, **FORMER),
               "shipped": Batch(dyn, scenario, controller, duration=duration),
               "reference": Batch(dyn, scenario, controller, duration=duration, substeps=reference,
                                  predictor_substeps=reference)}
    out = {r: {"errors": {}, "failed": {}, "us": []} for r in ROUTES}
    for seed in seeds:
        for route, batch in batches.items():
            try:
                res = batch.run(None, seed)
            except Exception as exc:  # noqa: BLE001 - a diverged run is a result, not a crash
                out[route]["failed"][str(seed)] = str(exc).splitlines()[0]
                continue
            for c, v in _errors(res).items():
                out[route]["errors"].setdefault(c, []).append(float(v))
            out[route]["us"].append(res.metrics["loop_wall_s"] / batch.plan.n * 1e6)
    return out


def _task(args):
    model_name, scenario, controllers, seeds, reference, duration = args
    model = hydrogen.load_model(model_name)
    dyn = hydrogen.build(model)  # once per task: its controllers share the library
    sc = named_scenario(scenario, model)
    per = {c: measure(dyn, scenario, c, seeds, reference, duration) for c in controllers}
    return model_name, scenario, sc.substeps, sc.pressure_bounds, sc.predictor_substeps if sc.predicts() else None, per


def summarise(per: dict) -> dict:
    """Per scenario: µs per period (median over controllers and seeds) of each route, the ratio
    former / shipped, and each controller's deviations from the reference (former, shipped) and
    whether the shipped keeps its errors."""
    us = {r: statistics.median(x for c in per.values() for x in c[r]["us"]) for r in ("former", "shipped")}
    controllers = {}
    for c, runs in per.items():
        ref = runs["reference"]
        d = {r: deviation(runs[r], ref) for r in ("former", "shipped")}
        # chaotic: the former integration's runs already differ from the reference's seed by seed by
        # more than the tolerance, so the seeds cannot resolve the integration's share
        chaotic = d["former"]["paired"] is None or d["former"]["paired"] > TOLERANCE
        shipped = d["shipped"]["dev"]
        keeps = shipped is not None and shipped <= max(TOLERANCE, d["former"]["dev"] if chaotic else 0.0)
        controllers[c] = {"dev_former": d["former"]["dev"], "dev_shipped": shipped, "keeps": keeps,
                          "chaotic": chaotic, "paired_former": d["former"]["paired"],
                          "paired_shipped": d["shipped"]["paired"],
                          "failed": {r: runs[r]["failed"] for r in ROUTES if runs[r]["failed"]},
                          "median_shipped": {k: statistics.median(v) for k, v in runs["shipped"]["errors"].items()}}
    def largest(key, chaotic):
        return max((v[key] for v in controllers.values() if v[key] is not None and v["chaotic"] == chaotic),
                   default=None)

    return {"us_former": us["former"], "us_shipped": us["shipped"], "ratio": us["former"] / us["shipped"],
            "dev_former": largest("dev_former", False), "dev_shipped": largest("dev_shipped", False),
            "dev_former_chaotic": largest("dev_former", True), "dev_shipped_chaotic": largest("dev_shipped", True),
            "keeps": all(v["keeps"] for v in controllers.values()),
            "not_kept": sorted(c for c, v in controllers.items() if not v["keeps"]),
            "chaotic": sorted(c for c, v in controllers.items() if v["chaotic"]), "controllers": controllers}


def run(quick: bool = False, workers: int = 2) -> dict:
    start = time.perf_counter()
    seeds, reference = (QUICK_SEEDS, QUICK_REFERENCE) if quick else (SEEDS, REFERENCE)
    duration = QUICK_DURATION if quick else None
    tasks = []
    for name in common.robots()[:1] if quick else common.robots():
        model = hydrogen.load_model(name)
        controllers = list(model.controllers[:1] if quick else model.controllers)
        for s in rig_scenarios(model, quick):
            tasks.append((name, s, controllers, seeds, reference, duration))
    if workers > 1 and len(tasks) > 1:
        with ProcessPoolExecutor(workers) as pool:
            results = list(pool.map(_task, tasks))
    else:
        results = [_task(t) for t in tasks]
    rows = [{"model": m, "scenario": s, "substeps": n, "pressure_bounds": b, "predictor_substeps": k, **summarise(per)}
            for m, s, n, b, k, per in results]
    return {"rows": rows, "former": FORMER, "reference": reference, "seeds": list(seeds), "tolerance": TOLERANCE,
            "quick": quick, "workers": workers, "cores": os.cpu_count(), "machine": common.machine_info(),
            "wall_s": time.perf_counter() - start}


def _g(x, digits=2):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}g}"


def print_table(res: dict) -> None:
    f = res["former"]
    print(f"µs per rig period: former ({f['substeps']} sub-steps, bounds {f['pressure_bounds']}) -> shipped; "
          f"largest deviation of a reported error from {res['reference']} sub-steps (points)")
    for r in res["rows"]:
        pred = f" pred {r['predictor_substeps']}" if r.get("predictor_substeps") else ""
        print(f"{r['model']:14} {r['scenario']:22} {r['substeps']:2} {r['pressure_bounds']:5}{pred} "
              f"{r['us_former']:6.2f} -> {r['us_shipped']:6.2f} us  x{r['ratio']:.2f}  "
              f"dev {_g(r['dev_former'])} -> {_g(r['dev_shipped'])}, chaotic {_g(r['dev_former_chaotic'])} -> "
              f"{_g(r['dev_shipped_chaotic'])}  {'keeps' if r['keeps'] else 'not: ' + ', '.join(r['not_kept'])}")


def main(argv=None) -> int:
    return common.script_main(__doc__, run, print_table, argv,
                              {"--workers": dict(type=int, default=2, help="processes (default 2)")})


if __name__ == "__main__":
    sys.exit(main())
