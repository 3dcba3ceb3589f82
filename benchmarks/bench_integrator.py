"""What the plant's integration costs and what it buys on the rig: for each shipped robot's rig
scenarios (``rig = true``) and each of their variants (``<scenario>.<variant>``), every controller
the robot lists, the C loop at each RK4 sub-step count (``substeps``: plant steps per control
period) against a reference run of :data:`REFERENCE` sub-steps, over noise seeds :data:`SEEDS`.

Every reported error (the max tracking error in % of each coordinate's reference amplitude, the
coordinates the reference moves: ``res.metrics["max_error_pct"]``) is a distribution over the
seeds: its median and worst. A count's **deviation** is the largest difference, over those
coordinates and the two statistics, from the reference's (percentage points). On the rig the
adaptive runs are chaotic (a difference of 1e-15 grows to another run within seconds: benchmarks/
rig_seeds.py), so the reference itself moves: its **floor** is the deviation of a run at
:data:`CHECK` sub-steps, whose integration error is far below the reference's. A count **keeps** the
errors when its deviation is within :data:`TOLERANCE` point, or within the floor where that is
larger (then the seeds cannot resolve a smaller difference); a run that fails (diverges) keeps
nothing. The per-seed (paired) deviation is reported too: for a controller that is not chaotic it is
the integration error alone.

Per scenario: the cheapest count from which every tested count keeps every controller's errors,
against the scenario's own setting; the cost of each count per control period (the C loop's
``loop_wall_s`` over its periods, median over seeds and controllers) and in CasADi instructions
(``plant_rhs``'s count x its calls per period: 4 per RK4 step of the plant and of the predictor). The valve's stability check
(``2 pi valve_bandwidth_hz / (control_rate substeps) <= 1``) bounds the count from below; its
``omega h`` is reported per count. Then the same for the delay predictor's ``predictor_substeps``
on every scenario whose loop predicts (reference :data:`PRED_REFERENCE`, floor :data:`PRED_CHECK`),
the plant at the scenario's own count.

Run: ``python benchmarks/bench_integrator.py [--quick] [--json FILE]`` (about 10 minutes on 2 cores;
``--quick``: the first rig scenario of each robot, its first controller, 2 seeds, a few counts).
"""
from __future__ import annotations

import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import hydrogen
from hydrogen.errors import HydrogenError
from hydrogen.plant import integrator
from hydrogen.simulation.scenarios import scenario as named_scenario, scenario_names, variant_names
from hydrogen.simulation.simulator import Batch

try:  # imported as benchmarks.bench_integrator
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

#: Plant sub-step counts tested (the scenario's own is added when missing), the reference and the
#: check of the reference (its floor).
SUBSTEPS, REFERENCE, CHECK = (1, 2, 3, 4, 6, 8, 12, 16), 64, 128
QUICK_SUBSTEPS, QUICK_REFERENCE, QUICK_CHECK = (1, 2), 16, 32
#: The predictor's step counts per control period, its reference and check.
PRED_SUBSTEPS, PRED_REFERENCE, PRED_CHECK = (1, 2, 4, 8), 32, 64
QUICK_PRED_SUBSTEPS, QUICK_PRED_REFERENCE, QUICK_PRED_CHECK = (1, 2), 8, 16
SEEDS, QUICK_SEEDS = (0, 1, 2, 3, 4), (0, 1)
#: A count keeps an error when it is within this many percentage points of the reference's.
TOLERANCE = 0.1


def rig_scenarios(model, quick: bool = False) -> list:
    """Names of ``model``'s rig scenarios (``rig = true``) and of each with each variant
    (``<scenario>.<variant>``); with ``quick`` the first rig scenario alone."""
    rigs = [s for s in scenario_names(model) if model.scenarios[s].get("rig", False)]
    if quick:
        return rigs[:1]
    return [f"{s}.{v}" if v else s for s in rigs for v in (None, *variant_names(model))]


def predicting_scenarios(model, quick: bool = False) -> list:
    """The rig scenarios and variants whose loop runs the delay predictor (``Scenario.predicts``);
    with ``quick`` the first of them alone."""
    names = [s for s in rig_scenarios(model) if named_scenario(s, model).predicts()]
    return names[:1] if quick else names


def plant_steps(sc) -> int:
    """RK4 steps of the plant per control period: ``substeps``, or, when the command switches inside the
    period (a fraction of a period of delay), each part's share rounded up (the C loop's plant_step)."""
    _, frac = sc.delay_split()
    return sum(n for n, _ in integrator.period_pieces(sc.substeps, frac, 1.0))


def predictor_steps(sc) -> int:
    """RK4 steps of the delay predictor per control period (0 when the loop does not predict): a
    whole period of delay each, then the fraction (the C loop's pred_hold)."""
    if not sc.predicts():
        return 0
    d, frac = sc.delay_split()
    return sc.predictor_steps(1) * d + (sc.predictor_steps(frac) if frac else 0)


def _instructions(dyn, fn_name):
    entry = next((e for e in dyn.library.manifest["functions"] if e["name"] == fn_name), None)
    return None if entry is None else entry.get("instructions")


def measure(dyn, scenario: str, controller: str, field: str, value: int, seeds) -> dict:
    """The runs of ``scenario`` and ``controller`` with scenario field ``field`` = ``value`` over
    ``seeds``: {"errors": {coordinate: [% per seed, None where the run failed]}, "failed": {seed:
    message}, "us_per_period": median over the completed runs}; {"refused": message} when the
    scenario's checks refuse the value."""
    try:
        batch = Batch(dyn, scenario, controller, **{field: value})
    except HydrogenError as exc:
        return {"refused": str(exc)}
    g = batch.grid([None], list(seeds))
    coords = tuple(dyn.model.coordinate_names)
    errors = {c: [None if math.isnan(v) else float(v) for v in g["max_error_pct"][0][:, i]]
              for i, c in enumerate(coords)}
    done = [m for m in g["metrics"][0] if "error" not in m]
    moved = set().union(*({c for c, v in m["max_error_pct"].items() if v is not None} for m in done)) if done else set()
    return {"errors": {c: errors[c] for c in coords if c in moved},
            "failed": {str(s): m["error"] for s, m in zip(seeds, g["metrics"][0]) if "error" in m},
            "us_per_period": (statistics.median(m["loop_wall_s"] for m in done) / batch.plan.n * 1e6
                              if done else None)}


def _stats(run: dict, coords) -> dict | None:
    """{coordinate: (median, worst)} of a run that completed on every seed, else None."""
    if "refused" in run or run["failed"]:
        return None
    return {c: (statistics.median(run["errors"][c]), max(run["errors"][c])) for c in coords}


def deviation(run: dict, ref: dict) -> dict:
    """How far ``run``'s errors are from the reference ``ref``'s (percentage points): "dev", the
    largest difference of the median or the worst over the coordinates; "paired", the largest
    difference on one seed. None (both) when a run failed or was refused."""
    coords = list(ref["errors"])
    a, b = _stats(run, coords), _stats(ref, coords)
    if a is None or b is None or set(run["errors"]) != set(ref["errors"]):
        return {"dev": None, "paired": None}
    dev = max(abs(a[c][k] - b[c][k]) for c in coords for k in (0, 1))
    paired = max(abs(x - y) for c in coords for x, y in zip(run["errors"][c], ref["errors"][c]))
    return {"dev": dev, "paired": paired}


def _largest(values):
    """The largest of ``values``; None when one is None (a failed run) or there are none."""
    values = list(values)
    return None if not values or any(v is None for v in values) else max(values)


def _keeps(dev, floor) -> bool:
    return dev is not None and dev <= max(TOLERANCE, floor if floor is not None else 0.0)


def cheapest(values, keeps) -> int | None:
    """The smallest of ``values`` (ascending) from which on every value keeps (``keeps[value]``), or None."""
    best = None
    for v in reversed(values):
        if not keeps[v]:
            break
        best = v
    return best


def sweep_field(dyn, scenario: str, field: str, values, reference: int, check: int, seeds, controllers) -> dict:
    """Each of ``controllers`` on ``scenario`` at each of ``values`` of ``field``, the
    reference and the check: per controller the reference's median and worst, the floor, each
    value's deviations and whether it keeps the errors, and the cheapest value that keeps them. A
    controller whose reference run fails (diverges on a seed) is left out and named in
    ``no_reference`` with the failure: nothing to judge its counts against."""
    rows, no_reference = {}, {}
    for c in controllers:
        ref = measure(dyn, scenario, c, field, reference, seeds)
        if "refused" in ref or ref["failed"]:  # nothing to judge its counts against: said, not judged
            no_reference[c] = ref.get("refused") or ref["failed"]
            continue
        floor = deviation(measure(dyn, scenario, c, field, check, seeds), ref)
        counts = []
        for v in values:
            run = measure(dyn, scenario, c, field, v, seeds)
            d = deviation(run, ref)
            counts.append({field: v, **d, "keeps": _keeps(d["dev"], floor["dev"]),
                           "keeps_strict": d["dev"] is not None and d["dev"] <= TOLERANCE,
                           "us_per_period": run.get("us_per_period"), "failed_seeds": sorted(run.get("failed", {})),
                           "refused": run.get("refused")})
        stats = _stats(ref, list(ref["errors"]))
        rows[c] = {"reference": {k: {"median": m, "worst": w} for k, (m, w) in stats.items()},
                   "reference_us_per_period": ref["us_per_period"], "floor": floor["dev"],
                   "floor_paired": floor["paired"], "chaotic": floor["dev"] is None or floor["dev"] > TOLERANCE,
                   "counts": counts,
                   "cheapest": cheapest(values, {r[field]: r["keeps"] for r in counts}),
                   "cheapest_strict": cheapest(values, {r[field]: r["keeps_strict"] for r in counts})}
    per_value = []
    for i, v in enumerate(values):
        at = [r["counts"][i] for r in rows.values()]
        us = [x["us_per_period"] for x in at if x["us_per_period"] is not None]
        calm = [r["counts"][i] for r in rows.values() if not r["chaotic"]]
        per_value.append({field: v, "us_per_period": statistics.median(us) if us else None,
                          "keeps": bool(at) and all(x["keeps"] for x in at), "dev": _largest(x["dev"] for x in at),
                          # the controllers whose reference does not move: their deviation is the integration's
                          "dev_not_chaotic": _largest(x["dev"] for x in calm),
                          "paired_not_chaotic": _largest(x["paired"] for x in calm)})
    return {"controllers": rows, "per_value": per_value, "no_reference": no_reference,
            "cheapest": cheapest(values, {r[field]: r["keeps"] for r in per_value})}


def run_robot(name: str, quick: bool = False) -> dict | None:
    model = hydrogen.load_model(name)
    names = rig_scenarios(model, quick)
    if not names:
        return None
    dyn = hydrogen.build(model)
    n_rhs = _instructions(dyn, "plant_rhs")
    seeds = QUICK_SEEDS if quick else SEEDS
    controllers = model.controllers[:1] if quick else model.controllers  # the controllers the robot lists
    tested, ref, check = (QUICK_SUBSTEPS, QUICK_REFERENCE, QUICK_CHECK) if quick else (SUBSTEPS, REFERENCE, CHECK)
    out = {"model": name, "plant_rhs_instructions": n_rhs, "scenarios": {}, "predictor": {}}
    for s in names:
        sc = named_scenario(s, model)
        values = sorted({*tested, sc.substeps})
        r = sweep_field(dyn, s, "substeps", values, ref, check, seeds, controllers)
        for row in r["per_value"]:  # the cost in instructions and the valve's omega h at each count
            at = sc.with_overrides(substeps=row["substeps"]) if _valve_ok(sc, row["substeps"]) else None
            evaluations = 4 * (plant_steps(at) + predictor_steps(at)) if at else None
            row.update(rhs_evaluations=evaluations,
                       rhs_instructions=n_rhs * evaluations if n_rhs and evaluations else None,
                       valve_omega_h=_omega_h(sc, row["substeps"]))
        current = next(row for row in r["per_value"] if row["substeps"] == sc.substeps)
        out["scenarios"][s] = {"scenario": s, "current": sc.substeps, "control_rate": sc.control_rate,
                               "valve_bandwidth_hz": sc.valve_bandwidth_hz, "valve_lag": sc.valve_lag,
                               "current_keeps": current["keeps"], **r}
    for s in predicting_scenarios(model, quick):
        sc = named_scenario(s, model)
        tested_p, ref_p, check_p = ((QUICK_PRED_SUBSTEPS, QUICK_PRED_REFERENCE, QUICK_PRED_CHECK) if quick else
                                    (PRED_SUBSTEPS, PRED_REFERENCE, PRED_CHECK))
        values = sorted({*tested_p, sc.predictor_substeps})
        r = sweep_field(dyn, s, "predictor_substeps", values, ref_p, check_p, seeds, controllers)
        for row in r["per_value"]:
            steps = predictor_steps(sc.with_overrides(predictor_substeps=row["predictor_substeps"]))
            evaluations = 4 * (plant_steps(sc) + steps)
            row.update(rhs_evaluations=evaluations, rhs_instructions=n_rhs * evaluations if n_rhs else None)
        current = next(row for row in r["per_value"] if row["predictor_substeps"] == sc.predictor_substeps)
        out["predictor"][s] = {"scenario": s, "current": sc.predictor_substeps, "substeps": sc.substeps,
                               "current_keeps": current["keeps"], **r}
    return out


def _omega_h(sc, n) -> float | None:
    """The valve's natural frequency times the sub-step (rad), what its stability check bounds by 1."""
    return 2 * math.pi * sc.valve_bandwidth_hz / (sc.control_rate * n) if sc.valve_bandwidth_hz else None


def _valve_ok(sc, n) -> bool:
    w = _omega_h(sc, n)
    return w is None or w <= 1.0


def run(quick: bool = False) -> dict:
    start = time.perf_counter()
    out = {name: run_robot(name, quick) for name in common.robots()}
    return {"robots": {k: v for k, v in out.items() if v}, "quick": quick, "cores": os.cpu_count(),
            "seeds": list(QUICK_SEEDS if quick else SEEDS), "tolerance": TOLERANCE,
            "reference": QUICK_REFERENCE if quick else REFERENCE, "check": QUICK_CHECK if quick else CHECK,
            "predictor_reference": QUICK_PRED_REFERENCE if quick else PRED_REFERENCE,
            "predictor_check": QUICK_PRED_CHECK if quick else PRED_CHECK,
            "wall_s": time.perf_counter() - start}


def _g(v, digits=2) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _dev_cell(r) -> str:
    if r.get("refused"):
        return "refused"
    if r["dev"] is None:
        return f"FAIL({len(r['failed_seeds'])})"
    return _g(r["dev"]) + ("" if r["keeps"] else "!")


def print_table(res):
    print(f"seeds {res['seeds']}; deviation = largest |median or worst max error % - the reference's| "
          f"(points), reference {res['reference']} sub-steps, floor = the deviation at {res['check']}; "
          f"'!' = not within max({res['tolerance']:g}, floor)")
    for field, key, ref in (("substeps", "scenarios", res["reference"]),
                            ("predictor_substeps", "predictor", res["predictor_reference"])):
        for rob in res["robots"].values():
            for s in rob[key].values():
                values = [row[field] for row in s["per_value"]]
                print(f"\n{rob['model']} {s['scenario']}: {field} (now {s['current']}, reference {ref})")
                print(f"{'controller':18} {'ref median/worst %':>22} {'floor':>6} "
                      + " ".join(f"{v:>7}" for v in values) + f" {'cheapest':>8}")
                for c, r in s["controllers"].items():
                    ref_txt = ", ".join(f"{k} {v['median']:.2f}/{v['worst']:.2f}" for k, v in r["reference"].items())
                    print(f"{c:18} {ref_txt:>22} {_g(r['floor']):>6} "
                          + " ".join(f"{_dev_cell(x):>7}" for x in r["counts"]) + f" {r['cheapest'] or '-':>8}")
                print(f"{'us per period':18} {'':>22} {'':>6} "
                      + " ".join(f"{_g(row['us_per_period'], 1):>7}" for row in s["per_value"]))
                print(f"{'rhs instructions':18} {'':>22} {'':>6} "
                      + " ".join(f"{row['rhs_instructions'] or '-':>7}" for row in s["per_value"]))
                if field == "substeps" and any(row["valve_omega_h"] for row in s["per_value"]):
                    print(f"{'valve omega h':18} {'':>22} {'':>6} "
                          + " ".join(f"{_g(row['valve_omega_h']):>7}" for row in s["per_value"]))
                print(f"cheapest that keeps every controller's errors: {s['cheapest'] or 'none tested'}; "
                      f"now {s['current']} ({'keeps' if s['current_keeps'] else 'does NOT keep'})")
    print(f"\n{res['wall_s']:.0f} s")


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
