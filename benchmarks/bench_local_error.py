"""The plant integration's own error on the rig's trajectories, without the loop's amplification.

``bench_integrator.py`` judges a sub-step count by the reported errors of whole runs against a
reference; on the rig those runs amplify any difference (the adaptive ones are chaotic; every loop
reads quantised, noisy sensors and drives Stribeck friction), so a whole run tells how sensitive the
loop is as much as how accurate the integration. This measures the integration alone: a run at the
scenario's own count (the Python engine, the same numbers as the C loop) records each period's
commands (the one the valves hold over the delay's fraction, then the applied one); the plant is then
replayed open loop from the same start under those commands at each count of :data:`COUNTS` and at
:data:`REFERENCE` sub-steps. A count's **replay error** is its largest difference from the
reference's replay over the run: of the coordinates, in percentage points of each coordinate's
reference amplitude (the unit of the reported max errors), and of the pressure states, in Pa and as a
share of the pressure sensors' noise (``noise_p``). The commands being the same, the difference is the
integration's error carried by the plant's own dynamics, with no sensor, estimator or controller to
amplify it.

Per rig scenario and variant of each shipped robot, the trajectories of :data:`CONTROLLERS`, the
scenario's own noise seed, with the pressures held within their bounds by each of :data:`SCHEMES`
(the scenario field ``pressure_bounds``: where a chamber would cavitate, clipping only after each
step converges at first order, clipping at every stage too at RK4's). A count **keeps** the
errors when its coordinates stay within :data:`POINTS` points of the reference's and its pressures
within :data:`NOISE_SHARE` of the pressure noise; cheapest: the smallest count from which every
tested count keeps them.

The delay predictor's own integration the same way (``predictor`` in the results): on every rig
scenario and variant whose loop predicts, each period's prediction (the plant state when the command
lands, by the controller's model from the measured state over the commands in flight) is computed at
each count of :data:`PREDICTOR_COUNTS` RK4 steps per period (the scenario field
``predictor_substeps``) and at :data:`REFERENCE`, from the same measured state and commands, along the
run at the scenario's own count; a count's error is the largest difference of its predicted pose
(points of amplitude) and pressures (Pa) from the reference's, kept by the same rule.

Run: ``python benchmarks/bench_local_error.py [--quick] [--json FILE] [--part plant|predictor]``
(about 15 minutes on one core; ``--quick``: the first rig scenario of the first robot, 0.3 s of it,
two counts, and the first predicting one; ``--part``: that part alone).
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import hydrogen
from hydrogen.plant import plant_layout, slot
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.simulator import PythonStages, prepare_run

try:  # imported as benchmarks.bench_local_error
    from . import common
    from .bench_integrator import predicting_scenarios, rig_scenarios
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common
    from bench_integrator import predicting_scenarios, rig_scenarios

#: Sub-step counts tested, and the reference.
COUNTS, REFERENCE = (2, 3, 4, 6, 8), 64
QUICK_COUNTS, QUICK_REFERENCE, QUICK_DURATION = (2, 4), 16, 0.3
#: The predictor's RK4 steps per control period tested (``predictor_substeps``), against REFERENCE.
PREDICTOR_COUNTS = (1, 2, 3, 4, 8)
QUICK_PREDICTOR_COUNTS = (1, 4)
#: The controllers whose trajectories are replayed: the paper's Theorem 1 (known parameters: not
#: chaotic) and the baseline P, which drives the valves hardest.
CONTROLLERS = ("backstepping", "p")
#: How the pressures are held within their bounds (the scenario field ``pressure_bounds``): after each
#: RK4 step (the default), and also at every stage.
SCHEMES = ("step", "stage")
#: A count keeps the errors within this many points of amplitude (a tenth of the 0.1 point
#: bench_integrator holds the reported errors to) and this share of the pressure sensors' noise.
POINTS, NOISE_SHARE = 1e-2, 1e-1


def replay_errors(dyn, scenario: str, controller: str, counts, reference: int, duration=None, **overrides) -> dict:
    """The run of ``controller`` on ``scenario`` (its own count) replayed open loop under its commands at
    each count and at ``reference`` sub-steps: {"periods", "q_pts": {count: largest difference from the
    reference's replay, points of amplitude}, "p_pa": {count: Pa}, "noise_p": Pa, "failed": {count:
    period}} (a count whose replay is not finite). ``overrides``: scenario fields (``pressure_bounds``)."""
    p = prepare_run(dyn, scenario, controller, None, duration, True, overrides, keep_logs=False)
    loop = PythonStages(dyn, p.sc, p.ctrl, p.x0.copy(), p.q0, p.estimate, p.h)
    start = loop.x.copy()
    commands = []

    def before_plant(s):  # the period's commands, before the plant moves
        commands.append((np.array(s.u_held, float), np.array(s.u_app, float)))

    for k in range(p.n):
        loop.k = k
        loop.run_period(p.noise[k], before_plant)

    def replay(n):
        x, out = start, np.empty((len(commands), start.size))
        for k, (u_held, u_app) in enumerate(commands):
            x = loop.integrate(x, u_held, u_app, n)
            out[k] = x
            if not np.all(np.isfinite(x)):
                return out[:k + 1]
        return out

    return {"periods": p.n, **_differences(dyn, p.sc, replay(reference), replay, counts)}


def _differences(dyn, sc, ref: np.ndarray, rows, counts) -> dict:
    """{"q_pts", "p_pa", "noise_p", "failed"} of the states ``rows(n)`` (one row per period; a row not
    finite ends them) of each count against the reference's ``ref``: the largest difference of the
    coordinates in points of ``sc``'s reference amplitude and of the pressures in Pa; a count whose
    rows are not finite fails at the first such period, every count where the reference's are not."""
    layout = plant_layout(dyn.model)
    q, pc = slot(layout, "q").slice, slot(layout, "pc").slice
    amplitude = np.asarray(sc.reference.amplitude(), float)
    moving = amplitude > 0

    def first_bad(xs):
        bad = np.flatnonzero(~np.all(np.isfinite(xs), axis=1))
        return int(bad[0]) if bad.size else None

    q_pts, p_pa, failed = {}, {}, {}
    ref_bad = first_bad(ref)
    for n in counts:
        if ref_bad is not None:  # no reference to compare with: every count fails where it stopped
            failed[n] = ref_bad
            continue
        xs = rows(n)
        bad = first_bad(xs)
        if bad is not None:
            failed[n] = bad
            continue
        q_pts[n] = float((np.abs(xs[:, q] - ref[:, q])[:, moving] / amplitude[moving] * 100.0).max(initial=0.0))
        p_pa[n] = float(np.abs(xs[:, pc] - ref[:, pc]).max(initial=0.0))
    return {"q_pts": q_pts, "p_pa": p_pa, "noise_p": float(sc.noise_p), "failed": failed}


def predictor_errors(dyn, scenario: str, controller: str, counts, reference: int, duration=None) -> dict:
    """The run of ``controller`` on the predicting ``scenario`` (its own counts), each period's prediction
    made again from the same measured state and commands at each count of predictor steps per period
    and at ``reference``: {"periods", "q_pts": {count: largest difference of the predicted pose from the
    reference's, points of amplitude}, "p_pa": {count: of the predicted pressures, Pa}, "noise_p": Pa,
    "failed": {count: period}} (a count whose prediction is not finite)."""
    p = prepare_run(dyn, scenario, controller, None, duration, True, {}, keep_logs=False)
    loop = PythonStages(dyn, p.sc, p.ctrl, p.x0.copy(), p.q0, p.estimate, p.h)
    own, sc = loop.predicted, loop.sc
    tried = (*counts, reference)
    preds = {n: [] for n in tried}

    def predicted(s):  # every count from the one measured state and commands; the loop goes on with its own
        for n in tried:
            loop.sc = replace(sc, predictor_substeps=n)
            try:
                preds[n].append(own(s))
            finally:
                loop.sc = sc
        mine = preds.get(sc.predictor_substeps)
        return mine[-1].copy() if mine is not None else own(s)

    loop.predicted = predicted
    for k in range(p.n):
        loop.k = k
        loop.run_period(p.noise[k])
    rows = {n: np.array(v) for n, v in preds.items()}
    return {"periods": p.n, "predictor_substeps": int(sc.predictor_substeps),
            **_differences(dyn, sc, rows[reference], rows.get, counts)}


def keeps(e: dict, n: int) -> bool:
    """Whether count ``n`` keeps the errors on the replay ``e``."""
    return n not in e["failed"] and e["q_pts"][n] < POINTS and e["p_pa"][n] < NOISE_SHARE * e["noise_p"]


def cheapest(counts, e: dict) -> int | None:
    """The smallest count from which every larger tested count keeps the errors."""
    ok = [keeps(e, n) for n in counts]
    return next((n for i, n in enumerate(counts) if all(ok[i:])), None)


def _robot(name: str, quick: bool) -> tuple:
    """(model, the controllers replayed, their dynamics) of robot ``name``."""
    model = hydrogen.load_model(name)
    controllers = CONTROLLERS[:1] if quick else CONTROLLERS
    return model, controllers, hydrogen.build(model, controllers=controllers)


def run_robot(name: str, quick: bool = False) -> dict:
    model, controllers, dyn = _robot(name, quick)
    counts, reference = (QUICK_COUNTS, QUICK_REFERENCE) if quick else (COUNTS, REFERENCE)
    rows = []
    for scen in rig_scenarios(model, quick):
        for c in controllers:
            for bounds in SCHEMES:
                e = replay_errors(dyn, scen, c, counts, reference, QUICK_DURATION if quick else None,
                                  pressure_bounds=bounds)
                rows.append({"scenario": scen, "controller": c, "pressure_bounds": bounds,
                             "substeps": named_scenario(scen, model).substeps, **e, "cheapest": cheapest(counts, e)})
    return {"model": name, "rows": rows}


def predictor_robot(name: str, quick: bool = False) -> dict:
    """The predictor's replay errors (:func:`predictor_errors`) of ``name``'s predicting rig scenarios."""
    model, controllers, dyn = _robot(name, quick)
    counts, reference = (QUICK_PREDICTOR_COUNTS, QUICK_REFERENCE) if quick else (PREDICTOR_COUNTS, REFERENCE)
    rows = []
    for scen in predicting_scenarios(model, quick):
        for c in controllers:
            e = predictor_errors(dyn, scen, c, counts, reference, QUICK_DURATION if quick else None)
            rows.append({"scenario": scen, "controller": c, **e, "cheapest": cheapest(counts, e)})
    return {"model": name, "rows": rows}


#: The parts of the benchmark (``--part``): the plant's replay, the predictor's.
PARTS = ("plant", "predictor")


def run(quick: bool = False, part: str | None = None) -> dict:
    t0 = time.perf_counter()
    names = hydrogen.models()[:1] if quick else hydrogen.models()
    out = {"counts": list(QUICK_COUNTS if quick else COUNTS), "schemes": list(SCHEMES),
           "reference": QUICK_REFERENCE if quick else REFERENCE, "points": POINTS, "noise_share": NOISE_SHARE,
           "quick": quick, "controllers": list(CONTROLLERS), "machine": common.machine_info(), "cores": os.cpu_count()}
    if part in (None, "plant"):
        out["robots"] = [run_robot(n, quick) for n in names]
    if part in (None, "predictor"):
        out["predictor"] = {"counts": list(QUICK_PREDICTOR_COUNTS if quick else PREDICTOR_COUNTS),
                            "robots": [predictor_robot(n, quick) for n in names]}
    out["wall_s"] = time.perf_counter() - t0
    return out


def _cells(r, counts) -> str:
    return " ".join(f"{n}: {r['q_pts'][n]:.1e} / {r['p_pa'][n]:.1e}" if n not in r["failed"]
                    else f"{n}: fails" for n in counts)


def print_table(res: dict) -> None:
    keep = f"keeps: < {res['points']:g} point and < {res['noise_share']:g} of the pressure noise"
    if "robots" in res:
        print(f"each controller's trajectory replayed open loop at each sub-step count against {res['reference']}: "
              f"largest difference over the run, coordinates in points of amplitude, pressures in Pa; {keep}")
        for rob in res["robots"]:
            for r in rob["rows"]:
                print(f"{rob['model']:14} {r['scenario']:22} {r['controller']:13} {r['pressure_bounds']:5} "
                      f"now {r['substeps']:2} cheapest {r['cheapest']}  {_cells(r, res['counts'])}")
    pred = res.get("predictor")
    if pred:
        print(f"each period's delay prediction made again at each count of predictor steps against "
              f"{res['reference']}: largest difference over the run of the predicted pose (points of amplitude) "
              f"and pressures (Pa); {keep}")
        for rob in pred["robots"]:
            for r in rob["rows"]:
                print(f"{rob['model']:14} {r['scenario']:22} {r['controller']:13} now {r['predictor_substeps']:2} "
                      f"cheapest {r['cheapest']}  {_cells(r, pred['counts'])}")


def main(argv=None) -> int:
    return common.script_main(__doc__, run, print_table, argv,
                              {"--part": dict(choices=PARTS, default=None, help="run this part alone")})


if __name__ == "__main__":
    sys.exit(main())
