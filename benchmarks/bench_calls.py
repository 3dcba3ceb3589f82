"""Per-call cost of the compiled functions from Python, route by route, and of batches per state.

One process, one run, side by side, at the inputs of ``benchmarks/common.py``:

  * the C cost of one call: a stand-alone C driver per function (the approach of
    ``bench_functions.py``: ``templates/bench_function.c.j2``, median of 5 repeats);
  * per call from Python, for ``regressor`` and ``forward_dynamics``: ``dyn.<function>`` through the
    compiled extension (``backend="extension"``), the same with ``out=``, the extension function
    itself (``dyn.functions[...]``), ``dyn.<function>`` through ctypes (``backend="ctypes"``), and the
    generated function loaded as a CasADi Function (``casadi.external``) called from Python;
    for forward dynamics also the route without it (D, C and G, then ``numpy.linalg.solve``);
  * Pinocchio, when ``import pinocchio`` works: ``pin.rnea``, ``pin.computeJointTorqueRegressor``
    and ``pin.aba`` on one free-flying body with the platform's mass and inertia (θ);
  * batches: per-state cost of one call with n = 1, 10, 100, 1000, 10000 stacked states, through
    the extension (new output arrays each call), against the C cost.

Times are 31 repeats (11 with ``--quick``) of at least 2 ms each, from Python by timeit and in C by
the driver (the same template, run with these repeats). Both the median and the fastest repeat are
recorded; overheads (a route's per-call time minus the C cost) and ratios use the fastest repeat on
both sides, the one least disturbed by other work on a shared machine. No timing is asserted anywhere.

Run: ``python benchmarks/bench_calls.py [--quick] [--json FILE]`` or ``hydrogen bench --only bench_calls``.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

try:  # imported as benchmarks.bench_calls
    from . import bench_functions, common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_functions
    import common

FUNCTIONS = ("regressor", "forward_dynamics")
BATCH_SIZES = (1, 10, 100, 1000, 10000)
#: Many short repeats, on the Python side and in the C driver alike: on a shared machine the fastest
#: of them is the one no other process interrupted.
REPEATS, QUICK_REPEATS = 31, 11
MIN_TIME_S = 0.002


def _time(fn, repeats: int) -> dict:
    """Seconds per call of ``fn()``: calls per repeat doubled until one repeat takes MIN_TIME_S."""
    number = 1
    while True:
        t = timeit.timeit(fn, number=number)
        if t >= MIN_TIME_S:
            break
        number *= 2
    times = [timeit.timeit(fn, number=number) / number for _ in range(repeats)]
    return {"s": statistics.median(times), "min_s": min(times), "number": number}


def c_costs(entries: list, gen_dir: Path, repeats: int) -> dict:
    """ns per call of each entry's generated C (median and min of the repeats), from the driver of
    bench_functions.py."""
    cc = common.require_cc("cc")
    out = {}
    with tempfile.TemporaryDirectory(prefix="bench_calls_") as tmp:
        for entry in entries:
            driver, exe = Path(tmp) / f"{entry['name']}.c", Path(tmp) / entry["name"]
            driver.write_text(bench_functions.render_driver(entry, common.function_inputs(entry),
                                                            repeats, MIN_TIME_S))
            argv = [cc, *common.CFLAGS, "-I", str(gen_dir), str(driver), str(gen_dir / entry["source"]),
                    "-o", str(exe), "-lm"]
            _, proc = bench_functions._compile(argv)
            if proc.returncode != 0:
                raise RuntimeError(f"compiling the driver of {entry['c_name']} failed:\n{proc.stderr}")
            run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
            if run.returncode != 0:
                raise RuntimeError(f"the driver of {entry['c_name']} failed:\n{run.stderr}")
            r = bench_functions._parse(run.stdout, entry, repeats)
            out[entry["name"]] = {"median": common.median(r["ns"]), "min": min(r["ns"])}
    return out


def _user_inputs(entry: dict) -> list:
    """common.function_inputs as the arrays a user passes: (rows,) vectors, C-order matrices."""
    out = []
    for (name, r, c), (_, flat) in zip(entry["inputs"], common.function_inputs(entry)):
        x = np.asarray(flat, float).reshape((int(r), int(c)), order="F")
        out.append(np.ascontiguousarray(x[:, 0] if int(c) == 1 else x))
    return out


def _pinocchio_body(theta):
    """A free-flying body with the platform's mass and principal inertia (θ = [M, Ix, Iy, Iz])."""
    import pinocchio as pin

    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "platform")
    model.appendBodyToJoint(joint, pin.Inertia(float(theta[0]), np.zeros(3), np.diag(theta[1:])),
                            pin.SE3.Identity())
    return pin, model, model.createData()


def run(quick: bool = False) -> dict:
    import casadi

    import hydrogen

    t_start = time.perf_counter()
    repeats = QUICK_REPEATS if quick else REPEATS
    dyn = hydrogen.build()
    dyn_ctypes = hydrogen.build(backend="ctypes")
    manifest = dyn.library.manifest
    gen_dir = Path(dyn.library.generated_dir)
    entries = {e["name"]: e for e in manifest["functions"]}
    c_ns = c_costs([entries[f] for f in FUNCTIONS], gen_dir, repeats)
    theta = dyn.model.theta

    per_call = {}
    for name in FUNCTIONS:
        entry = entries[name]
        args = _user_inputs(entry)
        method = getattr(dyn, name)
        want = method(*args)
        out = np.empty_like(want)
        routes = {
            "extension": lambda: method(*args),
            "extension_out": lambda: method(*args, out=out),
            "extension_function": (lambda f: lambda: f(*args))(dyn.functions[name]),
            "ctypes": (lambda m: lambda: m(*args))(getattr(dyn_ctypes, name)),
        }
        if dyn.backend != "extension":
            routes = {"ctypes": routes["ctypes"]}
        ext_fn = casadi.external(entry["c_name"], str(dyn.library.path))
        routes["casadi_external"] = lambda: ext_fn(*args)
        np.testing.assert_allclose(np.array(ext_fn(*args)).reshape(want.shape, order="F") if want.ndim == 2
                                   else np.array(ext_fn(*args)).ravel(), want, rtol=1e-12)
        if name == "forward_dynamics":
            q, qdot, tau, th = args

            def solve_route():
                D = dyn.mass_matrix(q, th)
                return np.linalg.solve(D, tau - dyn.coriolis(q, qdot, th) @ qdot - dyn.gravity(q, th))

            np.testing.assert_allclose(solve_route(), want, rtol=1e-9)
            routes["D_C_G_then_numpy_solve"] = solve_route
        per_call[name] = {k: _time(f, repeats) for k, f in routes.items()}

    pin_res = None
    try:
        pin, pmodel, pdata = _pinocchio_body(theta)
    except ImportError:
        pin = None
    if pin is not None:
        rng = np.random.default_rng(0)
        quat = rng.standard_normal(4)
        qp = np.concatenate([[0.01, -0.02, -2.3], quat / np.linalg.norm(quat)])
        vp, ap, taup = (0.1 * rng.standard_normal(pmodel.nv) for _ in range(3))
        pin_res = {
            "version": pin.__version__,
            "rnea": _time(lambda: pin.rnea(pmodel, pdata, qp, vp, ap), repeats),
            "computeJointTorqueRegressor": _time(
                lambda: pin.computeJointTorqueRegressor(pmodel, pdata, qp, vp, ap), repeats),
            "aba": _time(lambda: pin.aba(pmodel, pdata, qp, vp, taup), repeats),
        }

    batches = {}
    if dyn.backend == "extension":
        rng = np.random.default_rng(1)
        for name in FUNCTIONS:
            base = _user_inputs(entries[name])
            method = getattr(dyn, name)
            rows = {}
            for n in BATCH_SIZES:
                stacked = [b + 1e-6 * rng.standard_normal((n,) + b.shape) for b in base]
                if name == "forward_dynamics":
                    stacked[-1] = base[-1]  # one θ for all states
                t = _time(lambda: method(*stacked), repeats)
                rows[str(n)] = {"per_state_ns": 1e9 * t["s"] / n, "per_state_min_ns": 1e9 * t["min_s"] / n,
                                "ratio_to_c": 1e9 * t["min_s"] / n / c_ns[name]["min"]}
            batches[name] = rows

    return {
        "backend": dyn.backend, "c_ns": c_ns, "per_call": per_call, "pinocchio": pin_res,
        "batches": batches, "batch_sizes": list(BATCH_SIZES), "repeats": repeats, "min_time_s": MIN_TIME_S,
        "quick": quick, "wall_s": time.perf_counter() - t_start, "machine": common.machine_info(),
    }


def print_table(res: dict) -> None:
    m = res["machine"]
    print(f"machine : {m['processor']}, {m['cpu_count']} CPUs; Python {m['python']}, numpy {m['numpy']}")
    print(f"per call from Python (median and min of {res['repeats']} repeats >= {res['min_time_s']:g} s) against "
          f"the C cost; overhead and ratio from the mins; backend in use: {res['backend']}")
    header = f"{'function':<18} {'route':<26} {'median ns':>9} {'min ns':>8} {'overhead ns':>12} {'x C':>7}"
    print(header)
    print("-" * len(header))
    for name, routes in res["per_call"].items():
        c = res["c_ns"][name]
        print(f"{name:<18} {'C (stand-alone driver)':<26} {c['median']:>9.0f} {c['min']:>8.0f} {'':>12} {1.0:>7.2f}")
        for route, t in routes.items():
            ns, mn = 1e9 * t["s"], 1e9 * t["min_s"]
            print(f"{'':<18} {route:<26} {ns:>9.0f} {mn:>8.0f} {mn - c['min']:>12.0f} {mn / c['min']:>7.2f}")
    p = res["pinocchio"]
    if p:
        print(f"Pinocchio {p['version']}, one free-flying body with the platform's mass and inertia:")
        for route in ("rnea", "computeJointTorqueRegressor", "aba"):
            print(f"{'':<18} {'pin.' + route:<26} {1e9 * p[route]['s']:>9.0f} {1e9 * p[route]['min_s']:>8.0f}")
        ext = res["per_call"]["regressor"].get("extension")
        if ext:
            print(f"  dyn.regressor (extension) / pin.rnea: {ext['min_s'] / p['rnea']['min_s']:.2f}; "
                  f"/ pin.computeJointTorqueRegressor: {ext['min_s'] / p['computeJointTorqueRegressor']['min_s']:.2f}"
                  " (mins)")
        fd = res["per_call"]["forward_dynamics"].get("extension")
        if fd:
            print(f"  dyn.forward_dynamics (extension) / pin.aba: {fd['min_s'] / p['aba']['min_s']:.2f} (mins)")
    else:
        print("Pinocchio: not importable, not measured")
    if res["batches"]:
        print("batches through the extension: per-state cost of one call with n stacked states (min ns; x C: "
              "min / C min)")
        header = f"{'function':<18} " + " ".join(f"{'n=' + str(n):>10}" for n in res["batch_sizes"])
        print(header)
        print("-" * len(header))
        for name, rows in res["batches"].items():
            print(f"{name + ' ns':<18} " + " ".join(f"{rows[str(n)]['per_state_min_ns']:>10.1f}"
                                                    for n in res["batch_sizes"]))
            print(f"{'  x C':<18} " + " ".join(f"{rows[str(n)]['ratio_to_c']:>10.2f}" for n in res["batch_sizes"]))
    print(f"whole benchmark {res['wall_s']:.1f} s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter repeats")
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    a = ap.parse_args(argv)
    res = run(quick=a.quick)
    print_table(res)
    if a.json:
        a.json.write_text(json.dumps(res, indent=2) + "\n")
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
