"""Compiler flags: compile time from a clean cache and the C loop's cost per period, per flag set,
for every shipped robot (its simulation scenario with adaptive-robust).

Chooses the runtime's default flags (hydrogen/runtime/compiler.py) by measurement. The C is
generated once per robot into a temporary folder, so each clean build compiles only (even when
the committed generated/ folder is stale by its hash and ``build()`` would regenerate it).
Run: ``python benchmarks/bench_flags.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import hydrogen
from hydrogen.codegen.generate import generate
from hydrogen.simulation import simulator as S

try:  # imported as benchmarks.bench_flags
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

CONTROLLER = "adaptive-robust"
#: -fno-semantic-interposition (nsi) lets the compiler inline CasADi's exported one-line helpers
#: (casadi_sq, casadi_fmin, ...) inside a shared library; without it each is a call through the PLT.
FLAG_SETS = {
    "-O1": ("-O1", "-fPIC", "-std=c99"),
    "-O2": ("-O2", "-fPIC", "-std=c99"),
    "-O2 nsi (default)": ("-O2", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
    "-O3 nsi": ("-O3", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
    "-O3 nsi -march=native": ("-O3", "-march=native", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
}


def _loop_us(dyn, scenario, repeats):
    p = S.prepare_run(dyn, scenario, CONTROLLER, None, None, False, {})
    times = []
    for _ in range(repeats):
        runner = S.make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.kf_gain, p.h)
        t0 = time.perf_counter()
        code = runner.run(p.n, p.noise, None)
        times.append((time.perf_counter() - t0) / p.n * 1e6)
        if code != 0:
            raise RuntimeError(f"{dyn.model.name} {scenario}: the C loop stopped with code {code}")
    return statistics.median(times)


def run_robot(name: str, quick: bool = False) -> dict:
    model = hydrogen.load_model(name)
    scenario = common.sim_scenario(model)
    out = {"model": name, "scenario": scenario, "flags": {}}
    with tempfile.TemporaryDirectory(prefix="bench_flags_") as tmp:
        folder = Path(tmp) / "generated" / name
        generate(model, folder)
        for label, flags in FLAG_SETS.items():
            cache = Path(tmp) / f"cache{len(out['flags'])}"
            t0 = time.perf_counter()
            dyn = hydrogen.build(model, cflags=flags, cache=cache, generated=folder)
            compile_s = time.perf_counter() - t0
            out["flags"][label] = {"cflags": list(flags), "compile_s": compile_s,
                                   "loop_us_per_period": _loop_us(dyn, scenario, 3 if quick else 7)}
    return out


def run(quick: bool = False) -> dict:
    return {"robots": {name: run_robot(name, quick) for name in common.robots()}, "quick": quick}


def print_table(res):
    for r in res["robots"].values():
        print(f"{r['model']}: {r['scenario']} with {CONTROLLER}")
        print(f"{'flags':24} {'compile s':>10} {'loop us/period':>15}")
        for k, v in r["flags"].items():
            print(f"{k:24} {v['compile_s']:10.2f} {v['loop_us_per_period']:15.2f}")
        print()


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
