"""How long it takes to get from a robot's description to a loaded library, and how large its
controller's code is, for every shipped robot (``hydrogen.models()``).

(a) generation from scratch: ``render(hydrogen.load_model(name), tmpdir)`` in a fresh Python process,
    so the imports are included; the same process also reports the import, the derivation alone
    (``derive_functions(model)``) and the SymPy -> CasADi -> C part (``render`` given the derived
    functions: exactly what ``render(model, tmpdir)`` does after deriving). The rendered files are
    compared with the committed ``generated/<model>`` (generation is deterministic; the manifest
    is compared without its derivation hash, as ``hydrogen generate --check`` does).
(b) compilation from a clean cache: ``hydrogen.build(model, cache=<fresh dir>, generated=<the folder
    (a) rendered>)`` in a fresh process (the core library's sources compiled in parallel, then one
    link, then loaded; the controllers' libraries wait for their first use, see (e)): a compile only,
    even when the committed folder is stale by its hash.
(c) the same build again with nothing changed (``cache=<same dir>``), in a fresh process, timed
    inside it with ``time.perf_counter`` around the ``build`` call.
(e) cold time to the first run: in a fresh process with a fresh cache, ``hydrogen.simulate`` of one
    controller (adaptive-robust, the main job) on the robot's first scenario for 0.05 s, by two
    routes side by side: the current one (the core library and that controller's library, compiled
    in one pool of compilers) and the one before libraries were split (every generated function,
    every controller and variant, compiled into one library, then the same run). Wall seconds of the
    process and CPU seconds (the process and its compilers: ``getrusage`` of self and children).
(d) Theorem 1's controller (``ctrl_backstepping``, leg-force mapping) in CasADi instructions: as
    hydrogen generates it (tau_d_dot derived by SymPy) against the same law with tau_d_dot from
    CasADi's forward AD (``jtimes``), both checked to give the same outputs at random points first,
    both counted with ``{"cse": True}``.

Times of (a), (b) and (e) include a fresh interpreter; each is the median of its runs (1 run with
``--quick``, 2 without; (c) 3 runs). A run takes about 25 s per robot (``--quick``: about 15 s) on
2 quiet cores.

Run: ``python benchmarks/bench_build.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:  # imported as benchmarks.bench_build
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

AD_CHECK_POINTS = 5
AD_CHECK_RTOL = 1e-9

_GENERATE = """
import time
t0 = time.perf_counter()
import hydrogen
from hydrogen.codegen.generate import DEFAULT_NUMBERS, derive, render
t1 = time.perf_counter()
model = hydrogen.load_model({model!r})
t2 = time.perf_counter()
functions, names = derive(model, DEFAULT_NUMBERS)  # as hydrogen.build generates by default
t3 = time.perf_counter()
render(model, {out!r}, functions=functions, names=names, numbers=DEFAULT_NUMBERS)
t4 = time.perf_counter()
print("import_s", t1 - t0)
print("load_model_s", t2 - t1)
print("derive_s", t3 - t2)
print("render_s", t4 - t3)
print("total_s", t4 - t0)
"""

_BUILD = """
import time
t0 = time.perf_counter()
import hydrogen
model = hydrogen.load_model({model!r})
t1 = time.perf_counter()
dyn = hydrogen.build(model, cache={cache!r}, generated={generated!r})
t2 = time.perf_counter()
print("import_s", t1 - t0)
print("build_s", t2 - t1)
print("n_functions", len(dyn.functions) if hasattr(dyn, "functions") else -1)
"""


def _committed_dir(name: str) -> Path:
    return common.REPO / "generated" / name


def _same_files(a: Path, b: Path) -> bool:
    """The two generated folders hold the same files, byte for byte (the manifest without its
    derivation hash: an edit of the derivation code that changes nothing generated is current)."""
    names = {p.name for p in a.iterdir() if not p.name.startswith(".")}
    if names != {p.name for p in b.iterdir() if not p.name.startswith(".")}:
        return False
    for n in names:
        x, y = (a / n).read_bytes(), (b / n).read_bytes()
        if n == "manifest.json":
            x, y = (json.loads(v) for v in (x, y))
            x.pop("derivation_hash", None)
            y.pop("derivation_hash", None)
        if x != y:
            return False
    return True


def bench_generate(name: str, runs: int, keep: Path) -> dict:
    """(a) for robot ``name``; the last run's folder is copied to ``keep`` for (b)."""
    rows = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory(prefix="bench_build_gen_") as tmp:
            stdout, wall = common.run_python(_GENERATE.format(out=tmp, model=name))
            r = common.parse_keyed(stdout)
            r["process_wall_s"] = wall
            r["files"] = len(list(Path(tmp).iterdir()))
            committed = _committed_dir(name)
            r["matches_committed"] = committed.is_dir() and _same_files(Path(tmp), committed)
            shutil.rmtree(keep, ignore_errors=True)
            shutil.copytree(tmp, keep)
            rows.append(r)
    keys = ("process_wall_s", "total_s", "import_s", "load_model_s", "derive_s", "render_s")
    out = {k: common.median(r[k] for r in rows) for k in keys}
    out.update(runs=rows, files=rows[-1]["files"], matches_committed=all(r["matches_committed"] for r in rows))
    return out


#: (e): the controller and the length of the first run
FIRST_RUN_CONTROLLER = "adaptive-robust"
FIRST_RUN_DURATION = 0.05

_FIRST_RUN = """
import resource, time
t0 = time.perf_counter()
from pathlib import Path
import hydrogen
from hydrogen.simulation.scenarios import default_scenario_name
model = hydrogen.load_model({model!r})
scenario = default_scenario_name(model)
cache, generated = Path({cache!r}), Path({generated!r})
t1 = time.perf_counter()
if {route!r} == "per_controller":
    dyn = hydrogen.build(model, cache=cache, generated=generated, controllers=({controller!r},))
else:  # every function in one library, as hydrogen.build compiled it before the libraries were split
    from hydrogen.codegen.generate import read_manifest
    from hydrogen.dynamics import Dynamics
    from hydrogen.runtime.compiler import Toolchain, compile_library
    from hydrogen.runtime.extension import attach_extension
    from hydrogen.runtime.library import GeneratedLibrary
    manifest = read_manifest(generated)
    sources = [generated / e["source"] for e in manifest["functions"]] + [generated / d for d in manifest["drivers"]]
    lib = GeneratedLibrary(compile_library(sources, model.name, Toolchain(), cache=cache), manifest, generated,
                           numbers=model.numbers)
    attach_extension(lib, Toolchain(), cache=cache)
    dyn = Dynamics(model, lib)
t2 = time.perf_counter()
res = hydrogen.simulate(scenario, {controller!r}, dyn=dyn, duration={duration!r})
t3 = time.perf_counter()
ru_s, ru_c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print("import_s", t1 - t0)
print("build_s", t2 - t1)
print("first_simulate_s", t3 - t0)
print("cpu_s", ru_s.ru_utime + ru_s.ru_stime + ru_c.ru_utime + ru_c.ru_stime)
print("compiler_cpu_s", ru_c.ru_utime + ru_c.ru_stime)
print("periods", len(res.t))
"""

#: (e)'s routes: the current one, and every function in one library
FIRST_RUN_ROUTES = ("per_controller", "one_library")


def bench_first_run(name: str, generated: Path, runs: int) -> dict:
    """(e) for robot ``name`` from the generated folder ``generated``: each route from a fresh cache in a
    fresh process, the routes alternating (which goes first swaps each run)."""
    rows = {route: [] for route in FIRST_RUN_ROUTES}
    with tempfile.TemporaryDirectory(prefix="bench_build_first_") as root:
        for i in range(runs):
            order = FIRST_RUN_ROUTES if i % 2 == 0 else FIRST_RUN_ROUTES[::-1]
            for route in order:
                cache = Path(root) / f"{route}{i}"
                stdout, wall = common.run_python(_FIRST_RUN.format(
                    model=name, cache=str(cache), generated=str(generated), route=route,
                    controller=FIRST_RUN_CONTROLLER, duration=FIRST_RUN_DURATION))
                r = common.parse_keyed(stdout)
                r["process_wall_s"] = wall
                r["sources_compiled"] = _sources_compiled(cache)
                r["libraries"] = len(list(cache.glob("build/*/build.json")))
                rows[route].append(r)
                shutil.rmtree(cache, ignore_errors=True)
    from hydrogen.runtime.compiler import usable_cores

    out = {"controller": FIRST_RUN_CONTROLLER, "duration_s": FIRST_RUN_DURATION, "usable_cores": usable_cores()}
    for route, rs in rows.items():
        out[route] = {k: common.median(r[k] for r in rs) for k in
                      ("process_wall_s", "first_simulate_s", "build_s", "cpu_s", "compiler_cpu_s")}
        out[route].update(sources_compiled=rs[0]["sources_compiled"], libraries=rs[0]["libraries"], runs=rs)
    new, old = out["per_controller"], out["one_library"]
    out["wall_ratio"] = old["process_wall_s"] / new["process_wall_s"]
    out["cpu_ratio"] = old["cpu_s"] / new["cpu_s"]
    return out


def _sources_compiled(cache: Path) -> int:
    n = 0
    for info in cache.glob("build/*/build.json"):
        n += len(json.loads(info.read_text()).get("sources", []))
    return n


def bench_build_times(name: str, generated: Path, runs_clean: int, runs_warm: int) -> tuple[dict, dict]:
    clean, warm = [], []
    with tempfile.TemporaryDirectory(prefix="bench_build_cache_") as root:
        for i in range(runs_clean):
            cache = Path(root) / f"cache{i}"
            stdout, wall = common.run_python(_BUILD.format(cache=str(cache), model=name, generated=str(generated)))
            r = common.parse_keyed(stdout)
            r["process_wall_s"] = wall
            r["sources_compiled"] = _sources_compiled(cache)
            clean.append(r)
        cache = Path(root) / "cache0"
        for _ in range(runs_warm):
            stdout, wall = common.run_python(_BUILD.format(cache=str(cache), model=name, generated=str(generated)))
            r = common.parse_keyed(stdout)
            r["process_wall_s"] = wall
            warm.append(r)
        shutil.rmtree(root, ignore_errors=True)

    def summary(rows):
        return {"build_s": common.median(r["build_s"] for r in rows),
                "process_wall_s": common.median(r["process_wall_s"] for r in rows),
                "import_s": common.median(r["import_s"] for r in rows), "runs": rows}

    c, w = summary(clean), summary(warm)
    c["sources_compiled"] = clean[0]["sources_compiled"]
    w["under_1s"] = max(r["build_s"] for r in warm) < 1.0
    return c, w


# ---------------------------------------------------------------------------------------------
# (d) Theorem 1: SymPy's tau_d_dot against CasADi's forward AD
# ---------------------------------------------------------------------------------------------
def _stage(symbols) -> str:
    """Stage name of an intermediate from its first symbol: ``taud_dot_0`` -> ``taud_dot``."""
    return str(symbols[0]).rsplit("_", 1)[0]


def backstepping_ad_function(parts, name: str = "ctrl_backstepping_ad"):
    """The CasADi Function of ``parts`` built like ``to_casadi_function``, except that the
    ``taud_dot`` stage is ``jtimes(tau_d, X, Xdot)``: X = [q, qdot, qd0, qd1, qd2],
    Xdot = [qdot, q̈ (the acc stage), qd1, qd2, qd3]."""
    import casadi as ca
    import sympy as sp

    from hydrogen.codegen.sympy_to_casadi import SympyToCasadi, input_symbols

    table, named = input_symbols(parts.inputs)
    sx_in = dict(named)
    conv = SympyToCasadi(table)
    bound, seen = {}, []
    for symbols, value in parts.intermediates:
        stage = _stage(symbols)
        seen.append(stage)
        if isinstance(value, tuple) and value[0] == "inverse":
            mat = conv(value[1])
            sx = ca.solve(mat, ca.SX.eye(mat.shape[0]))
        elif isinstance(value, tuple) and value[0] == "solve":
            sx = ca.solve(conv(value[1]), conv(value[2]))
        elif stage == "taud_dot":
            if "taud" not in bound or "acc" not in bound:
                raise RuntimeError(f"taud_dot before taud/acc in the intermediates: {seen}")
            X = ca.vertcat(*(sx_in[k] for k in ("q", "qdot", "qd0", "qd1", "qd2")))
            Xdot = ca.vertcat(sx_in["qdot"], bound["acc"], sx_in["qd1"], sx_in["qd2"], sx_in["qd3"])
            sx = ca.jtimes(bound["taud"], X, Xdot)
        else:
            sx = conv(value)
        bound[stage] = sx
        conv.define(symbols, sx)
    missing = {"acc", "taud", "taud_dot", "fd", "fd_dot", "v", "u_raw"} - set(bound)
    if missing:
        raise RuntimeError(f"intermediate stages {sorted(missing)} not found; stages are {seen}")
    sx_out = [conv(sp.Matrix(e) if not isinstance(e, sp.MatrixBase) else e) for _, e in parts.outputs]
    names_in = [n for n, _ in parts.inputs]
    return ca.Function(name, [sx_in[n] for n in names_in], sx_out, names_in,
                       [n for n, _ in parts.outputs], {"cse": True})


def bench_ad(name: str) -> dict:
    import hydrogen
    from hydrogen.codegen.casadi_functions import shape_of, to_casadi_function
    from hydrogen.controllers import controller, function_name
    from hydrogen.symbolic.functions import SymbolicFunction

    model = hydrogen.load_model(name)
    fname = function_name("backstepping")
    t0 = time.perf_counter()
    parts = controller("backstepping").derive(model)
    t_derive = time.perf_counter() - t0
    sf = SymbolicFunction(fname, parts.inputs, parts.outputs, "", parts.intermediates)
    t0 = time.perf_counter()
    f_sympy = to_casadi_function(sf, cse=True)
    t_sympy = time.perf_counter() - t0
    t0 = time.perf_counter()
    f_ad = backstepping_ad_function(parts)
    t_ad = time.perf_counter() - t0
    values = common.InputValues(hydrogen.build(model))

    entry = {"name": fname, "inputs": [[n, *shape_of(m)] for n, m in parts.inputs]}
    out_names = [n for n, _ in parts.outputs]
    worst = {n: 0.0 for n in out_names}
    for seed in range(AD_CHECK_POINTS):
        args = [np.reshape(v, (r, c), order="F")
                for (_, v), (_, r, c) in zip(values.function_inputs(entry, seed=100 + seed), entry["inputs"])]
        a, b = f_sympy(*args), f_ad(*args)
        for n, x, y in zip(out_names, a, b):
            x, y = np.asarray(x.full()), np.asarray(y.full())
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
                raise AssertionError(f"{n}: non-finite output at check point {seed}")
            rel = float(np.max(np.abs(x - y)) / max(float(np.max(np.abs(x))), 1e-300))
            worst[n] = max(worst[n], rel)
    bad = {n: e for n, e in worst.items() if e > AD_CHECK_RTOL}
    if bad:
        raise AssertionError(f"{name}: SymPy and CasADi-AD controllers disagree (max relative error): {bad}")

    manifest = json.loads((_committed_dir(name) / "manifest.json").read_text())
    in_manifest = next((f["instructions"] for f in manifest["functions"] if f["name"] == fname), None)
    n_sympy, n_ad = f_sympy.n_instructions(), f_ad.n_instructions()
    return {
        "sympy_instructions": n_sympy, "casadi_ad_instructions": n_ad,
        "manifest_instructions": in_manifest, "ratio_ad_over_sympy": n_ad / n_sympy,
        "no_larger_than_ad": n_sympy <= n_ad,
        "check_points": AD_CHECK_POINTS, "max_relative_error": worst,
        "sympy_nodes": f_sympy.n_nodes(), "casadi_ad_nodes": f_ad.n_nodes(),
        "derive_parts_s": t_derive, "to_casadi_sympy_s": t_sympy, "to_casadi_ad_s": t_ad,
    }


def run_robot(name: str, quick: bool = False) -> dict:
    """(a)-(d) above for robot ``name``."""
    runs = 1 if quick else 2
    with tempfile.TemporaryDirectory(prefix="bench_build_keep_") as keep:
        folder = Path(keep) / name
        gen = bench_generate(name, runs, folder)
        clean, warm = bench_build_times(name, folder, runs, 3)
        first = bench_first_run(name, folder, runs)
    import hydrogen
    from hydrogen.codegen.generate import check

    committed = _committed_dir(name)
    stale = check(hydrogen.load_model(name), committed) if committed.is_dir() else ["missing"]
    return {"model": name, "generate": gen, "build_clean": clean, "build_warm": warm,
            "committed_stale_by_hash": stale, "controller_instructions": bench_ad(name), "first_run": first}


def run(quick: bool = False) -> dict:
    """(a)-(d) above for every shipped robot; returns JSON-serialisable results."""
    t_start = time.perf_counter()
    robots = {name: run_robot(name, quick) for name in common.robots()}
    return {"robots": robots, "quick": quick, "wall_s": time.perf_counter() - t_start,
            "machine": common.machine_info(), "python": sys.executable, "cpu_count": os.cpu_count()}


def print_table(res: dict) -> None:
    m = res["machine"]
    print(f"machine : {m['processor']}, {m['cpu_count']} CPUs; python {m['python']}, sympy {m['sympy']}, "
          f"casadi {m['casadi']}; {m['cc']}")
    for r in res["robots"].values():
        _print_robot(r)
    print(f"whole benchmark {res['wall_s']:.1f} s")


def _print_robot(res: dict) -> None:
    g, c, w, d = (res[k] for k in ("generate", "build_clean", "build_warm", "controller_instructions"))
    n = len(g["runs"])
    print(f"\n{res['model']}: build times (fresh Python process each; median of {n} run{'s' if n > 1 else ''} "
          f"for (a), (b); {len(w['runs'])} for (c)):")
    header = f"{'step':<58} {'seconds':>9}"
    print(header)
    print("-" * len(header))
    rows = [
        ("(a) generation from scratch: process wall", g["process_wall_s"]),
        ("      inside: import hydrogen (+ sympy, casadi)", g["import_s"]),
        ("      inside: load_model", g["load_model_s"]),
        ("      inside: derive_functions (SymPy derivation alone)", g["derive_s"]),
        ("      inside: render (SymPy -> CasADi -> C, manifest)", g["render_s"]),
        (f"(b) build, clean cache ({c['sources_compiled']} sources): build()", c["build_s"]),
        ("      process wall", c["process_wall_s"]),
        ("(c) build again, nothing changed: build()", w["build_s"]),
        ("      process wall", w["process_wall_s"]),
    ]
    for label, v in rows:
        print(f"{label:<58} {v:>9.3f}")
    print(f"(a) wrote {g['files']} files, identical to the committed generated/ (manifest without its "
          f"derivation hash): {g['matches_committed']}")
    if res["committed_stale_by_hash"]:
        print(f"    note: the committed generated/{res['model']} is stale by its hash (build() regenerates it into "
              f"the cache): {'; '.join(res['committed_stale_by_hash'])}")
    print(f"(c) under 1 s: {w['under_1s']} (runs: " + ", ".join(f"{r['build_s']:.3f}" for r in w["runs"]) + ")")
    f = res.get("first_run")
    if f:
        print(f"(e) cold: fresh process and cache to the first simulate of {f['controller']} ({f['duration_s']:g} s of "
              f"the first scenario); seconds:")
        header = f"{'route':<58} {'wall':>7} {'CPU':>7} {'sources':>7}"
        print(header)
        print("-" * len(header))
        for key, label in (("per_controller", "core + that controller's library (now)"),
                           ("one_library", "every function in one library (before)")):
            v = f[key]
            print(f"{label:<58} {v['process_wall_s']:>7.2f} {v['cpu_s']:>7.2f} {v['sources_compiled']:>7.0f}")
        print(f"    before / now: wall {f['wall_ratio']:.2f}x, CPU {f['cpu_ratio']:.2f}x")
    print("(d) Theorem 1 controller (ctrl_backstepping, leg-force mapping), CasADi instructions with cse:")
    header = f"{'tau_d_dot by':<40} {'instructions':>12} {'SX nodes':>9}"
    print(header)
    print("-" * len(header))
    print(f"{'SymPy (hydrogen, as generated)':<40} {d['sympy_instructions']:>12d} {d['sympy_nodes']:>9d}")
    print(f"{'CasADi forward AD (jtimes)':<40} {d['casadi_ad_instructions']:>12d} {d['casadi_ad_nodes']:>9d}")
    print(f"manifest ctrl_backstepping: {d['manifest_instructions']}; AD / SymPy = {d['ratio_ad_over_sympy']:.2f}; "
          f"SymPy's no larger than AD: {d['no_larger_than_ad']}")
    errs = ", ".join(f"{k} {v:.1e}" for k, v in d["max_relative_error"].items())
    print(f"same outputs at {d['check_points']} random points (max relative error: {errs})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one run of (a) and (b) instead of two")
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    a = ap.parse_args(argv)
    res = run(quick=a.quick)
    print_table(res)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(res, indent=2) + "\n")
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
