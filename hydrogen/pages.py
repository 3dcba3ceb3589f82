"""Documentation pages written by the runs that produce their numbers.

``hydrogen figures --out DIR`` ends by writing ``DIR/results.md`` (:func:`write_results_page`) from
the comparison table and the figures it has just written there; ``hydrogen bench --json FILE`` ends
by writing ``benchmarks.md`` beside FILE (:func:`write_benchmarks_page`) from that JSON (and from
``bench_release_repeats.json`` beside it, when present). The committed pages under ``docs/`` are
these functions' output on the committed data (``tools/render_pages.py``; a test checks it), so no
number on them is copied by hand.
"""
from __future__ import annotations

import json
from pathlib import Path

from .fileio import atomic_write

__all__ = ["figures_folder", "results_page", "write_results_page", "benchmarks_page", "write_benchmarks_page",
           "check_benchmarks_page",
           "RESULTS_PAGE", "BENCHMARKS_PAGE", "REPEATS_JSON"]

RESULTS_PAGE = "results.md"
BENCHMARKS_PAGE = "benchmarks.md"
#: The spread between whole runs of the release comparison (``bench_release.py --repeat N``).
REPEATS_JSON = "bench_release_repeats.json"

_DO_NOT_EDIT = "<!-- written by {cmd}; do not edit: rerun it -->"
#: The start of the first line of every page ``hydrogen bench --json`` writes: how it knows its own.
_BENCH_MARK = _DO_NOT_EDIT.split("{cmd}")[0] + "hydrogen bench --json "


# --------------------------------------------------------------------------------------------
# Results (hydrogen figures)


def figures_folder(name: str) -> str:
    """The folder (relative to the repository) that holds a built-in model's committed figures and
    results page: ``docs/figures`` for the default robot, ``docs/figures/<name>`` for the others."""
    from .model import DEFAULT_MODEL
    return "docs/figures" if name == DEFAULT_MODEL else f"docs/figures/{name}"


def results_page(model, folder) -> str:
    """Markdown of a model's results: the comparison table (``folder/table.md``) and every figure in
    ``folder``, grouped by the model's scenarios in description order, captioned with their labels."""
    from .simulation.scenarios import scenario as named_scenario, scenario_names

    folder = Path(folder)
    table = (folder / "table.md").read_text(encoding="utf-8") if (folder / "table.md").is_file() else ""
    figures = sorted(p.name for p in folder.glob("*.png"))
    out = [_DO_NOT_EDIT.format(cmd=f"hydrogen figures --model {model.name}"), "",
           f"# Results: {model.name}", "",
           f"Written by `hydrogen figures --model {model.name}` from the runs it has just made. "
           "Maximum errors are in % of each coordinate's reference amplitude over the scenario's metric "
           "window (the scenario's `metric_start`).", ""]
    if table:
        out += ["## Comparison table", "", table.strip(), ""]
    names = sorted(scenario_names(model), key=len, reverse=True)  # longest first: "z-1hz" before "z"
    used = set()
    for name in scenario_names(model):
        mine = [f for f in figures if f not in used and _belongs(f, name, names)]
        if not mine:
            continue
        used.update(mine)
        label = named_scenario(name, model).label
        out += [f"## {label}" if label != name else f"## {name}", ""]
        for f in mine:
            out += [f"![{name}: {Path(f).stem}]({f})", ""]
    rest = [f for f in figures if f not in used]
    if rest:
        out += ["## Other figures", ""] + [f"![{Path(f).stem}]({f})\n" for f in rest]
    return "\n".join(out).rstrip() + "\n"


def _belongs(filename: str, name: str, names) -> bool:
    stem = Path(filename).stem
    owner = next((n for n in names if stem == n or stem.startswith(n + "_")), None)
    return owner == name


def write_results_page(model, folder) -> Path:
    """Write :func:`results_page` to ``folder/results.md`` atomically; returns its path."""
    path = Path(folder) / RESULTS_PAGE
    atomic_write(path, results_page(model, folder))
    return path


# --------------------------------------------------------------------------------------------
# Benchmarks (hydrogen bench)


def _f(v, digits=2):
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    v = float(v)
    if abs(v) >= 100:
        return f"{v:,.0f}"
    return f"{v:.{digits}f}" if abs(v) >= 0.01 or v == 0 else f"{v:.{digits}g}"


def _table(header, rows) -> list:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return lines + [""]


_ROUTES = (("a_lambdify_python_loop", "(a) Python loop, `sympy.lambdify` (numpy) functions"),
           ("b_casadi_python_loop", "(b) Python loop, CasADi Functions called from Python"),
           ("c_stepping_api", "(c) hydrogen stepping API, one call per period from Python"),
           ("d_c_loop", "(d) the whole loop in C (`hydrogen.simulate`)"))


def _loop(b) -> list:
    robots = b.get("robots", {})
    if not robots:
        return []
    out = ["## The closed loop", "",
           "Per control period of each robot's simulation scenario (sensors, forward kinematics or encoders, "
           "controller, RK4 plant sub-steps); every route is checked to reproduce the compiled trajectory "
           "before it is timed (`benchmarks/bench_loop.py`).", ""]
    header = ["route"] + [f"{r['model']} {r['scenario']} ({r['controller']}), µs per period (× d)" for r in robots.values()]
    rows = [[label] + [f"{_f(r['per_period_us'][k])} ({_f(r['ratio_to_c_loop'][k], 1)})" for r in robots.values()]
            for k, label in _ROUTES]
    out += _table(header, rows)
    for r in robots.values():
        s = r.get("sim", {})
        if s:
            out.append(f"* **{r['model']}**: {s['scenario']} ({_f(s['sim_time_s'], 0)} s simulated) takes "
                       f"{_f(1e3 * s['simulate_call_wall_s'], 1)} ms through `hydrogen.simulate` with the library "
                       f"loaded ({_f(1e3 * s['loop_wall_s'], 1)} ms in the C loop): **{_f(s['real_time_factor'], 0)}× "
                       "real time**.")
        w = r.get("sweep", {})
        if w:
            rates = w["runs_per_s"]
            out.append(f"* **{r['model']} sweep**: {w['runs']} runs of {w['scenario']}, "
                       + ", ".join(f"{_f(v, 1)} runs/s with {k} worker{'s' if str(k) != '1' else ''}"
                                  for k, v in rates.items())
                       + f" ({_f(w['speedup_2_over_1'])}× with two).")
    return out + [""]


def _sweep(b) -> list:
    out = ["## Sweeps and identification", ""]
    rates = b.get("runs_per_s", {})
    names = {"pool_new": "default process pool (new per sweep)", "pool_persistent": "persistent `ProcessPoolExecutor`",
             "dask": "Dask `LocalCluster`, process workers"}
    if rates:
        out.append(f"{b.get('runs')} runs of {_f(b.get('sim_duration_s'))} s on {b.get('workers')} workers "
                   "(`benchmarks/bench_sweep.py`):")
        out.append("")
        out += _table(["executor", "runs/s"], [[names.get(k, k), _f(v, 1)] for k, v in rates.items()])
        if b.get("dask_cluster_start_s") is not None:
            out += [f"The Dask cluster took {_f(b['dask_cluster_start_s'])} s to start.", ""]
    batch = b.get("batch")
    if batch:
        former = batch.get("former") or {}
        names = {"c_loop": "bare C loop (`LoopRunner.run` alone)",
                 "per_run_former": f"one run per task, the former plant integration ({former.get('substeps')} "
                                   f"sub-steps, pressure bounds `{former.get('pressure_bounds')}`)",
                 "per_run": "one run per task", "batched": "batched, process pool (default)",
                 "batched_threads": "batched, thread pool"}
        out.append(f"{batch.get('runs')} runs of z-1hz with P ({batch.get('gain_sets')} gain sets x "
                   f"{batch.get('seeds')} seeds, {_f(batch.get('sim_duration_s'))} s each) on "
                   f"{batch.get('workers')} workers, per CPU-second of the parent and its workers:")
        out.append("")
        of = batch.get("of_c_loop", {})
        out += _table(["route", "runs/CPU-s", "of the C loop"],
                      [[names.get(k, k), _f(v, 1), _f(of.get(k))] for k, v in batch.get("runs_per_cpu_s", {}).items()])
        if batch.get("batched_over_former"):
            out += [f"The batched sweep does {batch['batched_over_former']:.2f}× the runs per CPU-second of one run "
                    "per task at the former plant integration (the sweep before both).", ""]
        rel = batch.get("release") or {}
        if rel.get("runs_per_cpu_s"):
            out += [f"The same 100 runs through `hydrogen.sweep` of commit {rel['commit']} (its own code, description "
                    f"and plant integration, in the same benchmark run): {_f(rel['runs_per_cpu_s'], 1)} runs/CPU-s; "
                    f"the batched sweep does {batch['batched_over_release']:.2f}× that.", ""]
    ident = b.get("identify_paper_sim")
    if ident:
        st = ident.get("stages_s", {})
        out += [f"Identification of the paper-sim log ({_f(ident['samples'])} samples, the rig's sensor noise): "
                f"{_f(ident['wall_s'])} s, of which forward kinematics {_f(st.get('forward_kinematics'))} s. "
                "Errors against the truth, %: θ " + ", ".join(_f(v) for v in ident.get("theta_error_pct", []))
                + "; γ " + ", ".join(_f(v) for v in ident.get("gamma_error_pct", [])) + ".", ""]
    return out


def _functions(b) -> list:
    out = ["## Generated functions, C only", "",
           "Each function in a stand-alone C driver (`benchmarks/bench_functions.py`, built with "
           "`-O2 -std=c99`): CasADi instructions and the median ns per call over the repeats.", ""]
    for r in b.get("robots", {}).values():
        rows = sorted(r.get("functions", {}).items(), key=lambda kv: kv[1]["instructions"])
        out += [f"**{r['model']}**", ""]
        out += _table(["function", "instructions", "ns per call", "ns per instruction"],
                      [[f"`{k}`", _f(v["instructions"]), _f(v["ns_per_call"]), _f(v["ns_per_instruction"])]
                       for k, v in rows])
    return out


def _build(b) -> list:
    out = ["## Build", "",
           "Generation from scratch in a fresh process, the SymPy derivation and the rendering within it, a clean compile and "
           "`hydrogen.build()` with nothing changed (`benchmarks/bench_build.py`), seconds:", ""]
    rows = []
    for r in b.get("robots", {}).values():
        g, c, w = r.get("generate", {}), r.get("build_clean", {}), r.get("build_warm", {})
        rows.append([r["model"], _f(g.get("process_wall_s")), _f(g.get("derive_s")), _f(g.get("render_s")),
                     _f(c.get("build_s")), _f(c.get("sources_compiled")), _f(w.get("build_s"))])
    out += _table(["robot", "generation", "of it SymPy derivation", "rendering (SymPy → CasADi → C)",
                   "clean compile", "sources", "warm build"], rows)
    out += ["The clean compile is the core library (kinematics, rigid body, hydraulics, plant, C loop); each "
            "controller's library is compiled on its first use.", ""]
    rows = []
    for r in b.get("robots", {}).values():
        f = r.get("first_run")
        if f:
            now, before = f["per_controller"], f["one_library"]
            rows.append([r["model"], f"`{f['controller']}`", _f(now["process_wall_s"]), _f(now["cpu_s"]),
                         _f(now["sources_compiled"]), _f(before["process_wall_s"]), _f(before["cpu_s"]),
                         _f(before["sources_compiled"]), f"{f['wall_ratio']:.2f}× / {f['cpu_ratio']:.2f}×"])
    if rows:
        out += ["Cold start to the first run: a fresh process and cache, then `hydrogen.simulate` of one controller "
                "(0.05 s of the robot's first scenario), wall and CPU seconds (the process and its compilers), with "
                "the core and that controller's library against every generated function compiled into one "
                "library (as before the libraries were split), side by side in one run:", ""]
        out += _table(["robot", "controller", "now: wall", "CPU", "sources", "one library: wall", "CPU", "sources",
                       "one library / now (wall / CPU)"], rows)
    rows = []
    for r in b.get("robots", {}).values():
        ci = r.get("controller_instructions")
        if ci:
            rows.append([r["model"], _f(ci["sympy_instructions"]), _f(ci["casadi_ad_instructions"]),
                         _f(ci["no_larger_than_ad"])])
    if rows:
        out += ["Theorem 1's controller with τ̇_d derived in SymPy against τ̇_d from CasADi's forward AD of the "
                "same τ_d (CasADi instructions, with CSE):", ""]
        out += _table(["robot", "SymPy", "CasADi AD", "SymPy no larger"], rows)
    return out


def _flags(b) -> list:
    robots = b.get("robots", {})
    if not robots:
        return []
    flags = list(next(iter(robots.values()))["flags"])
    first = robots[next(iter(robots))]["flags"]
    chain = b.get("chain") or {}
    out = ["## Compiler flags", "", "C loop µs per period of each robot's simulation scenario with adaptive-robust, "
           "and in brackets the seconds of `hydrogen.build` from a clean cache (the core library and "
           "adaptive-robust's, the variant the scenario's gains run) (`benchmarks/bench_flags.py`)"
           + (f"; the last column: seconds to compile the largest source of the {chain['n']}-link planar chain "
              f"(`{chain['source']}`, {chain['source_kb']:.0f} kB, what its first adaptive run waits for), "
              "one compiler alone" if chain else "") + ":", ""]
    out += _table(["flags"] + [f"{r['model']} µs (compile s)" for r in robots.values()]
                  + ([f"chain n = {chain['n']}, s"] if chain else []),
                  [[f"`{' '.join(first[fl]['cflags'])}`"
                    + (" (default)" if "default" in fl else " (a quick build's)" if "quick build" in fl else "")]
                   + [f"{_f(r['flags'].get(fl, {}).get('loop_us_per_period'))} "
                      f"({_f(r['flags'].get(fl, {}).get('compile_s'))})" for r in robots.values()]
                   + ([_f(chain["compile_s"].get(fl))] if chain else []) for fl in flags])
    return out


_CALLS = (("extension", "`dyn.<function>(...)`, extension"), ("extension_out", "`dyn.<function>(..., out=buf)`, extension"),
          ("extension_function", "`dyn.functions[name](...)`, extension"),
          ("ctypes", "`dyn.<function>(...)`, ctypes (`backend=\"ctypes\"`)"),
          ("casadi_external", "the same C through `casadi.external`"),
          ("D_C_G_then_numpy_solve", "D, C and G through the extension, then `numpy.linalg.solve`"))


def _calls(b) -> list:
    per = b.get("per_call", {})
    if not per:
        return []
    fns = list(per)
    out = ["## Calls from Python", "",
           f"Each route from Python against the C cost of the same function (`benchmarks/bench_calls.py`), "
           f"the platform's functions, the fastest of {b.get('repeats')} repeats, ns per call:", ""]
    rows = [["C work (stand-alone driver)"] + [_f(b["c_ns"][f]["min"], 0) for f in fns]]
    for key, label in _CALLS:
        if any(key in per[f] for f in fns):
            rows.append([label] + [_f(1e9 * per[f][key]["min_s"], 0) if key in per[f] else "" for f in fns])
    pin = b.get("pinocchio")
    if pin:
        rows.append([f"Pinocchio {pin['version']}: `rnea`, `computeJointTorqueRegressor` / `aba`",
                     f"{_f(1e9 * pin['rnea']['min_s'], 0)}, {_f(1e9 * pin['computeJointTorqueRegressor']['min_s'], 0)}",
                     _f(1e9 * pin["aba"]["min_s"], 0)][:1 + len(fns)])
    out += _table(["route"] + [f"`{f}`" for f in fns], rows)
    batches = b.get("batches", {})
    if batches:
        sizes = list(next(iter(batches.values())))
        out += ["Batches: one call with n stacked states, ns per state (× the C work):", ""]
        out += _table(["n"] + sizes, [[f"`{f}`"] + [f"{_f(v[s]['per_state_ns'], 0)} ({_f(v[s]['ratio_to_c'], 1)})"
                                                    for s in sizes] for f, v in batches.items()])
    return out


def _release(b, repeats) -> list:
    if not b:
        return []
    out = ["## Side by side with the previous release", "",
           f"`benchmarks/bench_release.py`: commit `{b.get('previous')}` (the last release before robots became "
           "descriptions), checked out and run in its own processes in the same run.", ""]
    ins = b.get("instructions", {})
    if ins:
        out += _table(["function", "previous", "current", "change %", "bound", "status"],
                      [[f"`{k}`", _f(v.get("previous")), _f(v.get("current")), _f(v.get("change_pct"), 1),
                        v.get("bound") or "–", v.get("status") or "–"] for k, v in ins.items()])
    lp = b.get("loop_per_period", {})
    if lp:
        out += [f"paper-sim's C loop per period (median of interleaved runs): previous {_f(lp['previous']['us'])} µs, "
                f"current as shipped {_f(lp['current']['us'])} µs ({_f(100 * lp['change'], 1)} %), current with "
                f"the previous release's law {_f(lp['current_gradient_law']['us'])} µs "
                f"({_f(100 * lp['change_gradient_law'], 1)} %).", ""]
    g = b.get("generation", {})
    if g:
        out += [f"Generation from scratch: {_f(g['previous']['process_wall_s'])} → {_f(g['current']['process_wall_s'])} s "
                f"({_f(g['ratio'])}×).", ""]
    checks = b.get("checks", {})
    if checks:
        out += _table(["check", "holds"], [[k, _f(v) if isinstance(v, bool) else len(v)] for k, v in checks.items()])
    if repeats and repeats.get("runs"):
        out += [f"Whole runs of the comparison (`{REPEATS_JSON}`): the machine's speed drifts between runs far more "
                "than within one.", ""]
        out += _table(["run", "previous µs", "current µs", "change %", "previous release's law µs", "change %",
                       "generation ×"],
                      [[i + 1, _f(r["previous_us"]), _f(r["current_us"]), _f(100 * r["change"], 1),
                        _f(r["current_gradient_law_us"]), _f(100 * r["change_gradient_law"], 1),
                        _f(r["generation_ratio"])] for i, r in enumerate(repeats["runs"])])
        out += [f"Medians: as shipped {_f(100 * repeats['median_change'], 1)} %, with the previous release's law "
                f"{_f(100 * repeats['median_change_gradient_law'], 1)} %, generation "
                f"{_f(repeats['median_generation_ratio'])}×.", ""]
    return out


def _scaling(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    out = ["## How cost grows with the robot", "",
           "`benchmarks/bench_scaling.py`: a synthetic planar chain of n links (one cylinder per joint; θ = each "
           "link's mcx, mcz, Iyy) derived, generated, compiled and run, each n in a fresh process with a time "
           f"budget of {_f(b.get('budget_s'))} s; the adaptive-robust controller's first run compiles the library "
           "of the variant its gains run. Instruction counts are exact; seconds vary between runs.", ""]
    table = []
    for r in rows:
        i = r.get("instructions") or {}
        ctrl = (f"{_f(i.get('ctrl_backstepping'))} / {_f(i.get('ctrl_adaptive_robust'))} "
                f"({_f(i.get('ctrl_adaptive_robust_lean'))}) / {_f(i.get('ctrl_adaptive_observer'))} "
                f"({_f(i.get('ctrl_adaptive_observer_lean'))})")
        table.append([r["n"], _f(r.get("derive_s"), 1), f"{_f(r.get('generate_s'), 1)} + {_f(r.get('compile_s'), 1)}",
                      f"{_f(r.get('controller_compile_s'), 1)}"
                      + (f" ({r['controller_variant']})" if r.get("controller_variant") else ""), ctrl, _f(r.get("loop_us"), 1),
                      "timed out" if r.get("timed_out") else ""])
    out += _table(["n", "derivation s", "generation + compile s", "adaptive-robust first run s (variant)",
                   "backstepping / adaptive-robust (lean) / adaptive-observer (lean) instructions",
                   "C loop µs per period", ""], table)
    return out


#: The parametric variants of benchmarks/bench_folding.py, as the page names them.
_FOLDING = (("by_name", "by name"), ("shared", "by value"), ("per_use", "per use"))


def _folding(b) -> list:
    robots = b.get("robots", {})
    if not robots:
        return []
    out = ["## Folding the description's numbers", "",
           "`benchmarks/bench_folding.py`: every derived function generated folded (the description's numbers "
           "constants in the expressions, as shipped) and with the numbers as one more input, in one run: a symbol "
           "per description number (*by name*: what a vector of runtime parameters holds), per distinct value "
           "(*by value*) and per number met (*per use*); each checked against the folded function at the "
           "description's numbers and timed with the same driver. Sums over one call of each function "
           "(instructions, ns), and their ratios to folded:", ""]
    rows = []
    for r in robots.values():
        funcs = r.get("functions", {}).values()
        tot = {k: (sum(f[k]["instructions"] for f in funcs), sum(f[k]["ns_per_call"] for f in funcs))
               for k in ("folded", *(v for v, _ in _FOLDING))}
        fi, ft = tot["folded"]
        rows.append([r["model"], ", ".join(_f(r["numbers"].get(v)) for v, _ in _FOLDING), _f(fi), _f(ft),
                     *(f"{_f(tot[v][0] / fi)}× / {_f(tot[v][1] / ft)}×" for v, _ in _FOLDING),
                     _f(r.get("agree"))])
    out += _table(["robot", "numbers (by name, by value, per use)", "instructions folded", "ns folded",
                   *(f"{label}: instructions / ns" for _, label in _FOLDING), "agree"], rows)
    out += ["The controllers and the plant, by name against folded (instructions; ns per call):", ""]
    rows = []
    for r in robots.values():
        for name, f in r.get("functions", {}).items():
            if name.startswith("ctrl_") or name == "plant_rhs":
                rows.append([r["model"], f"`{name}`", _f(f["folded"]["instructions"]),
                             _f(f["by_name"]["instructions"]), _f(f["folded"]["ns_per_call"]),
                             _f(f["by_name"]["ns_per_call"])])
    return out + _table(["robot", "function", "instructions folded", "by name", "ns folded", "by name"], rows)


def _edit(b) -> list:
    robots = b.get("robots", {})
    if not robots:
        return []
    any_robot = next(iter(robots.values()))
    out = ["## From a numeric edit to the next run", "",
           f"`benchmarks/bench_edit.py`: a copy of each robot's description with gravity 0.1 % lower, then a fresh "
           f"process that builds it and runs `{any_robot['controller']}` for {_f(any_robot['duration_s'])} s of its "
           "first scenario in the C loop, by two routes: the default, the numbers as inputs, on a cache holding the "
           "shipped description's build (the same structure: the build only loads), and `numbers=\"constants\"` "
           "(generated and compiled again). Seconds, median of "
           f"{b.get('runs')} run{'s' if b.get('runs') != 1 else ''}:", ""]
    rows = []
    for name, r in robots.items():
        for route in ("inputs", "constants"):
            v = r[route]
            rows.append([name, route, _f(v["process_wall_s"]), _f(v["import_s"]), _f(v["build_s"]),
                         _f(v["simulate_s"]), "yes" if v["loaded_only"] else "no"])
        rows.append([name, "constants / inputs", f"{_f(r['wall_ratio'])}×", "", "", "", ""])
    return out + _table(["robot", "route", "process wall", "import", "build", "run", "build only loaded"], rows)


def _cold(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    out = ["## From a structural edit to the first run", "",
           f"`benchmarks/bench_cold.py`: a description whose structure changed (each shipped robot with gravity 0: "
           f"a number become zero, which the derivation holds exact), a spatial 3-DOF leg, a 7-link planar chain "
           f"and a leg loaded from a URDF (`benchmarks/data/urdf_leg.toml`: rpy joint origins, full inertia "
           f"tensors, a rotary vane and two four-way cylinders, nine adapted parameters) by both routes, the numbers "
           f"as inputs and folded, each in a fresh process with an empty cache: generation, the core library's "
           f"compile, and the first run of {_f(b.get('duration_s'))} s of the controller named (its first use "
           f"compiles the library of the variant it runs; the spatial leg, with no scenario, compiles the full one). "
           f"Seconds, median of {b.get('runs')} run{'s' if b.get('runs') != 1 else ''}:", ""]
    table = [[r["case"], r.get("controller", b.get("controller")), _f(r["process_wall_s"]), _f(r["cpu_s"]),
              _f(r["generate_s"]), _f(r["core_compile_s"]), _f(r["first_use_s"])] for r in rows]
    return out + _table(["case", "controller", "process wall", "CPU", "generation", "core compile", "first use"],
                        table)


def _structural(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    out = ["## A structural edit of a shipped robot, as a user meets it", "",
           "`benchmarks/bench_structural.py`: each shipped robot edited in structure on a cache that holds its "
           f"shipped build (the user built and ran it before): a fixed link added (a {b.get('payload_kg', 0):g} kg "
           "payload with a full inertia tensor, 0.3 m out from the last link on a tilted mount) and, where the robot "
           "has a moving joint, the first one's axis reversed. The payload is merged into the body it is fixed to "
           "(its inertia in that body's frame: no Jacobian of its own), so the robot keeps one body per moving "
           "joint and the closed form. A fresh process builds the edited robot for the "
           f"controller named and runs {_f(b.get('duration_s'))} s of its first scenario. The core's sources start "
           "compiling as soon as they are written, while the controller is derived; objects whose source did not "
           "change come from the object store. Each edit is built both ways: *optimized* (`hydrogen.build`'s "
           "default: the run waits for the optimized compile) and *quick* (`quick=True`, as `hydrogen simulate` "
           "builds for one run: what is not compiled yet compiles at -O0, the same numbers bit for bit, while the "
           "optimized compile goes on in the background and outlives the process). For the quick build: its "
           "compile, its CPU (without the compiles it left in the background), the seconds after the process "
           "ended until those were done, and a second run then (a new process, which links the optimized "
           f"objects). Seconds, median of {b.get('runs')} run{'s' if b.get('runs') != 1 else ''}:", ""]
    table = [[r["robot"], r["edit"], r["controller"], _f(r["process_wall_s"]), _f(r["cpu_s"]), _f(r["generate_s"]),
              _f(r["compile_s"]), _f(r.get("quick_process_wall_s")), _f(r.get("quick_cpu_s")),
              _f(r.get("quick_compile_s")), _f(r.get("background_s")), _f(r.get("next_run_s"))] for r in rows]
    return out + _table(["robot", "edit", "controller", "optimized: process wall", "CPU", "generation", "compile",
                         "quick: process wall", "CPU", "compile", "background after", "second run"], table)


def _code_edit(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    out = ["## An edit of hydrogen's code, as a developer meets it", "",
           "`benchmarks/bench_code_edit.py`: in a copy of the package beside its committed generated code, after "
           "the shipped robots were built and run (their objects in the cache), a rig part added (a viscous damper "
           "along each actuator: one module of `hydrogen/plant`) or a line added to the loop driver's template. A "
           "fresh process builds each shipped robot for the controller named and runs "
           f"{_f(b.get('duration_s'))} s of its first scenario: *alone*, as hydrogen does (the committed folder is "
           "stale for the plant's function and the loop drivers only; the cache's folder starts as its copy and "
           "derives the plant's function alone, or nothing after the template edit), and *whole*, the same build "
           "into a folder of its own, which derives every function it needs (as every edit of the package did when "
           "one hash covered all of its code); unchanged sources compile from the object store either way. Seconds, "
           f"median of {b.get('runs')} run{'s' if b.get('runs') != 1 else ''}, and the ratio whole / alone of the "
           "process wall:", ""]
    table = [[r["robot"], r["edit"], r["controller"], r["route"],
              f"{r['process_wall_s']:.2f}×" if r.get("ratio") else _f(r["process_wall_s"]),
              "" if r.get("ratio") else _f(r["cpu_s"]), "" if r.get("ratio") else _f(r["generate_s"]),
              "" if r.get("ratio") else _f(r["compile_s"])] for r in rows]
    return out + _table(["robot", "edit", "controller", "route", "process wall", "CPU", "generation", "compile"], table)


#: hydrogen's function and the recursive algorithm of benchmarks/bench_recursive.py it is compared with.
_RECURSIVE = (("forward_dynamics", "ABA", "aba"), ("inverse_dynamics", "RNEA", "rnea"), ("mass_matrix", "CRBA", "crba"))


def _own(r) -> str:
    own = r.get("form_own") or {}
    return f"{_f(own.get('mass_matrix'))} / {_f(own.get('inverse_dynamics'))}" if own else "–"


def _recursive(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    out = ["## Against the recursive algorithms", "",
           "`benchmarks/bench_recursive.py`: on the planar chain of `bench_scaling.py`, hydrogen's `forward_dynamics`, "
           "`inverse_dynamics` and `mass_matrix` against Featherstone's ABA, RNEA and CRBA (what Pinocchio "
           "implements) in local link frames, written over CasADi SX with the same inputs (θ symbolic), checked "
           "against `pinocchio` at random states. CasADi instructions with CSE, hydrogen / reference (ratio); "
           "*form*: the form of C, G and Y, whose own D and D a + C q̇ + G (what the controllers are derived "
           "with) the column after the three counts; seconds: hydrogen's rigid-body derivation and conversion.", ""]
    table = [[r["n"], r["form"],
              *(f"{_f(r['hydrogen'][h])} / {_f(r['reference'][k])} ({_f(r['ratio'][h])})" for h, _, k in _RECURSIVE),
              _own(r), _f(r["hydrogen_derive_s"] + r["hydrogen_convert_s"], 1),
              f"{max(r['check_max_rel'].values()):.0e}" if r.get("check_max_rel") else "–"] for r in rows]
    out += _table(["n", "form", *(f"`{h}` / {a}" for h, a, _ in _RECURSIVE), "form's D / D a + C q̇ + G",
                   "hydrogen s", "reference vs pinocchio"], table)
    g = b.get("growth") or {}
    if g:
        out += ["Growth, count ∝ nᵏ fitted over the table: " + ", ".join(
            f"`{h}` k = {_f(g[h])} ({a} {_f(g[k])})" for h, a, k in _RECURSIVE) + ".", ""]
    inputs = [r for r in rows if r.get("inputs")]
    if inputs:  # the default build: the description's numbers one more input, in both
        out += ["With the description's numbers as inputs (the default build): hydrogen's functions take every "
                "number they meet as one more input (a joint axis's 0 and ±1 entries are structure, as a "
                "Pinocchio joint's axis is its type), the reference the same numbers as SX symbols; the two "
                "agree at random states. Instructions, hydrogen / reference (ratio), and hydrogen's as inputs "
                "/ folded:", ""]
        out += _table(["n", "numbers", *(f"`{h}` / {a}" for h, a, _ in _RECURSIVE),
                       *(f"`{h}` inputs / folded" for h, _, _ in _RECURSIVE), "agreement"],
                      [[r["n"], r["inputs"]["numbers"],
                        *(f"{_f(r['inputs']['hydrogen'][h])} / {_f(r['inputs']['reference'][k])} "
                          f"({_f(r['inputs']['ratio'][h])})" for h, _, k in _RECURSIVE),
                        *(_f(r["inputs"]["over_folded"][h]) for h, _, _ in _RECURSIVE),
                        f"{r['inputs']['agree']:.0e}"] for r in inputs])
        worst = {h: max(r["inputs"]["ratio"][h] for r in inputs) for h, _, _ in _RECURSIVE}
        over = {h: max(r["inputs"]["over_folded"][h] for r in inputs) for h, _, _ in _RECURSIVE}
        folded = {h: max(r["ratio"][h] for r in rows) for h, _, _ in _RECURSIVE}
        out += [f"Largest over n = {rows[0]['n']} … {rows[-1]['n']}: hydrogen / reference folded "
                + ", ".join(f"`{h}` {_f(folded[h])}" for h, _, _ in _RECURSIVE) + "; as inputs "
                + ", ".join(f"`{h}` {_f(worst[h])}" for h, _, _ in _RECURSIVE) + "; as inputs / folded "
                + ", ".join(f"`{h}` {_f(over[h])}" for h, _, _ in _RECURSIVE) + ".", ""]
    traced = [r for r in rows if r.get("pinocchio_traced")]
    if traced:  # Pinocchio itself, every number a constant
        r0 = traced[0]
        out += [f"Pinocchio itself traced on SX (`cmeel-casadi-kin-dyn`, CasADi {r0['pinocchio_traced'].get('casadi')}, "
                "from a URDF of the same chain: its numbers, θ too, are constants) against hydrogen's and the "
                "reference's functions with θ given as numbers (SX folds them), instructions and hydrogen / "
                "Pinocchio:", ""]
        out += _table(["n", *(f"`{h}` / {a} / reference" for h, a, _ in _RECURSIVE)],
                      [[r["n"], *(f"{_f(r['hydrogen_theta_numeric'][h])} / {_f(r['pinocchio_traced'][k])} / "
                                  f"{_f(r['reference_theta_numeric'][k])} "
                                  f"({_f(r['hydrogen_theta_numeric'][h] / r['pinocchio_traced'][k])})"
                                  for h, _, k in _RECURSIVE)] for r in traced])
    return out


def _period(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    out = ["## Per period and per call: numbers as inputs, folded, and an earlier version", "",
           f"`benchmarks/bench_period.py`: the current version (the numbers as inputs), the same code built with "
           f"them folded (like for like) and commit `{b.get('baseline')}` (its own default build, descriptions "
           "and gains), and the current code on that commit's own descriptions (\"described\"; renamed keys "
           f"migrated), each in its own processes, rotating for {b.get('rounds')} rounds (medians): the C loop's µs per control period "
           f"of every scenario (`{b.get('controller')}`, the fastest of a few runs per round) and the ns per call "
           "from Python of every function all have with the same inputs (the extension). Against the earlier "
           "version, current / earlier is like for like only for the same robot (links, joints, hydraulics, "
           "cylinders) and, for a loop, the same rig, timing, scenario and controller variant (the last column "
           "says where it is not); described / earlier is like for like unless another controller variant runs "
           "(marked *).", ""]
    if "bound" in b:  # the release checks' bounds (a run without them keeps the figures only)
        names = {"ratio": "current / folded", "ratio_earlier": "current / earlier",
                 "ratio_described": "described / earlier"}
        above = [f"{r['robot']} {r['name']} ({', '.join(f'{names[k]} {r[k]:.2f}' for k in r['above_bound'])})"
                 for r in rows if r.get("above_bound")]
        out += [f"Bounds where like for like: current / earlier and described / earlier {b['bound']:.2f} (within "
                f"{100 * (b['bound'] - 1):.0f} % of commit `{b.get('baseline')}`)"
                + (f", current / folded {b['bound_folded']:.2f}" if "bound_folded" in b else "") + ". "
                + (f"Above them in this run: {'; '.join(above)}." if above else "This run keeps them."), ""]
    ratio = lambda r, key: f"{r[key]:.2f}" if key in r else "–"  # noqa: E731
    table = [[r["robot"], r["what"], f"`{r['name']}`" if r["what"] == "call" else r["name"], _f(r.get("earlier")),
              _f(r.get("folded")), _f(r.get("current")), _f(r.get("described")), ratio(r, "ratio"),
              ratio(r, "ratio_earlier"),
              ratio(r, "ratio_described") + (" *" if "ratio_described" in r
                                              and not r.get("described_like_for_like", True) else ""),
              r.get("unlike", "")]
             for r in rows]
    return out + _table(["robot", "", "scenario or function", "earlier", "folded", "current", "described",
                         "current / folded", "current / earlier", "described / earlier", "not like for like"], table)


def _shared_step(b) -> list:
    robots = b.get("robots", {})
    if not robots:
        return []
    out = ["## The semi-implicit step: the controller inlined or called", "",
           "`benchmarks/bench_shared_step.py`: each adaptive controller's step (full variant), as shipped (the "
           "controller and its rates inlined in one graph: what depends on the measurement only is computed once, "
           "the C repeats the controller's) and as two calls of the controller's and the rates' functions (the "
           f"controller compiled once). The two agree (relative {_f(b.get('agreement_rtol'))}). Per call: the "
           "step's C cost; per period: the extra cost against the scenario's C loop period; compile: every source "
           "of the variant's library, CPU seconds one after another and wall seconds on all cores.", ""]
    table = []
    for rob in robots.values():
        for kind, r in rob["controllers"].items():
            ns, c = r["ns_per_call"], r["compile"]
            table.append([rob["model"], kind, _f(ns["inlined"], 0), _f(ns["calls"], 0), f"{r['time_ratio']:.2f}",
                          f"{100 * r['period_increase']:+.0f} %", _f(c["inlined"]["serial_s"]),
                          _f(c["calls"]["serial_s"]), _f(c["inlined"]["wall_s"]), _f(c["calls"]["wall_s"])])
    return out + _table(["robot", "controller", "step ns, inlined", "calls", "calls / inlined", "per period",
                         "compile CPU s, inlined", "calls", "compile wall s, inlined", "calls"], table)


def _integrator(b) -> list:
    robots = b.get("robots", {})
    if not robots:
        return []
    tol = b.get("tolerance")
    out = ["## The rig's plant integration: sub-steps against a reference", "",
           "`benchmarks/bench_integrator.py`: every rig scenario and variant of each robot, every controller it "
           f"lists, noise seeds {', '.join(map(str, b.get('seeds', [])))}: the C loop at each count of RK4 plant "
           f"sub-steps per control period against a reference of {b.get('reference')} sub-steps. Each reported "
           "error (max tracking error, % of the amplitude, per moving coordinate) is a distribution over the seeds; "
           "a count's deviation is the largest difference of its median or worst from the reference's (percentage "
           "points). The adaptive runs are chaotic on the rig, so the reference itself moves: the floor is the "
           f"deviation of {b.get('check')} sub-steps. A count keeps the errors when its deviation is within "
           f"{_f(tol)} point, or within the floor where that is larger (the seeds resolve no less; * marks "
           "such a controller); `!` marks a count that does not, `fail` one with a failed run. Cheapest: the "
           "smallest count from which every tested count keeps every controller's errors. Cost: the loop's µs per "
           "control period (median over seeds and controllers) and `plant_rhs` instructions x calls per period "
           "(4 per RK4 step, of the plant and of the predictor). Valve ω h: the servo-valve's natural frequency "
           "times the sub-step, which the scenario check bounds by 1.", ""]
    out += _integrator_field(b, "scenarios", "substeps", "sub-steps")
    if any(r.get("predictor") for r in robots.values()):
        out += ["The delay predictor's own RK4 steps per period (`predictor_substeps`) on every scenario whose loop "
                f"predicts, the plant at the scenario's sub-steps, against {b.get('predictor_reference')} steps "
                f"(floor: {b.get('predictor_check')}):", ""]
        out += _integrator_field(b, "predictor", "predictor_substeps", "predictor steps")
    return out


def _local_error(b) -> list:
    robots = b.get("robots", [])
    if not robots:
        return []
    counts = b.get("counts", [])
    out = ["## The plant integration alone: each run replayed open loop", "",
           "`benchmarks/bench_local_error.py`: the runs of the rig scenarios above amplify any difference (the "
           "adaptive ones are chaotic; every loop reads quantised, noisy sensors and drives Stribeck friction), "
           "so their reported errors tell how sensitive each loop is as much as how accurate the integration. "
           f"Here the trajectory of each of {', '.join(b.get('controllers', []))} on each rig scenario and "
           "variant (the scenario's own sub-steps and noise seed) is replayed open loop under its recorded "
           f"commands at each count of RK4 sub-steps and at {b.get('reference')}: the largest difference over "
           "the run, of the coordinates in points of their reference amplitude (the reported errors' unit) and "
           "of the pressure states in Pa. The commands being equal, it is the integration's error as the "
           f"plant's own dynamics carry it. A count keeps the errors within {_f(b.get('points'))} point and "
           f"{_f(100 * b.get('noise_share', 0))} % of the pressure sensors' noise; cheapest: the smallest "
           "count from which every tested count keeps them (none: not even the largest). *Pressure bounds*: the "
           "scenario's `pressure_bounds`, how the plant holds each pressure within its bounds (a chamber that "
           "would cavitate stays at 0): `step` clips after each RK4 step, `stage` (the default) also at every "
           "stage, where a pressure at a bound does not rate past it.", ""]

    def at(d, n):  # a count's entry, keyed by the number or, read back from JSON, by its text
        return d.get(n, d.get(str(n)))

    table = []
    for rob in robots:
        for r in rob["rows"]:
            table.append([rob["model"], r["scenario"], r["controller"], r.get("pressure_bounds", "step"),
                          r["substeps"], r["cheapest"] or "none",
                          *("fail" if at(r["failed"], n) is not None else
                            f"{_f(at(r['q_pts'], n))} / {_f(at(r['p_pa'], n))}" for n in counts)])
    out += _table(["robot", "scenario", "controller", "pressure bounds", "now", "cheapest",
                   *(f"{n} sub-steps: points / Pa" for n in counts)], table)
    pred = b.get("predictor") or {}
    if not pred.get("robots"):
        return out
    pcounts = pred.get("counts", [])
    out += ["", "The delay predictor's own integration the same way: on each rig scenario and variant whose loop "
            "predicts, each period's prediction (the plant state when the command lands, by the controller's model "
            "from the measured state over the commands in flight) made again at each count of RK4 steps per period "
            f"(`predictor_substeps`) and at {b.get('reference')} from the same measured state and commands, along "
            "the run at the scenario's own counts: the largest difference over the run of the predicted pose "
            "(points of amplitude) and pressures (Pa), kept by the same rule.", ""]
    table = [[rob["model"], r["scenario"], r["controller"], r["predictor_substeps"], r["cheapest"] or "none",
              *("fail" if at(r["failed"], n) is not None else
                f"{_f(at(r['q_pts'], n))} / {_f(at(r['p_pa'], n))}" for n in pcounts)]
             for rob in pred["robots"] for r in rob["rows"]]
    return out + _table(["robot", "scenario", "controller", "now", "cheapest",
                         *(f"{n} steps: points / Pa" for n in pcounts)], table)


def _rig_period(b) -> list:
    rows = b.get("rows", [])
    if not rows:
        return []
    f = b.get("former", {})
    out = ["## The rig period: the shipped plant integration against the former one", "",
           "`benchmarks/bench_rig_period.py`: every rig scenario and variant, every controller the robot lists, noise "
           f"seeds {', '.join(map(str, b.get('seeds', [])))}; per seed three runs in a row in one process: at the "
           f"former integration ({f.get('substeps')} sub-steps, pressures clipped after each step"
           + (f", {f['predictor_substeps']} predictor steps per period" if f.get("predictor_substeps") else "")
           + f"), at the scenario's own (shipped) and at {b.get('reference')} sub-steps"
           + (" and predictor steps" if f.get("predictor_substeps") else "")
           + f" (the reference). Cost: the C loop's µs "
           "per control period, median over seeds and controllers. Deviation: the largest difference of a reported "
           "error's median or worst over the seeds (max tracking error, % of amplitude, each moving coordinate) "
           "from the reference's, over the controllers, in points, former → shipped. A controller is chaotic "
           f"when the former's runs already differ from the reference's by more than {_f(b.get('tolerance'))} "
           "point on some seed (the adaptive ones on the rig, mostly): the seeds cannot resolve the integration's "
           "share there. Keeps: each controller's shipped deviation within "
           f"{_f(b.get('tolerance'))} point, or a chaotic one's within the former's; else the controllers named.",
           ""]
    table = [[r["model"], r["scenario"], f"{r['substeps']}, {r['pressure_bounds']}"
              + (f", {r['predictor_substeps']} predictor" if r.get("predictor_substeps") else ""),
              f"{_f(r['us_former'], 1)} → {_f(r['us_shipped'], 1)}", f"{r['ratio']:.2f}×",
              f"{_f(r['dev_former'])} → {_f(r['dev_shipped'])}",
              f"{_f(r.get('dev_former_chaotic'))} → {_f(r.get('dev_shipped_chaotic'))}",
              "yes" if r["keeps"] else "no: " + ", ".join(r.get("not_kept", []))] for r in rows]
    out += _table(["robot", "scenario", "shipped: sub-steps, bounds", "µs per period, former → shipped",
                   "cheaper", "deviation, not chaotic", "deviation, chaotic", "keeps"], table)
    ratios = [r["ratio"] for r in rows]
    out += [f"The period is {min(ratios):.2f}-{max(ratios):.2f}× cheaper than the former integration's "
            f"({sum(1 for r in rows if r['keeps'])} of {len(rows)} scenarios keep every controller's errors).", ""]
    return out


def _integrator_field(b, key, field, what) -> list:
    dev = lambda x: ("fail" if x["dev"] is None else _f(x["dev"]) + ("" if x["keeps"] else " !"))  # noqa: E731
    summary, detail, values = [], [], set()
    for rob in b["robots"].values():
        for s in rob.get(key, {}).values():
            values.update(r[field] for r in s["per_value"])
    values = sorted(values)
    for rob in b["robots"].values():
        for s in rob.get(key, {}).values():
            at = {r[field]: r for r in s["per_value"]}
            now, best = at[s["current"]], at.get(s["cheapest"])
            pair = lambda k: f"{_f(now[k], 1)} → {_f(best[k], 1)}" if best else _f(now[k], 1)  # noqa: E731
            chaotic = [c for c, r in s["controllers"].items() if r["chaotic"]]
            # a controller whose reference run diverged: nothing to judge against, named with the chaotic
            chaotic += [f"{c} (its reference diverged)" for c in s.get("no_reference", {})]
            summary.append([rob["model"], s["scenario"], s["current"], s["cheapest"] or "none",
                            pair("us_per_period"), pair("rhs_instructions"),
                            _f(best["dev"]) if best else "–", _f(best["paired_not_chaotic"]) if best else "–",
                            _f(max((r["floor"] for r in s["controllers"].values()), default=None)),
                            ", ".join(chaotic) or "none"]
                           + ([_f(at[min(at)]["valve_omega_h"])] if field == "substeps" else []))
            for c, r in s["controllers"].items():
                counts = {x[field]: x for x in r["counts"]}
                detail.append([rob["model"], s["scenario"], c + (" *" if r["chaotic"] else ""),
                               ", ".join(f"{k} {_f(v['median'])} / {_f(v['worst'])}" for k, v in r["reference"].items()),
                               _f(r["floor"])] + [dev(counts[v]) if v in counts else "–" for v in values])
    omega = ["valve ω h at the fewest"] if field == "substeps" else []
    out = _table(["robot", "scenario", "now", "cheapest", "µs per period, now → cheapest",
                  "instructions per period, now → cheapest", "deviation at cheapest",
                  "paired, controllers not chaotic", "largest floor", "chaotic"] + omega, summary)
    return out + _table(["robot", "scenario", "controller", "reference median / worst %", "floor"]
                        + [f"{what} {v}" for v in values], detail)


def _spread_cell(p, coord) -> str:
    """One point over seeds: ``median [min - max]`` of ``coord``, ``fail`` when no seed completed, `` !`` when one failed."""
    text = f"{_f(p['median'][coord])} [{_f(p['min'][coord])} - {_f(p['max'][coord])}]" \
        if p["median"][coord] is not None else "fail"
    return text + (" !" if p["failed"] else "")


def _delay(b) -> list:
    rows = b.get("scenarios", {})
    if not rows:
        return []
    fr = b.get("fractions", [])
    out = ["## The computation delay: tracking error from 0 to 1 control period", "",
           f"`benchmarks/bench_delay.py`: {b.get('model')}'s rig scenarios, every controller it lists, the command "
           "applied a fraction of a control period after its measurement (the scenario's `delay`: 1 is the rig's "
           f"full period, the `{b.get('variant')}` variant's 5 µs about 0), over noise seeds "
           f"{', '.join(map(str, b.get('seeds', [])))} (not the seeds the gains were tuned on). Each controller runs "
           f"with the description's gains at the rig and, where the `{b.get('variant')}` variant gives it its own, "
           "with those too (main gain shown). Max tracking error, % of the amplitude of the coordinate the "
           "reference moves: median [min - max] over the seeds; `!` marks a delay where a seed's run failed "
           "(diverged; the statistics are over the others). The paper states no computation delay "
           "([The timing](paper.md#the-timing)).", ""]
    if b.get("figure"):
        out += [f"![max error against computation delay]({Path(b['figure']).name})", ""]
    table = []
    for row in rows.values():
        coord = row["coordinates"][0]
        for c, sets in row["controllers"].items():
            for label, e in sets.items():
                g = e["gains"]
                table.append([row["scenario"], coord, c, f"{label}: {g['main_gain']} {g['value']:.4g}"]
                             + [_spread_cell(p, coord) for p in e["delays"]])
    return out + _table(["scenario", "coordinate", "controller", "gains"] + [f"delay {f:g} period" for f in fr],
                        table)


def _sensitivity(b) -> list:
    rows = b.get("scenarios", {})
    if not rows:
        return []
    out = ["## Sensitivity: tracking error against the rig's friction and valve bandwidth", "",
           f"`benchmarks/bench_sensitivity.py`: {b.get('model')}'s rig scenarios, every controller it lists with the "
           "description's gains at the rig, one rig element varied at a time: the friction (Coulomb and viscous "
           "of every cylinder) as a multiple of the rig's, and the servo-valve's natural frequency (Hz). No "
           "controller models either. Noise seeds "
           f"{', '.join(map(str, b.get('seeds', [])))} (not the seeds the gains were tuned on). Max tracking error, % "
           "of the amplitude of the coordinate the reference moves: median [min - max] over the seeds; `!` marks a "
           "point where a seed's run failed (diverged; the statistics are over the others).", ""]
    if b.get("figure"):
        out += [f"![max error against friction and valve bandwidth]({Path(b['figure']).name})", ""]
    heads = {"friction": "friction x {:g}", "valve": "valve {:g} Hz"}
    for element, head in heads.items():
        table = []
        for row in rows.values():
            coord = row["coordinates"][0]
            for c, e in row["controllers"].items():
                table.append([row["scenario"], coord, c] + [_spread_cell(p, coord) for p in e.get(element, [])])
        out += _table(["scenario", "coordinate", "controller"]
                      + [head.format(v) for v in b.get("values", {}).get(element, [])], table)
    return out


def _supply_limits(b) -> list:
    rows = b.get("scenarios", {})
    if not rows:
        return []
    out = ["## Supply limits: tracking error when the pump's flow runs out", "",
           "`benchmarks/supply_limits.py`: each robot on its shipped pump (its description's `[supply]`) in its rig "
           "scenario whose motion asks for more oil than the pump gives; every controller it lists on a constant "
           "supply (`constant`: the description without its `[supply]`, unlimited flow), on the pump reading the "
           "measured supply pressure (`measured`), and on the pump assuming the description's constant supply pressure "
           "(`assumed`: `supply_feedback = false`). Noise seeds "
           f"{', '.join(map(str, b.get('seeds', [])))}. Max tracking error, % of the amplitude of each coordinate "
           "the reference moves: median [min - max] over the seeds (`!`: a seed's run failed); the lowest supply "
           f"pressure (MPa, median [min - max]) and the median fraction of the run below {b.get('low', 0.9):g} of "
           "its nominal value.", ""]
    for name, row in rows.items():
        out += [f"**{name}**, {row['scenario']} ({row['label']}): `{row['supply']}` of {_f(row['pump_l_min'])} L/min "
                f"at {_f(row['nominal_mpa'])} MPa ({row['sources']}); the reference asks up to "
                f"{_f(row['demand_peak_l_min'])} L/min, more than the pump {_f(100 * row['demand_over_frac'])} % of "
                "the time.", ""]
        coords = row["coordinates"]
        table = []
        for c, points in row["controllers"].items():
            for p in points:
                s, f = p["ps_min_mpa"], p["ps_low_frac"]
                low = "–" if s["median"] is None else (f"{_f(s['median'])} [{_f(s['min'])} - {_f(s['max'])}], "
                                                       f"{_f(100 * f['median'])} %")
                table.append([c, p["supply"]] + [_spread_cell(p, k) for k in coords] + [low])
        out += _table(["controller", "supply"] + [f"{k} max error %" for k in coords]
                      + ["lowest p_s MPa, time below"], table)
    return out


def benchmarks_page(results: dict, repeats: dict | None = None, source: str = "docs/bench.json") -> str:
    """Markdown of a ``hydrogen bench`` run (the dict it writes as JSON), optionally with the whole-run
    spread of the release comparison (``bench_release_repeats.json``); sections of modules not run
    are left out."""
    calls = results.get("bench_calls", {})
    machine = calls.get("machine") or {}
    out = [_DO_NOT_EDIT.format(cmd=f"hydrogen bench --json {source}"), "", "# Benchmarks", "",
           f"Written by `hydrogen bench --json {source}` from that file. Times are medians unless a table says "
           "otherwise; on a shared virtual machine speed drifts between runs, so compare ratios within one run."]
    if machine:
        out += ["", f"Machine: {machine.get('processor')}, {machine.get('cpu_count')} cores; "
                f"{machine.get('cc')}; Python {machine.get('python')}, numpy {machine.get('numpy')}, "
                f"SymPy {machine.get('sympy')}, CasADi {machine.get('casadi')}."]
    out.append("")
    for key, render in (("bench_loop", _loop), ("bench_sweep", _sweep), ("bench_functions", _functions),
                        ("bench_build", _build), ("bench_flags", _flags), ("bench_calls", _calls)):
        if key in results:
            out += render(results[key])
    if "bench_release" in results:
        out += _release(results["bench_release"], repeats)
    if "bench_scaling" in results:
        out += _scaling(results["bench_scaling"])
    if "bench_folding" in results:
        out += _folding(results["bench_folding"])
    if "bench_edit" in results:
        out += _edit(results["bench_edit"])
    if "bench_cold" in results:
        out += _cold(results["bench_cold"])
    if "bench_structural" in results:
        out += _structural(results["bench_structural"])
    if "bench_code_edit" in results:
        out += _code_edit(results["bench_code_edit"])
    if "bench_recursive" in results:
        out += _recursive(results["bench_recursive"])
    if "bench_period" in results:
        out += _period(results["bench_period"])
    if "bench_shared_step" in results:
        out += _shared_step(results["bench_shared_step"])
    if "bench_integrator" in results:
        out += _integrator(results["bench_integrator"])
    if "bench_local_error" in results:
        out += _local_error(results["bench_local_error"])
    if "bench_rig_period" in results:
        out += _rig_period(results["bench_rig_period"])
    if "bench_delay" in results:
        out += _delay(results["bench_delay"])
    if "bench_sensitivity" in results:
        out += _sensitivity(results["bench_sensitivity"])
    if "supply_limits" in results:
        out += _supply_limits(results["supply_limits"])
    return "\n".join(out).rstrip() + "\n"


def check_benchmarks_page(json_path) -> Path:
    """The page ``hydrogen bench --json json_path`` writes (``benchmarks.md`` beside it), or an
    OutputPathError when writing it would destroy something: the JSON itself (``--json
    d/benchmarks.md``), or a file there that is not a page bench wrote (its first line is the mark
    this module writes). Checked before any benchmark runs."""
    from .errors import OutputPathError

    json_path = Path(json_path)
    page = json_path.with_name(BENCHMARKS_PAGE)
    if json_path.name == BENCHMARKS_PAGE or (page.exists() and json_path.exists()
                                             and page.resolve() == json_path.resolve()):
        raise OutputPathError(f"--json {json_path}: the results would be overwritten by the page rendered "
                              f"from them ({page}); give the JSON another name, e.g. {page.with_name('bench.json')}")
    if page.is_symlink() or (page.exists() and not page.is_file()):
        raise OutputPathError(f"{page}: not a regular file; 'bench --json {json_path}' writes its page "
                              "there: move it, or write the JSON into another folder")
    if page.exists():
        try:
            with page.open(encoding="utf-8", errors="replace") as fh:
                first = fh.readline()
        except OSError as exc:
            raise OutputPathError(f"{page}: cannot be read ({exc.strerror}); 'bench --json' writes its page "
                                  "there") from None
        if not first.startswith(_BENCH_MARK):
            raise OutputPathError(f"{page}: not a page 'hydrogen bench' wrote (its first line is not "
                                  f"'{_BENCH_MARK}...'), and 'bench --json {json_path}' writes its page "
                                  "there: move that file, or write the JSON into another folder")
    return page


def write_benchmarks_page(json_path) -> Path:
    """Render the run in ``json_path`` (and ``bench_release_repeats.json`` beside it) to
    ``benchmarks.md`` beside it, atomically; returns its path. Refused (:func:`check_benchmarks_page`)
    where that page would overwrite the JSON or a file bench did not write."""
    json_path = Path(json_path)
    check_benchmarks_page(json_path)
    results = json.loads(json_path.read_text(encoding="utf-8"))
    rep = json_path.with_name(REPEATS_JSON)
    repeats = json.loads(rep.read_text(encoding="utf-8")) if rep.is_file() else None
    page = json_path.with_name(BENCHMARKS_PAGE)
    atomic_write(page, benchmarks_page(results, repeats, source=_shown(json_path)))
    return page


def _shown(path: Path) -> str:
    """The path as a user would type it: relative to the working folder when inside it."""
    try:
        return Path(path).resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return Path(path).as_posix()
