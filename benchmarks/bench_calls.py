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
    the extension (new output arrays each call), against the C cost; and, timed interleaved, the
    leg_lengths batch against the library's own C loop over states (``leg_lengths_many``).

The routes of one table are timed interleaved (round robin over their repeats).

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


def _calls_per_repeat(fn) -> int:
    number = 1
    while timeit.timeit(fn, number=number) < MIN_TIME_S:
        number *= 2
    return number


def _time_all(routes: dict, repeats: int) -> dict:
    """Seconds per call of each ``fn()`` in ``routes``, the routes' repeats interleaved (round robin),
    so a change of load on the machine hits them all alike."""
    numbers = {k: _calls_per_repeat(fn) for k, fn in routes.items()}
    times = {k: [] for k in routes}
    for _ in range(repeats):
        for k, fn in routes.items():
            times[k].append(timeit.timeit(fn, number=numbers[k]) / numbers[k])
    return {k: {"s": statistics.median(t), "min_s": min(t), "number": numbers[k]} for k, t in times.items()}


def _time(fn, repeats: int) -> dict:
    return _time_all({"fn": fn}, repeats)["fn"]


def _call(fn, args, out=None):
    """A lambda making the literal call ``fn(x0, x1, ...)`` (or with ``out=o``), as a user writes it:
    ``lambda: fn(*args, out=out)`` would time the unpacking and a kwargs dict as well."""
    names = [f"x{i}" for i in range(len(args))]
    env = {"fn": fn, "o": out, **dict(zip(names, args))}
    return eval(f"lambda: fn({', '.join(names)}{', out=o' if out is not None else ''})", env)


def c_costs(entries: list, gen_dir: Path, repeats: int, values) -> dict:
    """ns per call of each entry's generated C (median and min of the repeats), from the driver of
    bench_functions.py."""
    cc = common.require_cc("cc")
    out = {}
    with tempfile.TemporaryDirectory(prefix="bench_calls_") as tmp:
        for entry in entries:
            driver, exe = Path(tmp) / f"{entry['name']}.c", Path(tmp) / entry["name"]
            driver.write_text(bench_functions.render_driver(entry, values.function_inputs(entry),
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


def _inputs(entry: dict, values) -> tuple:
    """The driver's inputs as the arrays a user passes ((rows,) vectors, C-order matrices): those of
    the Python call, which fills in the description's numbers itself, and every input of the C."""
    from hydrogen.layout import NUMBERS

    every, user = [], []
    for (name, r, c), (_, flat) in zip(entry["inputs"], values.function_inputs(entry)):
        x = np.asarray(flat, float).reshape((int(r), int(c)), order="F")
        every.append(np.ascontiguousarray(x[:, 0] if int(c) == 1 else x))
        if name != NUMBERS:
            user.append(every[-1])
    return user, every


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
    values = common.InputValues(dyn)
    c_ns = c_costs([entries[f] for f in FUNCTIONS], gen_dir, repeats, values)
    theta = dyn.model.theta

    per_call = {}
    for name in FUNCTIONS:
        entry = entries[name]
        args, c_args = _inputs(entry, values)
        method = getattr(dyn, name)
        want = method(*args)
        out = np.empty_like(want)
        routes = {
            "extension": _call(method, args),
            "extension_out": _call(method, args, out),
            "extension_function": _call(dyn.functions[name], args),
            "ctypes": _call(getattr(dyn_ctypes, name), args),
        }
        if dyn.backend != "extension":
            routes = {"ctypes": routes["ctypes"]}
        ext_fn = casadi.external(entry["c_name"], str(dyn.library.path))
        routes["casadi_external"] = _call(ext_fn, c_args)
        np.testing.assert_allclose(np.array(ext_fn(*c_args)).reshape(want.shape, order="F") if want.ndim == 2
                                   else np.array(ext_fn(*c_args)).ravel(), want, rtol=1e-12)
        if name == "forward_dynamics":
            q, qdot, tau, th = args

            def solve_route():
                D = dyn.mass_matrix(q, th)
                return np.linalg.solve(D, tau - dyn.coriolis(q, qdot, th) @ qdot - dyn.gravity(q, th))

            np.testing.assert_allclose(solve_route(), want, rtol=1e-9)
            routes["D_C_G_then_numpy_solve"] = solve_route
        per_call[name] = _time_all(routes, repeats)

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
        d1, d2, d3 = pdata, pmodel.createData(), pmodel.createData()  # one Data per algorithm
        pin_res = {"version": pin.__version__, **_time_all({
            "rnea": lambda: pin.rnea(pmodel, d1, qp, vp, ap),
            "computeJointTorqueRegressor": lambda: pin.computeJointTorqueRegressor(pmodel, d2, qp, vp, ap),
            "aba": lambda: pin.aba(pmodel, d3, qp, vp, taup),
            "dyn_regressor": _call(dyn.regressor, _inputs(entries["regressor"], values)[0]),
            "dyn_forward_dynamics": _call(dyn.forward_dynamics, _inputs(entries["forward_dynamics"], values)[0]),
        }, repeats)}

    batches, reference = {}, {}
    if dyn.backend == "extension":
        rng = np.random.default_rng(1)
        for name in FUNCTIONS:
            base = _inputs(entries[name], values)[0]
            method = getattr(dyn, name)
            rows = {}
            for n in BATCH_SIZES:
                stacked = [b + 1e-6 * rng.standard_normal((n,) + b.shape) for b in base]
                if name == "forward_dynamics":
                    stacked[-1] = base[-1]  # one θ for all states
                t = _time(_call(method, stacked), repeats)
                rows[str(n)] = {"per_state_ns": 1e9 * t["s"] / n, "per_state_min_ns": 1e9 * t["min_s"] / n,
                                "ratio_to_c": 1e9 * t["min_s"] / n / c_ns[name]["min"]}
            batches[name] = rows
        # Same conditions, same moment: the batch through the extension against the library's own
        # C loop over states (the loop driver's <model>_leg_lengths_many, called once through ctypes).
        if dyn._many is not None:
            base = _inputs(entries["leg_lengths"], values)[0][0]
            for n in BATCH_SIZES[-2:]:
                stacked = base + 1e-6 * rng.standard_normal((n,) + base.shape)
                t = _time_all({"extension": _call(dyn.leg_lengths, [stacked]),
                               "c_loop": _call(dyn.leg_lengths_many, [stacked])}, repeats)
                reference[str(n)] = {k: 1e9 * v["min_s"] / n for k, v in t.items()}

    return {
        "empty_lambda": _time(lambda: None, repeats),
        "backend": dyn.backend, "c_ns": c_ns, "per_call": per_call, "pinocchio": pin_res,
        "batches": batches, "batch_vs_c_loop": reference, "batch_sizes": list(BATCH_SIZES), "repeats": repeats, "min_time_s": MIN_TIME_S,
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
        # hydrogen's calls timed again in the same round as Pinocchio's
        reg, fd = p["dyn_regressor"], p["dyn_forward_dynamics"]
        print(f"{'':<18} {'dyn.regressor':<26} {1e9 * reg['s']:>9.0f} {1e9 * reg['min_s']:>8.0f}")
        print(f"{'':<18} {'dyn.forward_dynamics':<26} {1e9 * fd['s']:>9.0f} {1e9 * fd['min_s']:>8.0f}")
        print(f"  ({res['backend']}) dyn.regressor / pin.rnea: {reg['min_s'] / p['rnea']['min_s']:.2f}; "
              f"/ pin.computeJointTorqueRegressor: {reg['min_s'] / p['computeJointTorqueRegressor']['min_s']:.2f}; "
              f"dyn.forward_dynamics / pin.aba: {fd['min_s'] / p['aba']['min_s']:.2f} (mins)")
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
    if res.get("batch_vs_c_loop"):
        print("leg_lengths batch through the extension vs the library's C loop over states (leg_lengths_many), "
              "interleaved, min ns per state:")
        for n, r in res["batch_vs_c_loop"].items():
            print(f"  n={n:<6} extension {r['extension']:.1f}, C loop {r['c_loop']:.1f}: "
                  f"ratio {r['extension'] / r['c_loop']:.2f}")
    print(f"every Python time includes timeit's call of a lambda: {1e9 * res['empty_lambda']['min_s']:.0f} ns "
          f"(min) for an empty one; not subtracted above")
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
