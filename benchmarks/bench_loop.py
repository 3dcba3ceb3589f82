"""Cost per control period of each robot's simulation loop with adaptive-robust, through four routes.

For every shipped robot (``hydrogen.models()``) its simulation scenario (the first one of its
description on the ideal plant: paper-sim for the Stewart platform, arm-sim for the arm) runs

(a) the loop in Python with ``sympy.lambdify`` (numpy) functions,
(b) the loop in Python with CasADi Functions called from Python,
(c) the hydrogen stepping API from Python (one call into C per period),
(d) the whole loop in C (``hydrogen.simulate``'s default engine),
plus the scenario's real-time factor through ``hydrogen.simulate`` (the whole call, setup included)
and how a parallel sweep of its first experiment-like scenario (P gains) scales. Every route runs the same loop (sensors, Newton forward
kinematics, controller, 2 RK4 plant sub-steps) and is checked to give the same trajectory before
it is timed.

Sizes, names and the scenarios come from each robot's description. The sweep is timed in a fresh
Python process, as a user's script would call it: timed in this
process, right after the routes, it once scaled only 1.54x (cause not pinned down; README).

Run: ``python benchmarks/bench_loop.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import sympy as sp

import hydrogen
import hydrogen.simulation.scenarios
from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.controllers import function_name, rates_function_name
from hydrogen.dynamics import Dynamics
from hydrogen.simulation import simulator as S
from hydrogen.symbolic.functions import derive_functions

try:  # imported as benchmarks.bench_loop
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

CONTROLLER = "adaptive-robust"
#: The sweep's P gains: the robot's default Kleg times these factors (for the Stewart platform,
#: whose Kleg is 0.0358, the 0.02-0.3 of the previous runs).
KLEG_FACTORS = np.geomspace(0.02 / 0.0358, 0.3 / 0.0358, 8)


class _Fn:
    """Same call contract as the compiled functions: numpy in, numpy out, names of the inputs."""

    def __init__(self, sf):
        self.name = sf.name
        self.in_names = [n for n, _ in sf.inputs]
        self.arg_names = list(self.in_names)  # the argument order, as a compiled function's (no hidden input)
        self.in_shapes = [m.shape for _, m in sf.inputs]
        self._vec = [m.shape[1] == 1 for _, m in sf.outputs]
        self._single = len(sf.outputs) == 1

    def clone(self):
        return self  # no shared C buffers to separate

    def _pack(self, outs):
        outs = [np.asarray(o, float) for o in outs]
        outs = [o.reshape(-1) if v else o for o, v in zip(outs, self._vec)]
        return outs[0] if self._single else tuple(outs)


class CasadiFn(_Fn):
    """(b): a casadi.Function called from Python for each evaluation."""

    def __init__(self, sf):
        super().__init__(sf)
        self.f = to_casadi_function(sf)

    def __call__(self, *args):
        out = self.f(*args)
        return self._pack([o.full() for o in (out if isinstance(out, tuple) else (out,))])


class LambdifyFn(_Fn):
    """(a): SymPy's lambdify (numpy), one lambdified function per intermediate stage."""

    def __init__(self, sf):
        super().__init__(sf)
        self.in_syms = [list(m) for _, m in sf.inputs]  # row-major entries per input
        known = [s for syms in self.in_syms for s in syms]
        self.stages = []
        for symbols, expr in sf.intermediates:
            kind = expr[0] if isinstance(expr, tuple) else None  # "inverse" M, "solve" A b, or None
            parts = expr[1:] if kind else (expr,)
            self.stages.append((list(symbols), kind, [p.shape for p in parts],
                                [sp.lambdify(list(known), list(p), "numpy") for p in parts]))
            known = known + list(symbols)
        self.outs = [(e.shape, sp.lambdify(list(known), list(e), "numpy")) for _, e in sf.outputs]

    def __call__(self, *args):
        # numpy scalars, not Python floats: numpy.select evaluates every Piecewise branch, and a
        # branch guarded against division by zero must give inf there, not raise.
        vals = []
        for a, shape in zip(args, self.in_shapes):
            vals.extend(np.reshape(np.asarray(a, float), shape).ravel())
        with np.errstate(all="ignore"):
            for symbols, kind, shapes, fs in self.stages:
                parts = [np.array(f(*vals), float).reshape(shape) for f, shape in zip(fs, shapes)]
                if kind == "inverse":
                    v = np.linalg.inv(parts[0])
                elif kind == "solve":
                    v = np.linalg.solve(parts[0], parts[1])
                else:
                    v = parts[0]
                vals.extend(v.ravel())
            return self._pack([np.array(f(*vals), float).reshape(shape) for shape, f in self.outs])


#: What the Python loop calls besides the controller (Dynamics, the plant, the regressor offset).
_LOOP_FUNCTIONS = ("leg_lengths", "leg_jacobian", "mass_matrix", "coriolis", "gravity", "regressor",
                   "regressor_offset", "plant_rhs")


def proxy_dynamics(model, kind, functions=None, compiled=None):
    """A Dynamics whose functions are CasADi or lambdify routes instead of the compiled library
    (``functions``: the model's derived functions, derived here when not given). Forward kinematics
    has one implementation, the compiled loop driver's: it comes from the library ``compiled``
    (a robot without joint encoders needs it)."""
    make = CasadiFn if kind == "casadi" else LambdifyFn
    wanted = {*_LOOP_FUNCTIONS, function_name(CONTROLLER), rates_function_name(CONTROLLER)}
    fns = {sf.name: make(sf) for sf in (functions or derive_functions(model)) if sf.name in wanted}
    fns.update({n: None for n in ("valve_flow", "valve_inverse", "pressure_rate", "leg_force")})
    driver = {} if compiled is None else {"symbol": compiled.symbol, "numbers": compiled.numbers}
    return Dynamics(model, SimpleNamespace(functions=fns, **driver))


def python_loop_per_period(dyn, scenario, n_periods):
    """Seconds per period of the Python loop (engine 'python') over ``n_periods`` periods; and its q."""
    rate = common.periods_per_s(dyn, scenario)
    p = S.prepare_run(dyn, scenario, CONTROLLER, None, (n_periods - 1) / rate, False, {})
    log = S.new_logs(dyn.model, p.n, p.ctrl.xc.size)
    t0 = time.perf_counter()
    k, failure = S.run_python_loop(dyn, p.sc, p.ctrl, p.x0, p.q0, p.noise, p.estimate, log, p.n, p.h)
    wall = time.perf_counter() - t0
    if failure:
        raise RuntimeError(f"{dyn.model.name} {scenario}: the Python loop {failure}")
    return wall / p.n, log["q"]


def stepping_per_period(dyn, scenario, n_periods):
    st = hydrogen.stepper(scenario, CONTROLLER, dyn=dyn, duration=n_periods / common.periods_per_s(dyn, scenario))
    n_periods = min(n_periods, st.n_max)
    t0 = time.perf_counter()
    for _ in range(n_periods):
        st.step()
    return (time.perf_counter() - t0) / n_periods


def c_loop_per_period(dyn, scenario, n_periods):
    return common.c_loop_per_period(dyn, scenario, CONTROLLER, n_periods)


#: A user's sweep script: 8 P-gain runs of the robot's experiment-like scenario, a new default
#: process pool per call; the median of ``repeats`` sweeps per worker count.
_SWEEP = """
import statistics, time
import numpy as np
import hydrogen
from hydrogen.simulation.control import default_gains
model = hydrogen.load_model({model!r})
dyn = hydrogen.build(model)  # build once, as any first call does
kleg = default_gains(dyn, "p")["Kleg"]
runs = [dict(scenario={scenario!r}, controller="p", gains={{"Kleg": (kleg * float(k)).tolist()}},
             duration={duration}) for k in {factors!r}]
hydrogen.simulate(**runs[0], model=model)
for w in (1, 2):
    rates = []
    for _ in range({repeats}):
        t0 = time.perf_counter()
        out = hydrogen.sweep(runs, max_workers=w, model={model!r})
        rates.append(len(runs) / (time.perf_counter() - t0))
    print(f"runs_per_s_{{w}}", statistics.median(rates))
print("failed_runs", sum(1 for r in out if not isinstance(r, dict) or "error" in r))
"""


def _median(f, repeats):
    return statistics.median(f() for _ in range(repeats))


def run_robot(name: str, quick: bool = False) -> dict:
    """The four routes, the real-time factor and the sweep for robot ``name``."""
    model = hydrogen.load_model(name)
    dyn = hydrogen.build(model)
    scenario = common.sim_scenario(model)
    rate = common.periods_per_s(dyn, scenario)
    repeats = 3 if quick else 5
    n_a, n_b, n_c, n_d = (20, 100, 2000, 10000) if quick else (50, 300, 10000, 10001)
    # correctness first: each route reproduces the compiled trajectory
    ref = hydrogen.simulate(scenario, CONTROLLER, dyn=dyn, duration=(n_a - 1) / rate)
    functions = derive_functions(model)
    dyn_a, dyn_b = (proxy_dynamics(model, k, functions, dyn.library) for k in ("lambdify", "casadi"))
    worst = {}
    for key, d in (("a_lambdify_python_loop", dyn_a), ("b_casadi_python_loop", dyn_b)):
        _, q = python_loop_per_period(d, scenario, n_a)
        np.testing.assert_allclose(q, ref.q, atol=1e-9, err_msg=f"{name} {scenario}: route {key}")
        worst[key] = float(np.max(np.abs(q - ref.q)))
    routes = {
        "a_lambdify_python_loop": _median(lambda: python_loop_per_period(dyn_a, scenario, n_a)[0], repeats),
        "b_casadi_python_loop": _median(lambda: python_loop_per_period(dyn_b, scenario, n_b)[0], repeats),
        "c_stepping_api": _median(lambda: stepping_per_period(dyn, scenario, n_c), repeats),
        "d_c_loop": _median(lambda: c_loop_per_period(dyn, scenario, n_d), repeats),
    }
    base = routes["d_c_loop"]
    sc = hydrogen.simulation.scenarios.scenario(scenario, model)
    out = {"model": name, "n": model.n, "scenario": scenario, "controller": CONTROLLER,
           "control_rate_hz": sc.control_rate, "substeps": sc.substeps,
           "per_period_us": {k: v * 1e6 for k, v in routes.items()},
           "ratio_to_c_loop": {k: v / base for k, v in routes.items()},
           "check_max_abs_dq": worst, "check_periods": n_a}
    out["stepping_overhead_us"] = (routes["c_stepping_api"] - base) * 1e6
    # the whole scenario through hydrogen.simulate (setup included)
    walls, totals = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        walls.append(hydrogen.simulate(scenario, CONTROLLER, dyn=dyn).loop_wall_s)
        totals.append(time.perf_counter() - t0)
    total = statistics.median(totals)
    out["sim"] = {"scenario": scenario, "sim_time_s": sc.duration, "loop_wall_s": statistics.median(walls),
                  "simulate_call_wall_s": total, "real_time_factor": sc.duration / total}
    # sweeps: the same 8 runs with 1 and 2 workers, in a fresh process
    rig = common.rig_scenario(model)
    if rig is None:
        out["sweep"] = None
    else:
        stdout, _ = common.run_python(_SWEEP.format(model=name, scenario=rig, duration=2.0 if quick else 6.0,
                                                    repeats=repeats, factors=KLEG_FACTORS.tolist()))
        keyed = common.parse_keyed(stdout)
        scale = {w: keyed[f"runs_per_s_{w}"] for w in (1, 2)}
        out["sweep"] = {"scenario": rig, "runs": len(KLEG_FACTORS), "failed_runs": int(keyed.get("failed_runs", 0)),
                        "runs_per_s": {str(k): v for k, v in scale.items()}, "speedup_2_over_1": scale[2] / scale[1]}
    out["cores"] = os.cpu_count()
    return out


def run(quick: bool = False) -> dict:
    return {"robots": {name: run_robot(name, quick) for name in common.robots()}, "quick": quick,
            "cores": os.cpu_count()}


def print_table(res):
    for r in res["robots"].values():
        print(f"{r['model']} (n = {r['n']}): {r['scenario']} loop with {r['controller']}, per control period "
              f"({r['control_rate_hz']:.0f} Hz, {r['substeps']} RK4 sub-steps), medians:")
        print(f"{'route':28} {'us/period':>12} {'ratio to (d)':>14}")
        for k, v in r["per_period_us"].items():
            print(f"{k:28} {v:12.2f} {r['ratio_to_c_loop'][k]:14.1f}")
        print(f"stepping API overhead above the C work: {r['stepping_overhead_us']:.2f} us per period")
        ps = r["sim"]
        print(f"{ps['scenario']}, {ps['sim_time_s']:g} s simulated: hydrogen.simulate takes "
              f"{ps['simulate_call_wall_s'] * 1e3:.1f} ms -> {ps['real_time_factor']:.0f}x real time")
        sw = r["sweep"]
        if sw:
            failed = f", {sw['failed_runs']} of {sw['runs']} runs failed" if sw["failed_runs"] else ""
            print(f"sweep ({sw['runs']} P-gain runs of {sw['scenario']}): {sw['runs_per_s']['1']:.2f} runs/s with "
                  f"1 worker, {sw['runs_per_s']['2']:.2f} with 2 ({sw['speedup_2_over_1']:.2f}x, "
                  f"{r['cores']} cores){failed}")
        print()


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
