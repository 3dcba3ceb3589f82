"""C-only cost of every generated function of every shipped robot, one timing driver per function.

For each robot (``hydrogen.models()``) and each function listed in its committed
``generated/<model>/manifest.json`` a C driver is rendered from ``templates/bench_function.c.j2``
with plausible inputs sized from the manifest (neutral pose plus small offsets, the model's true
θ and γ, each controller's gains, bounds and static inputs as the simulator gives them; see
``common.InputValues``), compiled
together with the function's generated ``.c`` in one ``cc -O2 -std=c99 -Wall -Wextra -Werror``
invocation (the drivers compile in parallel), and run. Each driver calls its function in a loop,
perturbing one input entry by a tiny amount every iteration so no call can be hoisted, and
accumulates a checksum it prints. The number of calls per repeat is doubled until one repeat
takes at least 0.05 s (0.01 s with ``--quick``); the reported cost is the median of 5 repeats,
in nanoseconds per call, next to the function's CasADi instruction count from the manifest.
The drivers run one after the other (never in parallel). A run takes about 10-15 s per robot.

Run: ``python benchmarks/bench_functions.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

try:  # imported as benchmarks.bench_functions
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

TEMPLATE = "bench_function.c.j2"
REPEATS = 5
MIN_TIME_S, QUICK_MIN_TIME_S = 0.05, 0.01
#: The input perturbed in the loop: the function's first input, this entry (or its last).
PERTURB_INDEX = 3
PERTURB_REL, PERTURB_ABS = 1e-9, 1e-12


def _perturbation(inputs: list) -> tuple[int, int, str]:
    """(input position, entry, step) of the entry changed every iteration."""
    name, values = inputs[0]
    k = min(PERTURB_INDEX, len(values) - 1)
    base = abs(float(values[k]))
    return 0, k, common.c_float(PERTURB_REL * base if base > 0 else PERTURB_ABS)


def render_driver(entry: dict, inputs: list, repeats: int, min_time: float) -> str:
    pos, k, step = _perturbation(inputs)
    return common.jinja_env().get_template(TEMPLATE).render(
        c_name=entry["c_name"], header=entry["header"], repeats=repeats,
        min_time_s=common.c_float(min_time),
        inputs=[(name, [common.c_float(x) for x in vals]) for name, vals in inputs],
        outputs=[(name, int(r) * int(c)) for name, r, c in entry["outputs"]],
        perturb_input=pos, perturb_name=inputs[pos][0], perturb_index=k, perturb_step=step)


def _compile(argv: list) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True)
    return time.perf_counter() - t0, proc


def _parse(stdout: str, entry: dict, repeats: int) -> dict:
    outs = {i: {} for i in range(len(entry["outputs"]))}
    ns, n_calls, checksum = [], None, None
    for line in stdout.splitlines():
        key, *vals = line.split()
        if key == "out":
            outs[int(vals[0])][int(vals[1])] = float(vals[2])
        elif key == "ns_per_call":
            ns.append(float(vals[0]))
        elif key == "n_calls":
            n_calls = int(vals[0])
        elif key == "checksum":
            checksum = float(vals[0])
    sizes = [int(r) * int(c) for _, r, c in entry["outputs"]]
    if len(ns) != repeats or n_calls is None or checksum is None \
            or any(len(outs[i]) != n for i, n in enumerate(sizes)):
        raise RuntimeError(f"unexpected output from the driver of {entry['c_name']}:\n{stdout}")
    values = [v for i in range(len(sizes)) for v in outs[i].values()]
    return {"ns": ns, "n_calls": n_calls, "checksum": checksum,
            "non_finite_outputs": sum(not math.isfinite(v) for v in values), "n_outputs": len(values)}


def run_robot(model, quick: bool = False, cc: str = "cc", gen_dir: Path | None = None) -> dict:
    """Time every generated function of ``model`` in C; returns JSON-serialisable results."""
    import hydrogen
    from hydrogen.codegen.generate import check

    t_start = time.perf_counter()
    cc_path = common.require_cc(cc)
    gen_dir = Path(gen_dir) if gen_dir else common.REPO / "generated" / model.name
    manifest = json.loads((gen_dir / "manifest.json").read_text())
    stale = []
    try:
        if model.name == manifest.get("model_name"):
            stale = check(model, gen_dir)
    except Exception as exc:  # the timing does not depend on it; report and go on
        stale = [f"could not check the generated folder: {exc}"]
    if stale:
        print(f"warning: the generated C of {model.name} is stale for the current model/derivation; it is "
              "timed as it is:\n  " + "\n  ".join(stale), file=sys.stderr)
    values = common.InputValues(hydrogen.build(model))
    min_time = QUICK_MIN_TIME_S if quick else MIN_TIME_S
    jobs = [(entry["name"], entry, values.function_inputs(entry), gen_dir) for entry in manifest["functions"]]
    results, compile_wall = time_drivers(jobs, min_time, cc_path)
    order = sorted(results, key=lambda n: results[n]["ns_per_call"], reverse=True)
    return {
        "model": model.name, "n": model.n, "generated": str(gen_dir), "stale": stale,
        "cflags": list(common.CFLAGS), "repeats": REPEATS, "min_time_s": min_time, "quick": quick,
        "functions": {n: results[n] for n in order},
        "total_ns_per_call": sum(r["ns_per_call"] for r in results.values()),
        "compile_wall_s": compile_wall, "wall_s": time.perf_counter() - t_start,
    }


def time_drivers(jobs: list, min_time: float, cc_path: str) -> tuple[dict, float]:
    """Time generated C functions: ``jobs`` of (key, manifest entry, [(input name, values)], the
    folder holding the entry's source). The drivers compile in parallel and run one at a time, in
    the order given. Returns ({key: result}, compile wall time s)."""
    results = {}
    with tempfile.TemporaryDirectory(prefix="bench_functions_") as tmp:
        built = []
        for k, (key, entry, inputs, folder) in enumerate(jobs):
            driver, exe = Path(tmp) / f"bench_{k}.c", Path(tmp) / f"bench_{k}"
            driver.write_text(render_driver(entry, inputs, REPEATS, min_time))
            argv = [cc_path, *common.CFLAGS, "-I", str(folder), str(driver),
                    str(Path(folder) / entry["source"]), "-o", str(exe), "-lm"]
            built.append((key, entry, argv, exe))
        t0 = time.perf_counter()
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            compiled = list(pool.map(lambda job: _compile(job[2]), built))
        compile_wall = time.perf_counter() - t0
        for (_, entry, argv, _), (_, proc) in zip(built, compiled):
            if proc.returncode != 0:
                raise RuntimeError(f"compiling the driver of {entry['c_name']} failed:\n$ "
                                   f"{' '.join(argv)}\n{proc.stderr}")
        # run one at a time: drivers running side by side would share the cores
        for (key, entry, argv, exe), (compile_s, _) in zip(built, compiled):
            proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
            if proc.returncode != 0:
                raise RuntimeError(f"the driver of {entry['c_name']} failed (exit {proc.returncode}):\n"
                                   f"{proc.stderr}")
            r = _parse(proc.stdout, entry, REPEATS)
            ns = common.median(r["ns"])
            results[key] = {
                "c_name": entry["c_name"], "instructions": entry["instructions"],
                "ns_per_call": ns, "ns_per_call_repeats": r["ns"],
                "ns_per_instruction": ns / entry["instructions"] if entry["instructions"] else None,
                "calls_per_repeat": r["n_calls"], "checksum": r["checksum"],
                "non_finite_outputs": r["non_finite_outputs"], "n_outputs": r["n_outputs"],
                "compile_s": compile_s,
            }
    return results, compile_wall


def run(quick: bool = False, cc: str = "cc") -> dict:
    """:func:`run_robot` for every shipped robot, from its committed generated folder."""
    import hydrogen

    robots = {name: run_robot(hydrogen.load_model(name), quick=quick, cc=cc) for name in common.robots()}
    return {"robots": robots, "quick": quick, "machine": common.machine_info(cc)}


def print_table(res: dict) -> None:
    m = res["machine"]
    print(f"machine : {m['processor']}, {m['cpu_count']} CPUs; {m['cc']}")
    for rob in res["robots"].values():
        _print_robot(rob)


def _print_robot(res: dict) -> None:
    print(f"\n{res['model']} (n = {res['n']}): C cost of each generated function ({res['generated']}), sorted "
          f"by cost: median of {res['repeats']} repeats, >= {res['min_time_s']:g} s each; {' '.join(res['cflags'])}")
    if res["stale"]:
        print(f"  (stale generated folder, timed as it is: {len(res['stale'])} reason(s))")
    header = (f"{'function':<24} {'instructions':>12} {'ns/call':>11} {'spread %':>9} "
              f"{'ns/instr':>9} {'calls/repeat':>13} {'compile s':>10}")
    print(header)
    print("-" * len(header))
    for name, r in res["functions"].items():
        ns = r["ns_per_call_repeats"]
        spread = 100.0 * (max(ns) - min(ns)) / r["ns_per_call"]
        per = f"{r['ns_per_instruction']:.3f}" if r["ns_per_instruction"] is not None else "-"
        flag = f"  ({r['non_finite_outputs']}/{r['n_outputs']} outputs not finite)" \
            if r["non_finite_outputs"] else ""
        print(f"{name:<24} {r['instructions']:>12d} {r['ns_per_call']:>11.1f} {spread:>9.1f} {per:>9} "
              f"{r['calls_per_repeat']:>13d} {r['compile_s']:>10.2f}{flag}")
    print(f"sum of one call of each: {res['total_ns_per_call'] / 1e3:.2f} us; drivers compiled in "
          f"{res['compile_wall_s']:.1f} s (parallel), {res['model']} benchmark {res['wall_s']:.1f} s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter repeats (>= 0.01 s)")
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    ap.add_argument("--cc", default="cc", help="C compiler (default: cc)")
    a = ap.parse_args(argv)
    res = run(quick=a.quick, cc=a.cc)
    print_table(res)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(res, indent=2) + "\n")
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
