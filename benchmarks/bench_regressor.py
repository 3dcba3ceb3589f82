"""Per-call cost of the regressor Y(q, v, w, a) (n x p; q, v, w, a are n-vectors) through four routes,
for every shipped robot (or the one ``--model`` names).

  (a) sympy_lambdify  ``sympy.lambdify`` (numpy module) of the symbolic expression
  (b) casadi_python   the CasADi Function (SX) called from Python with numpy inputs
                      (returns a casadi.DM; the ``.full()`` conversion is not timed)
  (c) ctypes          ``hydrogen.build(...).regressor``: one ctypes call into the compiled library
  (d) c_loop          a C driver (rendered from ``templates/bench_loop.c.j2``) calling the
                      generated ``generated/<model>/<model>_regressor.c`` N times in a
                      loop, timed with clock_gettime(CLOCK_MONOTONIC)

All four are first checked to give the same Y at the benchmark point (rtol 1e-9). Each
route is timed as the median over ``--repeats`` repeats; the calls per repeat are chosen
so one repeat takes at least ``--min-time`` seconds (timeit auto-ranging for (a)-(c), the
same doubling inside the C driver for (d)). The table gives microseconds per call and the
ratio of each route to the C loop. A whole run takes roughly 15 s.

Run from anywhere (the repository root is found from this file's location)::

    python benchmarks/bench_regressor.py
    python benchmarks/bench_regressor.py --json regressor.json   # also write the results

Route (c) compiles the library into the hydrogen build cache (``$HYDROGEN_CACHE_DIR``
or ``~/.cache/hydrogen``) if it is not there yet; route (d) compiles into a temporary
directory that is removed afterwards.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import timeit
from pathlib import Path

import casadi
import jinja2
import numpy as np
import sympy

import hydrogen

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import cc_version, cpu_name, pose_offset, robots  # noqa: E402
from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.codegen.generate import check
from hydrogen.symbolic.functions import derive_functions

REPO = Path(__file__).resolve().parents[1]
TEMPLATES = REPO / "templates"
FUNCTION = "regressor"
CFLAGS = ("-O2", "-std=c99", "-Wall", "-Wextra", "-Werror")
RTOL = 1e-9

def point_of(model) -> dict:
    """The benchmark point: the neutral pose plus offsets and rates, every entry non-zero, away from
    singular or symmetric configurations (sized from the model)."""
    k = np.arange(model.n)
    return {"q": np.asarray(model.neutral_pose, dtype=float) + pose_offset(model.n),
            "v": 0.2 * np.sin(1.3 * k + 0.4), "w": 0.2 * np.cos(1.7 * k + 0.3), "a": 1.2 * np.sin(0.9 * k + 0.8)}


#: Input perturbed in the C loop: q, entry 3 (psi on the Stewart platform: it enters through
#: sin/cos, so the call is realistic) or the last one of a smaller model.
PERTURB = ("q", 3, 1e-12)

ROUTES = ("sympy_lambdify", "casadi_python", "ctypes", "c_loop")


def time_python(fn, args, repeats: int, min_time: float) -> tuple[float, int]:
    """Median seconds per call of fn(*args) over ``repeats`` repeats, and calls per repeat."""
    timer = timeit.Timer(lambda: fn(*args))
    timer.timeit(number=10)  # warm-up
    number = 1
    while True:  # like Timer.autorange, but up to min_time instead of a fixed 0.2 s
        if timer.timeit(number=number) >= min_time:
            break
        number *= 2
    times = timer.repeat(repeat=repeats, number=number)
    return statistics.median(times) / number, number


def c_loop(c_name: str, gen_dir: Path, inputs: list, n_out: int, repeats: int,
           min_time: float, cc: str, perturb_index: int = PERTURB[1]) -> dict:
    """Render, compile and run the C driver; return its output Y entries and timings."""
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                             undefined=jinja2.StrictUndefined, trim_blocks=True,
                             lstrip_blocks=True, keep_trailing_newline=True)
    source = env.get_template("bench_loop.c.j2").render(
        c_name=c_name, header=f"{c_name}.h", n_out=n_out, repeats=repeats,
        min_time_s=repr(float(min_time)),
        inputs=[(name, [repr(float(x)) for x in vals]) for name, vals in inputs],
        perturb_input=PERTURB[0], perturb_index=perturb_index, perturb_step=repr(PERTURB[2]))
    if shutil.which(cc) is None:
        sys.exit(f"error: C compiler '{cc}' not found on PATH")
    with tempfile.TemporaryDirectory(prefix="bench_regressor_") as tmp:
        driver, exe = Path(tmp) / "bench_loop.c", Path(tmp) / "bench_loop"
        driver.write_text(source)
        argv = [cc, *CFLAGS, "-I", str(gen_dir), str(driver), str(gen_dir / f"{c_name}.c"),
                "-o", str(exe), "-lm"]
        proc = subprocess.run(argv, capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit(f"error: compiling the C driver failed:\n$ {' '.join(argv)}\n{proc.stderr}")
        proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
        if proc.returncode != 0:
            sys.exit(f"error: the C driver failed (exit {proc.returncode}):\n{proc.stderr}")
    out, ns, n_calls, checksum = {}, [], None, None
    for line in proc.stdout.splitlines():
        key, *vals = line.split()
        if key == "out":
            out[int(vals[0])] = float(vals[1])
        elif key == "ns_per_call":
            ns.append(float(vals[0]))
        elif key == "n_calls":
            n_calls = int(vals[0])
        elif key == "checksum":
            checksum = float(vals[0])
    if len(out) != n_out or len(ns) != repeats or checksum is None:
        sys.exit(f"error: unexpected output from the C driver:\n{proc.stdout}")
    return {"out": np.array([out[k] for k in range(n_out)]), "ns": ns, "n_calls": n_calls,
            "checksum": checksum, "argv": argv}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    ap.add_argument("--repeats", type=int, default=7, help="timed repeats per route (default 7)")
    ap.add_argument("--min-time", type=float, default=0.2,
                    help="minimum seconds per repeat (default 0.2)")
    ap.add_argument("--cc", default="cc", help="C compiler for the C loop (default: cc)")
    ap.add_argument("--model", help="a built-in model's name or a path (default: every shipped robot)")
    args = ap.parse_args(argv)
    if args.repeats < 1 or args.min_time <= 0:
        ap.error("--repeats must be >= 1 and --min-time > 0")
    results = {}
    for name in ([args.model] if args.model else robots()):
        results[name] = bench_model(hydrogen.load_model(name), args)
        print()
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


def bench_model(model, args) -> dict:
    """The four routes for ``model``'s regressor; prints the table, returns the results."""
    gen_dir = REPO / "generated" / model.name
    c_name = f"{model.name}_{FUNCTION}"
    stale = check(model, gen_dir)
    if stale:
        print("warning: the committed generated C is stale for the current model/derivation; "
              "the C loop uses it as it is:\n  " + "\n  ".join(stale), file=sys.stderr)

    sf = {f.name: f for f in derive_functions(model)}[FUNCTION]
    (_, Y_expr), = sf.outputs
    in_syms = [list(mat) for _, mat in sf.inputs]  # flat symbol lists unpack from 1-D arrays
    f_lambdify = sympy.lambdify(in_syms, Y_expr, modules="numpy")
    f_casadi = to_casadi_function(sf)
    dyn = hydrogen.build(model, backend="ctypes")  # route (c) is the ctypes call; bench_calls.py times the extension

    point = point_of(model)
    xs = [point[name] for name, _ in sf.inputs]
    shape = tuple(Y_expr.shape)

    # --- same Y from every route --------------------------------------------------------
    c_res = c_loop(c_name, gen_dir, list(zip([n for n, _ in sf.inputs], xs)),
                   int(np.prod(shape)), args.repeats, args.min_time, args.cc,
                   perturb_index=min(PERTURB[1], model.n - 1))
    Ys = {
        "sympy_lambdify": np.asarray(f_lambdify(*xs), dtype=float),
        "casadi_python": np.asarray(f_casadi(*xs).full()),
        "ctypes": np.asarray(dyn.regressor(*xs)),
        "c_loop": c_res["out"].reshape(shape, order="F"),  # CasADi dense is column-major
    }
    ref = Ys["c_loop"]
    for route, Y in Ys.items():
        assert Y.shape == shape, f"{route}: Y has shape {Y.shape}, expected {shape}"
        np.testing.assert_allclose(Y, ref, rtol=RTOL, atol=0,
                                   err_msg=f"{route} disagrees with c_loop at the benchmark point")

    # --- timing ---------------------------------------------------------------------------
    us, calls = {}, {}
    for route, fn in (("sympy_lambdify", f_lambdify), ("casadi_python", f_casadi),
                      ("ctypes", dyn.regressor)):
        t, calls[route] = time_python(fn, xs, args.repeats, args.min_time)
        us[route] = 1e6 * t
    us["c_loop"] = 1e-3 * statistics.median(c_res["ns"])
    calls["c_loop"] = c_res["n_calls"]
    ratio = {r: us[r] / us["c_loop"] for r in ROUTES}

    # --- report ---------------------------------------------------------------------------
    versions = {"python": platform.python_version(), "numpy": np.__version__,
                "sympy": sympy.__version__, "casadi": casadi.__version__,
                "jinja2": jinja2.__version__, "hydrogen": hydrogen.__version__,
                "cc": cc_version(shutil.which(args.cc) or args.cc)}
    machine = {"processor": cpu_name(), "cpu_count": os.cpu_count(),
               "platform": platform.platform()}
    print(f"machine : {machine['processor']}, {machine['cpu_count']} CPUs, {machine['platform']}")
    print("versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()))
    print(f"function: {c_name}  Y {shape[0]}x{shape[1]}, inputs "
          + ", ".join(f"{n}({m.shape[0]})" for n, m in sf.inputs)
          + f"; all routes agree (rtol {RTOL:g})")
    print(f"timing  : median of {args.repeats} repeats, >= {args.min_time:g} s each; "
          f"C loop: {' '.join(CFLAGS)}")
    print()
    header = f"{'route':<16} {'us/call':>12} {'ratio to C loop':>16} {'calls/repeat':>13}"
    print(header)
    print("-" * len(header))
    for r in ROUTES:
        print(f"{r:<16} {us[r]:>12.4f} {ratio[r]:>16.1f} {calls[r]:>13d}")

    result = {
        "function": c_name,
        "routes": {r: {"us_per_call": us[r], "ratio_to_c_loop": ratio[r],
                       "calls_per_repeat": calls[r]} for r in ROUTES},
        "repeats": args.repeats, "min_time_s": args.min_time,
        "c_loop_cflags": list(CFLAGS), "c_loop_checksum": c_res["checksum"],
        "machine": machine, "versions": versions,
        "point": {k: v.tolist() for k, v in point.items()},
    }
    return result


if __name__ == "__main__":
    sys.exit(main())
