"""Compiler flags: compile time from a clean cache and the C loop's cost per period, per flag set,
for every shipped robot (its simulation scenario with adaptive-robust).

Chooses the runtime's default flags (hydrogen/runtime/compiler.py) by measurement. The C is
generated once per robot into a temporary folder, so each clean build compiles only (even when
the committed generated/ folder is stale by its hash and ``build()`` would regenerate it).
Run: ``python benchmarks/bench_flags.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import shlex
import statistics
import sys
import tempfile
import time
from pathlib import Path

import hydrogen
from hydrogen.codegen.generate import generate
from hydrogen.runtime.compiler import DEFAULT_CFLAGS, GCC_CFLAGS, Toolchain, run_compiler
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
    "-O2 nsi": ("-O2", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
    "-O3 nsi": ("-O3", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
    "-O3 nsi -march=native": ("-O3", "-march=native", "-fPIC", "-std=c99", "-fno-semantic-interposition"),
}
#: With GCC, also its default (GCC_CFLAGS added): -fno-tree-fre turns off a pass that finds next to
#: nothing in CasADi's code and whose cost grows faster than a function (the chain's column shows it).
GCC_DEFAULT = "-O2 nsi no-fre (default with gcc)"


#: The default flags' row with another compiler than GCC (DEFAULT_CFLAGS alone).
OTHER_DEFAULT = "-O2 nsi no-contract (default)"


#: The flags of a quick build's unoptimized libraries (``Toolchain.unoptimized()``: the defaults at -O0):
#: what a first run after a structural edit gains in compile and pays per period.
QUICK = "-O0 (a quick build)"


def flag_sets(toolchain=None) -> dict:
    """The flag sets compared: :data:`QUICK`, :data:`FLAG_SETS`, and after -O2 nsi the compiler's
    default flags (:meth:`Toolchain.flags`: with GCC, :data:`GCC_DEFAULT`; else :data:`OTHER_DEFAULT`)."""
    sets = dict(FLAG_SETS)
    toolchain = toolchain or Toolchain()
    gcc = toolchain.is_gcc()
    items = list(sets.items())
    at = list(sets).index("-O2 nsi") + 1
    row = (GCC_DEFAULT, (*DEFAULT_CFLAGS, *GCC_CFLAGS)) if gcc else (OTHER_DEFAULT, DEFAULT_CFLAGS)
    quick = (QUICK, Toolchain(cc=toolchain.cc).unoptimized().flags())
    return dict([quick, *items[:at], row, *items[at:]])
#: The planar chain (bench_scaling.chain_description) whose largest source is compiled with each flag
#: set: its adaptive-robust controller's lean semi-implicit step, what its first adaptive run waits for.
CHAIN_N, CHAIN_N_QUICK = 12, 7


def _loop_us(dyn, scenario, repeats):
    p = S.prepare_run(dyn, scenario, CONTROLLER, None, None, False, {})
    times = []
    for _ in range(repeats):
        runner = S.make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
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
        for label, flags in flag_sets().items():
            cache = Path(tmp) / f"cache{len(out['flags'])}"
            t0 = time.perf_counter()
            # the core and the controller the loop runs (the variant its gains run), as a first run compiles
            dyn = hydrogen.build(model, cflags=flags, cache=cache, generated=folder, controllers=(CONTROLLER,))
            compile_s = time.perf_counter() - t0
            out["flags"][label] = {"cflags": list(flags), "compile_s": compile_s,
                                   "loop_us_per_period": _loop_us(dyn, scenario, 3 if quick else 7)}
    return out


def run_chain(quick: bool = False) -> dict:
    """Seconds to compile the chain's largest source to an object with each flag set (one compiler
    alone, the fastest of two)."""
    try:
        from .bench_scaling import chain_description
    except ImportError:
        from bench_scaling import chain_description
    from hydrogen.controllers import step_function_name
    from hydrogen.model import model_from_dict

    n = CHAIN_N_QUICK if quick else CHAIN_N
    model = model_from_dict(chain_description(n))
    out = {"n": n, "source": None, "source_kb": None, "compile_s": {}}
    with tempfile.TemporaryDirectory(prefix="bench_flags_chain_") as tmp:
        folder = Path(tmp) / model.name
        generate(model, folder, controllers=(CONTROLLER,))
        source = folder / f"{model.name}_{step_function_name(CONTROLLER, 'lean')}.c"
        out["source"], out["source_kb"] = source.name, source.stat().st_size / 1024
        tc = Toolchain()
        cc = [tc.executable(), *shlex.split(tc.cc)[1:]]  # $CC with its own words (e.g. "gcc -m32")
        for label, flags in flag_sets(tc).items():
            times = []
            for _ in range(1 if quick else 2):
                t0 = time.perf_counter()
                run_compiler([*cc, *flags, "-c", str(source), "-o", str(Path(tmp) / "step.o")], source.name,
                             tc.timeout)
                times.append(time.perf_counter() - t0)
            out["compile_s"][label] = min(times)
    return out


def run(quick: bool = False) -> dict:
    return {"robots": {name: run_robot(name, quick) for name in common.robots()}, "chain": run_chain(quick),
            "quick": quick}


def print_table(res):
    for r in res["robots"].values():
        print(f"{r['model']}: {r['scenario']} with {CONTROLLER}")
        print(f"{'flags':34} {'compile s':>10} {'loop us/period':>15}")
        for k, v in r["flags"].items():
            print(f"{k:34} {v['compile_s']:10.2f} {v['loop_us_per_period']:15.2f}")
        print()
    c = res.get("chain")
    if c:
        print(f"planar chain, n = {c['n']}: {c['source']} ({c['source_kb']:.0f} kB) compiled alone")
        for k, v in c["compile_s"].items():
            print(f"{k:34} {v:10.2f} s")


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
