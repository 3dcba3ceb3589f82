"""What folding the description's numbers into the generated code buys.

hydrogen generates each function with the description's numbers (masses, inertias, pin points,
areas, pressures, valve constants) folded into its expressions as constants, so CasADi simplifies
through them. The alternative keeps them as one more input, ``numbers``, so an edit of a number
needs no regeneration. For each shipped robot, every derived function
(``hydrogen.symbolic.functions.derive_functions``) is generated four times in one run: folded, as
shipped, and three times with the numbers as symbols (``hydrogen.symbolic.constants.numbers_as_symbols``;
the same rigid-body form, zeros and unit axes still structural): ``by_name``, one symbol per
description number (a link's mass, a joint origin's coordinate, a cylinder's area: what a vector of
runtime parameters would hold, ``hydrogen.model.Model.numbers``), ``shared``, one per distinct value (equal numbers merge, as folding merges them), and
``per_use``, one for every number the derivation meets. Each is checked to agree with the folded
function at the description's numbers (CasADi, relative 1e-9), then all are timed side by side
with the ``bench_functions`` driver (same flags, the same inputs plus the numbers). Reported per
function: CasADi instructions and C ns per call folded, and each variant's ratios to folded; per
robot, the derivation times, the numbers' counts and the sums.

Run: ``python benchmarks/bench_folding.py [--quick] [--model NAME] [--json FILE]``
(about 2-4 minutes per robot on 2 cores).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:  # imported as benchmarks.bench_folding
    from . import bench_functions, common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_functions
    import common

#: Relative agreement of the folded and the parametric function at the description's numbers.
AGREEMENT_RTOL = 1e-9


#: The parametric variants: the NumberTable key of each (hydrogen.symbolic.constants.KEYS).
VARIANTS = {"by_name": "name", "shared": "value", "per_use": "use"}


def derive_all(model) -> tuple[list, dict, dict]:
    """(folded functions, {variant: (functions with the numbers input, their values)}, derivation s)."""
    from hydrogen.symbolic.functions import SymbolicFunction, derive_functions, derive_parametric

    t0 = time.perf_counter()
    folded = [f for f in derive_functions(model) if isinstance(f, SymbolicFunction)]
    seconds, variants = {"folded": time.perf_counter() - t0}, {}
    for variant, key in VARIANTS.items():
        t0 = time.perf_counter()
        funcs, _, values = derive_parametric(model, key=key)
        seconds[variant] = time.perf_counter() - t0
        variants[variant] = ([f for f in funcs if isinstance(f, SymbolicFunction)], np.asarray(values))
    return folded, variants, seconds


def agreement(fun_folded, fun_param, inputs: list, numbers) -> float:
    """Largest relative difference of the two CasADi Functions' outputs at ``inputs`` (and the numbers)."""
    args = [np.asarray(v, float) for _, v in inputs]
    a = fun_folded.call(args)
    b = fun_param.call(args + [np.asarray(numbers, float)])
    worst = 0.0
    for x, y in zip(a, b):
        x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
        worst = max(worst, float(np.max(np.abs(x - y) / np.maximum(1.0, np.abs(x)), initial=0.0)))
    return worst


def run_robot(model, quick: bool = False, cc: str = "cc") -> dict:
    import hydrogen
    from hydrogen.codegen.generate import write_function
    from hydrogen.symbolic.functions import NUMBERS

    t_start = time.perf_counter()
    cc_path = common.require_cc(cc)
    folded, variants, derive_s = derive_all(model)
    values = common.InputValues(hydrogen.build(model))
    min_time = bench_functions.QUICK_MIN_TIME_S if quick else bench_functions.MIN_TIME_S
    kinds = ("folded", *variants)
    with tempfile.TemporaryDirectory(prefix="bench_folding_") as tmp:
        dirs = {kind: Path(tmp) / kind for kind in kinds}
        for d in dirs.values():
            d.mkdir()
        jobs, worst = [], {}
        for k, f in enumerate(folded):
            converted = {}  # the CasADi Functions write_function makes, reused for the agreement check
            entry = write_function(f, model.name, dirs["folded"], converted)
            inputs = values.function_inputs(entry)
            jobs.append(((f.name, "folded"), entry, inputs, dirs["folded"]))
            for variant, (funcs, numbers) in variants.items():
                mine = {}
                jobs.append(((f.name, variant), write_function(funcs[k], model.name, dirs[variant], mine),
                             [*inputs, (NUMBERS, numbers)], dirs[variant]))
                worst[(f.name, variant)] = agreement(converted[f.name], mine[f.name], inputs, numbers)
        timed, compile_wall = bench_functions.time_drivers(jobs, min_time, cc_path)
    functions = {}
    for f in folded:
        base = timed[(f.name, "folded")]
        functions[f.name] = {}
        for kind in kinds:
            t = timed[(f.name, kind)]
            functions[f.name][kind] = {
                "instructions": t["instructions"], "ns_per_call": t["ns_per_call"],
                "instruction_ratio": t["instructions"] / max(base["instructions"], 1),
                "time_ratio": t["ns_per_call"] / base["ns_per_call"],
                **({"largest_relative_difference": worst[(f.name, kind)]} if kind in variants else {})}
    return {"model": model.name, "n": model.n, "numbers": {v: len(n) for v, (_, n) in variants.items()},
            "derivation_s": derive_s, "functions": functions, "compile_wall_s": compile_wall,
            "wall_s": time.perf_counter() - t_start, "agree": all(w <= AGREEMENT_RTOL for w in worst.values())}


def run(quick: bool = False, cc: str = "cc", models=None) -> dict:
    import hydrogen

    return {"robots": {name: run_robot(hydrogen.load_model(name), quick=quick, cc=cc)
                       for name in (models or common.robots())},
            "quick": quick, "machine": common.machine_info(cc)}


def print_table(res: dict) -> None:
    m = res["machine"]
    print(f"machine : {m['processor']}, {m['cpu_count']} CPUs; {m['cc']}")
    for rob in res["robots"].values():
        d, nums = rob["derivation_s"], rob["numbers"]
        print(f"\n{rob['model']} (n = {rob['n']}): numbers as symbols "
              + ", ".join(f"{v} {nums[v]}" for v in VARIANTS) + "; derivation s: folded "
              f"{d['folded']:.1f}, " + ", ".join(f"{v} {d[v]:.1f}" for v in VARIANTS)
              + f"; every parametric function {'agrees' if rob['agree'] else 'DOES NOT AGREE'} with the "
              f"folded one (relative {AGREEMENT_RTOL:g}). Ratios to folded:")
        header = (f"{'function':<28} {'instructions':>12} " + " ".join(f"{v:>8}" for v in VARIANTS)
                  + f" {'ns/call':>9} " + " ".join(f"{v:>8}" for v in VARIANTS))
        print(header)
        print("-" * len(header))
        kinds = ("folded", *VARIANTS)
        tot = {k: [0, 0.0] for k in kinds}
        for name, r in rob["functions"].items():
            for k in kinds:
                tot[k][0] += r[k]["instructions"]
                tot[k][1] += r[k]["ns_per_call"]
            print(f"{name:<28} {r['folded']['instructions']:>12d} "
                  + " ".join(f"{r[v]['instruction_ratio']:>7.2f}x" for v in VARIANTS)
                  + f" {r['folded']['ns_per_call']:>9.1f} "
                  + " ".join(f"{r[v]['time_ratio']:>7.2f}x" for v in VARIANTS))
        f = tot["folded"]
        print(f"{'all (one call each)':<28} {f[0]:>12d} " + " ".join(f"{tot[v][0] / f[0]:>7.2f}x" for v in VARIANTS)
              + f" {f[1]:>9.1f} " + " ".join(f"{tot[v][1] / f[1]:>7.2f}x" for v in VARIANTS))


def main(argv=None) -> int:
    import argparse
    import json

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter repeats (>= 0.01 s)")
    ap.add_argument("--model", action="append", help="a shipped robot (repeatable; default: all)")
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    ap.add_argument("--cc", default="cc", help="C compiler (default: cc)")
    a = ap.parse_args(argv)
    res = run(quick=a.quick, cc=a.cc, models=a.model)
    print_table(res)
    if a.json:
        from hydrogen.fileio import atomic_write
        atomic_write(a.json, json.dumps(res, indent=2) + "\n")
        print(f"wrote {a.json}")
    return 0 if all(r["agree"] for r in res["robots"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
