"""Compiler flags: compile time from a clean cache and the C loop's cost per period, per flag set.

Chooses the runtime's default flags (hydrogen/runtime/compiler.py) by measurement.
Run: ``python benchmarks/bench_flags.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time

import hydrogen
from hydrogen.simulation import simulator as S

#: -fno-semantic-interposition (nsi) lets the compiler inline CasADi's exported one-line helpers
#: (casadi_sq, casadi_fmin, ...) inside a shared library; without it each is a call through the PLT.
FLAG_SETS = {
    "-O1": ("-O1", "-fPIC", "-std=c99"),
    "-O2": ("-O2", "-fPIC", "-std=c99"),
    "-O2 nsi (default)": ("-O2", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
    "-O3 nsi": ("-O3", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
    "-O3 nsi -march=native": ("-O3", "-march=native", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
}


def _loop_us(dyn, repeats):
    p = S._prepare(dyn, "paper-sim", "adaptive-robust", None, 10.0, False, {})
    times = []
    for _ in range(repeats):
        runner = S._make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.kf_gain, p.h)
        t0 = time.perf_counter()
        runner.run(p.n, p.noise, None)
        times.append((time.perf_counter() - t0) / p.n * 1e6)
    return statistics.median(times)


def run(quick: bool = False) -> dict:
    model = hydrogen.load_model()
    out = {}
    for name, flags in FLAG_SETS.items():
        with tempfile.TemporaryDirectory() as cache:
            t0 = time.perf_counter()
            dyn = hydrogen.build(model, cflags=flags, cache=cache)
            compile_s = time.perf_counter() - t0
            out[name] = {"compile_s": compile_s, "loop_us_per_period": _loop_us(dyn, 3 if quick else 7)}
    return out


def print_table(res):
    print(f"{'flags':20} {'compile s':>10} {'loop us/period':>15}")
    for k, v in res.items():
        print(f"{k:20} {v['compile_s']:10.2f} {v['loop_us_per_period']:15.2f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    r = run(a.quick)
    print_table(r)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(r, fh, indent=2)
