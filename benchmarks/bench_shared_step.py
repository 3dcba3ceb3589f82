"""The semi-implicit step with the controller inlined against the step that calls it.

A controller with a state (the adaptive ones) is generated three times in one library: the
controller (command and state rates), its rates alone, and the semi-implicit step the C loop calls
each period, ``u = U(y, clip(xc + h F(y, xc)))``. The shipped step inlines the controller and the
rates in one graph, so CasADi's common-subexpression elimination computes what depends on the
measurement only (kinematics, regressor, the desired force) once, but its C repeats the
controller's. The alternative compiles the controller once: the step as two calls of the
controller's and the rates' functions, in the same C file (CasADi writes a function another calls
once). Per shipped robot and controller with a state (full variant, the numbers as inputs), both
layouts are generated in one run, checked to agree (relative 1e-12), and measured side by side:
the step's C cost per call (the ``bench_functions`` driver, same flags) and the cost of compiling
the variant's library (every source of it compiled to objects as a build does, largest first: one
compiler at a time, about the CPU seconds, and on all usable cores, the wall seconds a run waits). The step runs once per control period, so
its extra cost is also given against the scenario's C loop period (``common.c_loop_per_period``).

Run: ``python benchmarks/bench_shared_step.py [--quick] [--json FILE]`` (about 2 minutes).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:  # imported as benchmarks.bench_shared_step
    from . import bench_functions, common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_functions
    import common

#: Relative agreement of the two steps' outputs.
AGREEMENT_RTOL = 1e-12
#: Periods of the scenario's C loop timed for the per-period context.
LOOP_PERIODS = 4000


def calls_step(step, ctrl, rates, c_name: str):
    """The CasADi Function of the step as calls: ``step``'s inputs and outputs, ``rates`` and
    ``ctrl`` (named as in the library) called, not inlined (an MX graph of two calls)."""
    import casadi as ca

    names = list(step.name_in())
    args = {n: ca.MX.sym(n, step.sparsity_in(i)) for i, n in enumerate(names)}
    xc_dot = rates.call({n: args[n] for n in rates.name_in()})[rates.name_out(0)]
    moved = args["xc"] + args["h"] * xc_dot
    lo, hi = args["xc_lo"], args["xc_hi"]
    xc_next = ca.if_else(moved < lo, lo, ca.if_else(moved > hi, hi, moved))  # the shipped step's clip
    u = ctrl.call({n: xc_next if n == "xc" else args[n] for n in ctrl.name_in()})[ctrl.name_out(0)]
    return ca.Function(c_name, [args[n] for n in names], [u, xc_next], names, list(step.name_out()))


def _entry(fun, source: str) -> dict:
    return {"c_name": fun.name(), "source": source, "header": source[:-2] + ".h",
            "outputs": [[fun.name_out(i), *fun.size_out(i)] for i in range(fun.n_out())],
            "instructions": fun.n_instructions() if fun.is_a("SXFunction") else None}


def compile_cost(sources: list, cc_path: str) -> dict:
    """Seconds of compiling ``sources`` to objects as a build does
    (:func:`hydrogen.runtime.compiler.compile_objects`, largest first): one compiler at a time
    (``serial_s``, about the CPU time) and on all usable cores (``wall_s``)."""
    from hydrogen.runtime.compiler import compile_objects, usable_cores

    out = {"files": len(sources)}
    for key, jobs in (("serial_s", 1), ("wall_s", usable_cores())):
        with tempfile.TemporaryDirectory(prefix="objects_") as objects:
            t0 = time.perf_counter()
            compile_objects(sources, Path(objects), [cc_path, *common.CFLAGS], timeout=600.0, jobs=jobs)
            out[key] = time.perf_counter() - t0
    return out


def run_robot(model, quick: bool = False, cc: str = "cc") -> dict:
    import hydrogen
    from hydrogen.codegen.casadi_functions import casadi_function
    from hydrogen.codegen.generate import c_name, derive, write_casadi, write_function
    from hydrogen.controllers import CONTROLLERS, function_name, rates_function_name, step_function_name

    cc_path = common.require_cc(cc)
    functions, _ = derive(model)
    by_name = {f.name: f for f in functions}
    dyn = hydrogen.build(model)
    values = common.InputValues(dyn)
    min_time = bench_functions.QUICK_MIN_TIME_S if quick else bench_functions.MIN_TIME_S
    scenario = common.sim_scenario(model)
    rows, jobs = {}, []
    with tempfile.TemporaryDirectory(prefix="bench_shared_step_") as tmp:
        for kind in CONTROLLERS:
            names = [function_name(kind), rates_function_name(kind), step_function_name(kind)]
            if names[2] not in by_name:
                continue  # no state, no step
            inl, calls = Path(tmp, kind, "inlined"), Path(tmp, kind, "calls")
            inl.mkdir(parents=True)
            calls.mkdir()
            cache = {}
            entries = [write_function(by_name[n], model.name, inl, cache) for n in names]
            ctrl, rates, step = (casadi_function(by_name[n], c_name=c_name(model.name, n), cache=cache)
                                 for n in names)
            shared = calls_step(step, ctrl, rates, c_name(model.name, names[2]))
            write_casadi([ctrl, rates, shared], shared.name(), calls)
            inputs = values.function_inputs(entries[2])
            args = [np.asarray(v, float) for _, v in inputs]
            worst = max(float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.maximum(1.0, np.abs(np.asarray(a))),
                                     initial=0.0))
                        for a, b in zip(step.call(args), shared.call(args)))
            jobs += [((kind, "inlined"), entries[2], inputs, inl),
                     ((kind, "calls"), _entry(shared, f"{shared.name()}.c"), inputs, calls)]
            rows[kind] = {
                "controller": kind, "largest_relative_difference": worst,
                "instructions": {"controller": ctrl.n_instructions(), "rates": rates.n_instructions(),
                                 "step_inlined": step.n_instructions()},
                "c_bytes": {"inlined": sum((inl / e["source"]).stat().st_size for e in entries),
                            "calls": (calls / f"{shared.name()}.c").stat().st_size},
                "compile": {"inlined": compile_cost([inl / e["source"] for e in entries], cc_path),
                            "calls": compile_cost([calls / f"{shared.name()}.c"], cc_path)},
            }
        timed, _ = bench_functions.time_drivers(jobs, min_time, cc_path)
    for kind, r in rows.items():
        a, b = timed[(kind, "inlined")]["ns_per_call"], timed[(kind, "calls")]["ns_per_call"]
        period = common.c_loop_per_period(dyn, scenario, kind, LOOP_PERIODS // (4 if quick else 1)) * 1e9
        r.update(ns_per_call={"inlined": a, "calls": b}, time_ratio=b / a, loop_period_ns=period,
                 period_increase=(b - a) / period)
    return {"model": model.name, "n": model.n, "scenario": scenario, "controllers": rows,
            "agree": all(r["largest_relative_difference"] <= AGREEMENT_RTOL for r in rows.values())}


def run(quick: bool = False, cc: str = "cc") -> dict:
    import hydrogen

    return {"robots": {name: run_robot(hydrogen.load_model(name), quick=quick, cc=cc) for name in common.robots()},
            "quick": quick, "machine": common.machine_info(cc), "agreement_rtol": AGREEMENT_RTOL}


def print_table(res: dict) -> None:
    m = res["machine"]
    print(f"machine : {m['processor']}, {m['cpu_count']} CPUs; {m['cc']}")
    header = (f"{'robot':<14} {'controller':<18} {'step ns: inlined':>16} {'calls':>7} {'ratio':>6} "
              f"{'+period':>8} {'compile CPU s: inl.':>19} {'calls':>6} {'wall s: inl.':>12} {'calls':>6}")
    print(header)
    print("-" * len(header))
    for rob in res["robots"].values():
        for kind, r in rob["controllers"].items():
            c = r["compile"]
            print(f"{rob['model']:<14} {kind:<18} {r['ns_per_call']['inlined']:>16.0f} {r['ns_per_call']['calls']:>7.0f} "
                  f"{r['time_ratio']:>5.2f}x {100 * r['period_increase']:>7.1f}% "
                  f"{c['inlined']['serial_s']:>19.2f} {c['calls']['serial_s']:>6.2f} "
                  f"{c['inlined']['wall_s']:>12.2f} {c['calls']['wall_s']:>6.2f}")
    ok = all(r["agree"] for r in res["robots"].values())
    print(f"the two steps {'agree' if ok else 'DO NOT AGREE'} (relative {res['agreement_rtol']:g}); +period: the "
          "extra step cost against the scenario's C loop period")


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
