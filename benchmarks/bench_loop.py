"""Cost per control period of the paper-sim loop with adaptive-robust, through four routes, in one run.

(a) the loop in Python with ``sympy.lambdify`` (numpy) functions,
(b) the loop in Python with CasADi Functions called from Python,
(c) the hydrogen stepping API from Python (one call into C per period),
(d) the whole loop in C (``hydrogen.simulate``'s default engine),
plus paper-sim's real-time factor through ``hydrogen.simulate`` (the whole call, setup included)
and how a parallel sweep scales. Every route runs the same loop (sensors, Newton forward
kinematics, controller, 2 RK4 plant sub-steps) and is checked to give the same trajectory before
it is timed.

The sweep is timed in a fresh Python process, as a user's script would call it: timed in this
process, right after the routes, it once scaled only 1.54x (cause not pinned down; README).

Run: ``python benchmarks/bench_loop.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import argparse
import json
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
from hydrogen.dynamics import Dynamics
from hydrogen.simulation import simulator as S
from hydrogen.symbolic.functions import derive_functions

try:  # imported as benchmarks.bench_loop
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

SCENARIO, CONTROLLER = "paper-sim", "adaptive-robust"


class _Fn:
    """Same call contract as the compiled functions: numpy in, numpy out, names of the inputs."""

    def __init__(self, sf):
        self.name = sf.name
        self.in_names = [n for n, _ in sf.inputs]
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
        self.in_shapes = [m.shape for _, m in sf.inputs]
        known = [s for syms in self.in_syms for s in syms]
        self.stages = []
        for symbols, expr in sf.intermediates:
            target = expr[1] if isinstance(expr, tuple) else expr
            self.stages.append((list(symbols), isinstance(expr, tuple), target.shape,
                                sp.lambdify(list(known), list(target), "numpy")))
            known = known + list(symbols)
        self.outs = [(e.shape, sp.lambdify(list(known), list(e), "numpy")) for _, e in sf.outputs]

    def __call__(self, *args):
        # numpy scalars, not Python floats: numpy.select evaluates every Piecewise branch, and a
        # branch guarded against division by zero must give inf there, not raise.
        vals = []
        for a, shape in zip(args, self.in_shapes):
            vals.extend(np.reshape(np.asarray(a, float), shape).ravel())
        with np.errstate(all="ignore"):
            for symbols, inverse, shape, f in self.stages:
                v = np.array(f(*vals), float)
                if inverse:
                    v = np.linalg.inv(v.reshape(shape)).ravel()
                vals.extend(v)
            return self._pack([np.array(f(*vals), float).reshape(shape) for shape, f in self.outs])


def proxy_dynamics(model, kind):
    """A Dynamics whose functions are CasADi or lambdify routes instead of the compiled library."""
    make = CasadiFn if kind == "casadi" else LambdifyFn
    wanted = {"leg_lengths", "leg_jacobian", "mass_matrix", "coriolis", "gravity", "regressor",
              "plant_rhs", f"ctrl_{CONTROLLER.replace('-', '_')}"}
    fns = {sf.name: make(sf) for sf in derive_functions(model) if sf.name in wanted}
    fns.update({n: None for n in ("valve_flow", "valve_inverse", "pressure_rate", "leg_force")})
    return Dynamics(model, SimpleNamespace(functions=fns, _lib=None))


def python_loop_per_period(dyn, n_periods):
    """Seconds per period of the Python loop (engine 'python') over ``n_periods`` periods; and its q."""
    p = S._prepare(dyn, SCENARIO, CONTROLLER, None, (n_periods - 1) / 1000.0, False, {})
    log = {k: np.full((p.n, w), np.nan) for k, w in (("q", 6), ("q_d", 6), ("l", 6), ("f", 6), ("pc", 6),
                                                        ("u", 6), ("xc", max(p.ctrl.xc.size, 1)))}
    t0 = time.perf_counter()
    S._run_python(dyn, p.sc, p.ctrl, p.x0, p.q0, p.noise, p.kf_gain, log, p.n, p.h)
    return (time.perf_counter() - t0) / p.n, log["q"]


def stepping_per_period(dyn, n_periods):
    st = hydrogen.stepper(SCENARIO, CONTROLLER, dyn=dyn, duration=n_periods / 1000.0)
    t0 = time.perf_counter()
    for _ in range(n_periods):
        st.step()
    return (time.perf_counter() - t0) / n_periods


def c_loop_per_period(dyn, n_periods):
    p = S._prepare(dyn, SCENARIO, CONTROLLER, None, n_periods / 1000.0, False, {})
    runner = S._make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.kf_gain, p.h)
    t0 = time.perf_counter()
    code = runner.run(n_periods, p.noise, None)
    assert code == 0
    return (time.perf_counter() - t0) / n_periods


#: A user's sweep script: 8 P-gain runs of z-1hz, a new default process pool per call; the median
#: of ``repeats`` sweeps per worker count.
_SWEEP = """
import statistics, time
import numpy as np
import hydrogen
runs = [dict(scenario="z-1hz", controller="p", gains={{"Kleg": float(k)}}, duration={duration})
        for k in np.geomspace(0.02, 0.3, 8)]
hydrogen.simulate(**runs[0])  # build once, as any first call does
for w in (1, 2):
    rates = []
    for _ in range({repeats}):
        t0 = time.perf_counter()
        hydrogen.sweep(runs, max_workers=w)
        rates.append(len(runs) / (time.perf_counter() - t0))
    print(f"runs_per_s_{{w}}", statistics.median(rates))
"""


def _median(f, repeats):
    return statistics.median(f() for _ in range(repeats))


def run(quick: bool = False) -> dict:
    model = hydrogen.load_model()
    dyn = hydrogen.build(model)
    repeats = 3 if quick else 5
    n_a, n_b, n_c, n_d = (20, 100, 2000, 10000) if quick else (50, 300, 10000, 10001)
    # correctness first: each route reproduces the compiled trajectory
    ref = hydrogen.simulate(SCENARIO, CONTROLLER, dyn=dyn, duration=(n_a - 1) / 1000.0)
    dyn_a, dyn_b = proxy_dynamics(model, "lambdify"), proxy_dynamics(model, "casadi")
    for d in (dyn_a, dyn_b):
        _, q = python_loop_per_period(d, n_a)
        np.testing.assert_allclose(q, ref.q, atol=1e-9)
    routes = {
        "a_lambdify_python_loop": _median(lambda: python_loop_per_period(dyn_a, n_a)[0], repeats),
        "b_casadi_python_loop": _median(lambda: python_loop_per_period(dyn_b, n_b)[0], repeats),
        "c_stepping_api": _median(lambda: stepping_per_period(dyn, n_c), repeats),
        "d_c_loop": _median(lambda: c_loop_per_period(dyn, n_d), repeats),
    }
    base = routes["d_c_loop"]
    out = {"per_period_us": {k: v * 1e6 for k, v in routes.items()},
           "ratio_to_c_loop": {k: v / base for k, v in routes.items()}}
    out["stepping_overhead_us"] = (routes["c_stepping_api"] - base) * 1e6
    # paper-sim, 10 s simulated, through hydrogen.simulate (setup included)
    walls, totals = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        walls.append(hydrogen.simulate(SCENARIO, CONTROLLER, dyn=dyn).loop_wall_s)
        totals.append(time.perf_counter() - t0)
    total = statistics.median(totals)
    out["paper_sim"] = {"sim_time_s": 10.0, "loop_wall_s": statistics.median(walls),
                        "simulate_call_wall_s": total, "real_time_factor": 10.0 / total}
    # sweeps: the same 8 runs with 1 and 2 workers, in a fresh process
    stdout, _ = common.run_python(_SWEEP.format(duration=2.0 if quick else 6.0, repeats=repeats))
    scale = {w: common.parse_keyed(stdout)[f"runs_per_s_{w}"] for w in (1, 2)}
    out["sweep_runs_per_s"] = {str(k): v for k, v in scale.items()}
    out["sweep_speedup_2_over_1"] = scale[2] / scale[1]
    out["cores"] = os.cpu_count()
    return out


def print_table(res):
    sc = hydrogen.simulation.scenarios.scenario(SCENARIO, hydrogen.load_model())
    print(f"paper-sim loop with {CONTROLLER}, per control period ({sc.control_rate:.0f} Hz, "
          f"{sc.substeps} RK4 sub-steps), medians:")
    print(f"{'route':28} {'us/period':>12} {'ratio to (d)':>14}")
    for k, v in res["per_period_us"].items():
        print(f"{k:28} {v:12.2f} {res['ratio_to_c_loop'][k]:14.1f}")
    print(f"stepping API overhead above the C work: {res['stepping_overhead_us']:.2f} us per period")
    ps = res["paper_sim"]
    print(f"paper-sim, 10 s simulated: hydrogen.simulate takes {ps['simulate_call_wall_s'] * 1e3:.1f} ms "
          f"-> {ps['real_time_factor']:.0f}x real time")
    print(f"sweep: {res['sweep_runs_per_s']['1']:.2f} runs/s with 1 worker, {res['sweep_runs_per_s']['2']:.2f} "
          f"with 2 ({res['sweep_speedup_2_over_1']:.2f}x, {res['cores']} cores)")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    r = run(quick=a.quick)
    print_table(r)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(r, fh, indent=2)
