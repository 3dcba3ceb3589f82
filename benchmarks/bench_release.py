"""Side by side with the previous release, in one run: results, generated code size and speed.

The previous release is git commit ``d9002f1`` of this repository (the last commit before the
generalisation to any hydraulic manipulator). It is extracted with ``git archive`` into a
temporary folder; every measurement then runs in fresh Python processes, one per version, with
``PYTHONPATH`` pointing at that version's checkout and a separate ``HYDROGEN_CACHE_DIR`` each
(so each version generates and compiles its own library). Skipped, with a message, outside a git
checkout or when the commit is not in the repository.

For the default robot (the Stewart platform, the only one the previous release knows):

(i)   every scenario x controller: the trajectories of both versions, compared: the largest
      |Δq| (m, rad) and the largest relative Δθ̂ over the run; bound 1e-9 each. A run whose
      scenario itself changed (a field of the scenario, or the reference q_d) is reported as
      such, with the fields that differ; a run that diverged in either version says so.
(ii)  CasADi instruction counts of every generated function (from the manifest each version
      writes when it generates from scratch): the rigid body and the kinematics no larger than
      the previous release's, the controllers and the plant within 5 % of them. An adaptive
      controller is compared like for like: the previous release's law is the gradient law,
      which the current version runs as its lean variant (``ctrl_<c>_lean``, the composite
      adaptation's rates 0, the default); the full function (with the composite law, new since)
      is shown against the same previous count, its change reported, not bounded.
(iii) the simulation scenario's (paper-sim's) cost per control period of the C loop,
      ``loop_wall_s`` of ``hydrogen.simulate`` (logs included, the same in both versions) over
      the periods; the median over runs interleaved between the versions; bound: within 10 %.
      Measured as shipped (paper-sim runs the composite law for θ and γ) and, in the current
      version, with the composite rates 0 (the previous release's law: like for like).
(iv)  generation from scratch: ``render(model, tmpdir)`` in a fresh process (imports included),
      process wall time, interleaved between the versions; bound: within 2x.

For every other shipped robot (no previous release): (ii), (iii) on its simulation scenario and
(iv) of the current version, reported.

A bound that does not hold is reported as FAIL in the table and in ``checks`` of the results;
the benchmark itself does not raise (``--strict`` makes the script exit 1). The bounds are the
project's release targets: this script (the developer's release comparison) and
``hydrogen bench --release-checks`` print them; ``hydrogen bench`` prints the figures alone.

Run: ``python benchmarks/bench_release.py [--quick] [--json FILE] [--strict]``
"""
from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

try:  # imported as benchmarks.bench_release
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

PREVIOUS = "d9002f1"
CONTROLLER = "adaptive-robust"
#: Bounds the release must keep ("what must not get worse" against the previous release).
TRAJECTORY_TOL = 1e-9
NO_LARGER = ("regressor", "mass_matrix", "coriolis", "gravity", "leg_kinematics")
WITHIN_5_PCT_PREFIX = ("ctrl_", "plant_rhs")
#: The composite adaptation's rates (1/s); 0 runs the gradient law of the previous release.
GRADIENT_LAW = {"rate_ls_gamma": 0.0, "rate_ls_theta": 0.0}
LEAN_SUFFIX = "_lean"
INSTRUCTION_REL_TOL = 0.05
LOOP_REL_TOL = 0.10
GENERATION_RATIO = 2.0
#: The counts quoted for the release before it when its bounds were set (shown next to the measured ones).
QUOTED_COUNTS = {"regressor": 182, "mass_matrix": 70, "coriolis": 143, "gravity": 10, "leg_kinematics": 398,
                "ctrl_backstepping": 3021, "ctrl_adaptive_robust": 3846, "ctrl_adaptive_observer": 3878,
                "plant_rhs": 1084}

# ---------------------------------------------------------------------------------------------
# scripts run in each version (only API both versions have)
# ---------------------------------------------------------------------------------------------
_PREAMBLE = """
import dataclasses, json, sys, time
import numpy as np
import hydrogen
print("hydrogen_file", 0, hydrogen.__file__)
"""

_GENERATE = _PREAMBLE + """
import tempfile
t0 = time.perf_counter()
from hydrogen.codegen.generate import render
model = hydrogen.load_model({model!r})
with tempfile.TemporaryDirectory() as tmp:
    t1 = time.perf_counter()
    render(model, tmp)
    t2 = time.perf_counter()
    manifest = json.load(open(tmp + "/manifest.json"))
print("render_s", t2 - t1)
print("inside_s", t2 - t0)
print("JSON", json.dumps({{f["name"]: f["instructions"] for f in manifest["functions"]}}))
"""

_TIMING = _PREAMBLE + """
model = hydrogen.load_model({model!r})
dyn = hydrogen.build(model)
gains = {gains!r}
hydrogen.simulate({scenario!r}, {controller!r}, dyn=dyn, duration=0.5, gains=gains)  # warm-up
for _ in range({repeats}):
    r = hydrogen.simulate({scenario!r}, {controller!r}, dyn=dyn, gains=gains)
    print("per_period_us", r.loop_wall_s / len(r.t) * 1e6)
"""

_RUNS = _PREAMBLE + """
from hydrogen.simulation import scenarios as SC
import os
# asked of the checkout's own files: an editable install's import finder would answer a module
# the previous release lacks from the current source
if os.path.isdir(os.path.join(os.path.dirname(hydrogen.__file__), "controllers")):
    from hydrogen.controllers import CONTROLLERS
else:  # the previous release
    from hydrogen.simulation.control import CONTROLLERS
model = hydrogen.load_model()
names = SC.scenario_names(model) if hasattr(SC, "scenario_names") else SC.SCENARIOS
dyn = hydrogen.build(model)
arrays, info = {{}}, {{}}
plain = lambda o: np.asarray(o).tolist()
for s in names:
    sc = SC.scenario(s, model)
    fields = {{f.name: getattr(sc, f.name) for f in dataclasses.fields(sc)
              if f.name not in ("name", "reference", "label", "paper")}}
    fields = json.loads(json.dumps(fields, default=plain))
    for c in getattr(model, "controllers", CONTROLLERS):  # those the robot lists (a release before: all)
        key = s + "__" + c
        err = None
        try:
            r = hydrogen.simulate(s, c, dyn=dyn)
        except hydrogen.SimulationError as exc:
            r, err = exc.result, str(exc)[:300]
        for k in ("t", "q", "q_d", "theta_hat", "gamma1_hat", "gamma2_hat"):
            arrays[key + "__" + k] = np.asarray(getattr(r, k), float)
        info[key] = {{"scenario": s, "controller": c, "error": err, "fields": fields}}
np.savez({out!r}, **arrays)
json.dump(info, open({out!r} + ".json", "w"))
print("runs", len(info))
"""


def _lines(stdout: str, key: str) -> list:
    return [line.split(None, 1)[1] for line in stdout.splitlines() if line.startswith(key + " ")]


class Version:
    """One version of hydrogen: its source folder and its own cache."""

    def __init__(self, label: str, source: Path, cache: Path):
        self.label, self.source, self.cache = label, Path(source), Path(cache)

    def env(self) -> dict:
        env = dict(os.environ)
        env.update(PYTHONUNBUFFERED="1", PYTHONPATH=str(self.source), HYDROGEN_CACHE_DIR=str(self.cache))
        return env

    def run(self, code: str, timeout: float = 1800.0) -> tuple[str, float]:
        stdout, wall = common.run_python(code, timeout=timeout, env=self.env(), cwd=self.source)
        where = Path(_lines(stdout, "hydrogen_file")[0].split(None, 1)[1]).resolve()
        if self.source.resolve() not in where.parents:
            raise RuntimeError(f"{self.label}: the subprocess imported hydrogen from {where}, not from {self.source}")
        return stdout, wall


def _extract_previous(dest: Path, commit: str = PREVIOUS) -> str | None:
    """Extract ``commit`` (default: PREVIOUS) into ``dest``; None, or the reason it cannot be done."""
    try:
        top = subprocess.run(["git", "-C", str(common.REPO), "rev-parse", "--show-toplevel"],
                             capture_output=True, text=True, timeout=60)
    except OSError as exc:
        return f"git is not available ({exc})"
    if top.returncode != 0:
        return f"{common.REPO} is not a git checkout ({top.stderr.strip()})"
    ok = subprocess.run(["git", "-C", str(common.REPO), "cat-file", "-e", f"{commit}^{{commit}}"],
                        capture_output=True, text=True, timeout=60)
    if ok.returncode != 0:
        return f"commit {commit} is not in this repository (a shallow clone?)"
    tar = subprocess.run(["git", "-C", str(common.REPO), "archive", "--format=tar", commit],
                         capture_output=True, timeout=300)
    if tar.returncode != 0:
        return f"git archive {commit} failed: {tar.stderr.decode(errors='replace').strip()}"
    with tarfile.open(fileobj=io.BytesIO(tar.stdout)) as tf:
        tf.extractall(dest)
    return None


# ---------------------------------------------------------------------------------------------
# (i) trajectories
# ---------------------------------------------------------------------------------------------
def _load_runs(path: Path) -> tuple[dict, dict]:
    arrays = dict(np.load(str(path)))
    info = json.loads(Path(str(path) + ".json").read_text())
    return arrays, info


def _rel(a, b):
    """Largest |a - b| / |b| (entries where b = 0: |a - b|)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.size == 0:
        return 0.0
    scale = np.where(b != 0, np.abs(b), 1.0)
    return float(np.max(np.abs(a - b) / scale))


def _same_value(a, b) -> bool:
    """Equal values, numbers compared as arrays (a scalar equals a vector of it, as gains broadcast)."""
    if isinstance(a, dict) or isinstance(b, dict):
        if not isinstance(a, dict) or not isinstance(b, dict) or set(a) != set(b):
            return False
        return all(_same_value(a[k], b[k]) for k in a)
    try:
        x, y = np.asarray(a, float), np.asarray(b, float)
        x, y = np.broadcast_arrays(x, y)
        return bool(np.array_equal(x, y))
    except (TypeError, ValueError):
        return a == b


def _zero_like(v) -> bool:
    try:
        return not np.any(np.asarray(v, float))
    except (TypeError, ValueError):
        return not v


def _changed_fields(prev: dict, cur: dict, controller: str) -> list:
    """Scenario fields that differ (a field only one version has counts when it is not zero or
    empty there; of the gains, only the run's controller's)."""
    out = []
    for k in [*prev, *(k for k in cur if k not in prev)]:
        if k == "gains":
            if not _same_value(prev[k].get(controller, {}), cur.get(k, {}).get(controller, {})):
                out.append(f"gains.{controller}")
        elif k not in prev or k not in cur:
            if not _zero_like(prev.get(k, cur.get(k))):
                out.append(k)
        elif not _same_value(prev[k], cur[k]):
            out.append(k)
    return out


def compare_runs(prev_path: Path, cur_path: Path) -> dict:
    pa, pi = _load_runs(prev_path)
    ca, ci = _load_runs(cur_path)
    out = {}
    for key in sorted(set(pi) | set(ci), key=lambda k: (list(pi) + list(ci)).index(k)):
        if key not in pi or key not in ci:
            out[key] = {"status": "only in the " + ("current version" if key in ci else "previous release")}
            continue
        p, c = pi[key], ci[key]
        row = {"scenario": p["scenario"], "controller": p["controller"], "error_previous": p["error"],
               "error_current": c["error"]}
        changed = _changed_fields(p["fields"], c["fields"], p["controller"])
        P = {k: pa[f"{key}__{k}"] for k in ("t", "q", "q_d", "theta_hat", "gamma1_hat", "gamma2_hat")}
        C = {k: ca[f"{key}__{k}"] for k in ("t", "q", "q_d", "theta_hat", "gamma1_hat", "gamma2_hat")}
        k = min(len(P["t"]), len(C["t"]))
        row["periods_previous"], row["periods_current"] = len(P["t"]), len(C["t"])
        if k and float(np.max(np.abs(P["q_d"][:k] - C["q_d"][:k]))) > 0.0:
            changed.append("reference q_d")
        row["scenario_changed"] = changed
        if k:
            row["max_abs_dq"] = float(np.max(np.abs(P["q"][:k] - C["q"][:k])))
            row["max_rel_dtheta"] = _rel(C["theta_hat"][:k], P["theta_hat"][:k])
            g_prev = [np.asarray(P[g][:k]).reshape(k, -1) for g in ("gamma1_hat", "gamma2_hat")]
            g_cur = [np.asarray(C[g][:k]).reshape(k, -1) for g in ("gamma1_hat", "gamma2_hat")]
            row["max_rel_dgamma"] = max(_rel(c_, np.broadcast_to(p_, c_.shape)) for p_, c_ in zip(g_prev, g_cur))
        else:
            row["max_abs_dq"] = row["max_rel_dtheta"] = row["max_rel_dgamma"] = None
        same_length = row["periods_previous"] == row["periods_current"]
        if changed:
            row["status"] = "scenario changed"
        elif not same_length or (p["error"] is None) != (c["error"] is None):
            row["status"] = "FAIL (different run length or divergence)"
        elif row["max_abs_dq"] is not None and row["max_abs_dq"] <= TRAJECTORY_TOL \
                and row["max_rel_dtheta"] <= TRAJECTORY_TOL:
            row["status"] = "ok"
        else:
            row["status"] = "FAIL"
        out[key] = row
    return out


# ---------------------------------------------------------------------------------------------
# (ii) instruction counts
# ---------------------------------------------------------------------------------------------
def _counterpart(name: str, cur: dict) -> str | None:
    """The previous release's function a current one is compared with: its own name; for an
    adaptive controller's lean variant (the previous law), the controller's name."""
    base = name[:-len(LEAN_SUFFIX)] if name.endswith(LEAN_SUFFIX) else None
    return base if base is not None and base + LEAN_SUFFIX in cur else name


def compare_instructions(prev: dict, cur: dict) -> dict:
    """Every current function against its counterpart (:func:`_counterpart`); a controller that
    also has a lean variant is the composite law's (reported, not bounded)."""
    out = {}
    for name in list(cur) + [n for n in prev if n not in cur]:
        p, c = prev.get(_counterpart(name, cur)), cur.get(name)
        row = {"previous": p, "current": c, "quoted": QUOTED_COUNTS.get(_counterpart(name, cur))}
        if p is None or c is None:
            row["bound"], row["status"] = None, "new" if p is None else "gone"
        elif name + LEAN_SUFFIX in cur:
            row["bound"], row["status"] = None, "composite law (new)"
        elif name in NO_LARGER:
            row["bound"], row["status"] = "no larger", "ok" if c <= p else "FAIL"
        elif name.startswith(WITHIN_5_PCT_PREFIX):
            ok = abs(c - p) <= INSTRUCTION_REL_TOL * p
            row["bound"], row["status"] = "within 5 %", "ok" if ok else "FAIL"
        else:
            row["bound"], row["status"] = None, "-"
        row["change_pct"] = None if p is None or c is None else 100.0 * (c - p) / p
        out[name] = row
    return out


# ---------------------------------------------------------------------------------------------
# run
# ---------------------------------------------------------------------------------------------
def _generation(version: Version, model, runs: list) -> dict:
    stdout, wall = version.run(_GENERATE.format(model=model))
    keyed = common.parse_keyed(stdout)
    runs.append({"process_wall_s": wall, "render_s": keyed["render_s"], "inside_s": keyed["inside_s"]})
    return json.loads(_lines(stdout, "JSON")[0])


def _timing(version: Version, model, scenario: str, repeats: int, values: list, gains=None):
    stdout, _ = version.run(_TIMING.format(model=model, scenario=scenario, controller=CONTROLLER, repeats=repeats,
                                           gains=gains))
    values.extend(float(v) for v in _lines(stdout, "per_period_us"))


def run(quick: bool = False) -> dict:
    import hydrogen

    t_start = time.perf_counter()
    rounds, repeats = (2, 3) if quick else (3, 5)
    default = hydrogen.load_model()
    sim = common.sim_scenario(default)
    with tempfile.TemporaryDirectory(prefix="bench_release_") as tmp:
        tmp = Path(tmp)
        (tmp / "previous").mkdir()
        reason = _extract_previous(tmp / "previous")
        if reason:
            return {"skipped": f"no side-by-side comparison: {reason}", "previous": PREVIOUS}
        versions = {"previous": Version(f"previous release {PREVIOUS}", tmp / "previous", tmp / "cache-previous"),
                    "current": Version("current", common.REPO, tmp / "cache-current")}
        for v in versions.values():
            v.run(_PREAMBLE)  # each imports its own hydrogen, before anything long runs
        # (i) every scenario x controller, in each version (builds each version's library first)
        for label, v in versions.items():
            v.run(_RUNS.format(out=str(tmp / f"runs-{label}.npz")))
        runs = compare_runs(tmp / "runs-previous.npz", tmp / "runs-current.npz")
        # (ii), (iv) generation from scratch, (iii) the loop: interleaved between the versions
        gen = {label: [] for label in versions}
        loop = {label: [] for label in [*versions, "current_gradient_law"]}
        counts = {}
        for _ in range(rounds if not quick else 1):
            for label, v in versions.items():
                counts[label] = _generation(v, None, gen[label])
        for _ in range(rounds):
            for label, v in versions.items():
                _timing(v, None, sim, repeats, loop[label])
            _timing(versions["current"], None, sim, repeats, loop["current_gradient_law"], GRADIENT_LAW)
        instructions = compare_instructions(counts["previous"], counts["current"])
        med = lambda rows, k: common.median(r[k] for r in rows)  # noqa: E731
        generation = {label: {"process_wall_s": med(gen[label], "process_wall_s"),
                              "render_s": med(gen[label], "render_s"), "runs": gen[label]} for label in versions}
        generation["ratio"] = generation["current"]["process_wall_s"] / generation["previous"]["process_wall_s"]
        per_period = {label: {"us": common.median(runs_), "runs": runs_} for label, runs_ in loop.items()}
        per_period["change"] = per_period["current"]["us"] / per_period["previous"]["us"] - 1.0
        per_period["change_gradient_law"] = per_period["current_gradient_law"]["us"] / per_period["previous"]["us"] - 1.0
        # the other robots: current version only
        others = {}
        for name in common.robots():
            if name == default.name:
                continue
            model = hydrogen.load_model(name)
            rows, values = [], []
            others[name] = {"instructions": _generation(versions["current"], name, rows)}
            others[name]["generation_process_wall_s"] = rows[0]["process_wall_s"]
            others[name]["generation_render_s"] = rows[0]["render_s"]
            scen = common.sim_scenario(model)
            _timing(versions["current"], name, scen, repeats, values)
            others[name]["scenario"] = scen
            others[name]["per_period_us"] = common.median(values)
    bad_runs = [k for k, r in runs.items() if r["status"].startswith("FAIL")]
    checks = {
        "trajectories_within_1e-9": not bad_runs,
        "scenarios_changed": [k for k, r in runs.items() if r["status"] == "scenario changed"],
        "instructions": all(r["status"] != "FAIL" for r in instructions.values()),
        "loop_within_10pct": per_period["change"] <= LOOP_REL_TOL,
        "loop_within_10pct_gradient_law": per_period["change_gradient_law"] <= LOOP_REL_TOL,
        "generation_within_2x": generation["ratio"] <= GENERATION_RATIO,
    }
    checks["all_bounds_hold"] = all(v for k, v in checks.items() if k != "scenarios_changed")
    return {"previous": PREVIOUS, "model": default.name, "scenario": sim, "controller": CONTROLLER,
            "runs": runs, "instructions": instructions, "loop_per_period": per_period,
            "generation": generation, "other_robots": others, "checks": checks, "quick": quick,
            "wall_s": time.perf_counter() - t_start}


def _fmt(x, spec=".1e"):
    return "-" if x is None else format(x, spec)


def _status(status: str, checks: bool) -> str:
    """A row's status; without the release checks only the facts (no ok/FAIL against the bounds)."""
    if checks:
        return status
    return {"ok": "", "FAIL": ""}.get(status, status.replace("FAIL (", "(").strip("()"))


def print_table(res: dict, checks: bool = True) -> None:
    """The figures; with ``checks`` (the developer's release comparison) also each bound and whether
    it holds. ``hydrogen bench`` prints the figures alone: the bounds are the project's release
    targets, not a user's."""
    if "skipped" in res:
        print(res["skipped"])
        return
    prev = res["previous"]
    ok = lambda key: (": ok" if res["checks"][key] else ": FAIL") if checks else ""  # noqa: E731
    print(f"{res['model']}: current version against the previous release ({prev}), one run")
    print("(i) trajectories, every scenario x controller"
          + (f" (bound: max |dq| and max relative d theta_hat <= {TRAJECTORY_TOL:g}):" if checks else ":"))
    header = f"{'scenario':<10} {'controller':<18} {'max |dq|':>9} {'max rel dth':>11} {'max rel dgam':>12}  " \
             + ("status" if checks else "note")
    print(header)
    print("-" * len(header))
    for r in res["runs"].values():
        if "scenario" not in r:
            print(f"  {r['status']}")
            continue
        status = _status(r["status"], checks)
        if r["scenario_changed"]:
            status += f" ({', '.join(r['scenario_changed'])})"
        for which in ("previous", "current"):
            if r[f"error_{which}"]:
                status += f"; diverged in the {which} version"
        print(f"{r['scenario']:<10} {r['controller']:<18} {_fmt(r['max_abs_dq']):>9} {_fmt(r['max_rel_dtheta']):>11} "
              f"{_fmt(r['max_rel_dgamma']):>12}  {status}")
    print("(ii) CasADi instructions of each generated function"
          + (" (bounds: rigid body and kinematics no larger; controllers and plant within 5 %):" if checks else ":"))
    header = f"{'function':<24} {'quoted':>7} {'previous':>9} {'current':>9} {'change %':>9}" \
             + (f" {'bound':>11}  status" if checks else "  note")
    print(header)
    print("-" * len(header))
    for name, r in res["instructions"].items():
        ch = "-" if r["change_pct"] is None else f"{r['change_pct']:+.1f}"
        print(f"{name:<24} {r['quoted'] if r['quoted'] is not None else '-':>7} "
              f"{r['previous'] if r['previous'] is not None else '-':>9} "
              f"{r['current'] if r['current'] is not None else '-':>9} {ch:>9}"
              + (f" {r['bound'] or '-':>11}  {r['status']}" if checks else f"  {_status(r['status'], checks)}"))
    lp, g = res["loop_per_period"], res["generation"]
    print(f"(iii) {res['scenario']} with {res['controller']}, C loop per period (hydrogen.simulate's loop_wall_s "
          f"over the periods, median of {len(lp['current']['runs'])} runs each, interleaved): previous "
          f"{lp['previous']['us']:.2f} us, current {lp['current']['us']:.2f} us ({100 * lp['change']:+.1f} %"
          f"{', bound +10 %' if checks else ''}){ok('loop_within_10pct')}; current with the composite "
          f"rates 0 (the previous release's law) {lp['current_gradient_law']['us']:.2f} us "
          f"({100 * lp['change_gradient_law']:+.1f} %){ok('loop_within_10pct_gradient_law')}")
    print(f"(iv) generation from scratch (fresh process, median of {len(g['current']['runs'])}): previous "
          f"{g['previous']['process_wall_s']:.2f} s (render {g['previous']['render_s']:.2f} s), current "
          f"{g['current']['process_wall_s']:.2f} s (render {g['current']['render_s']:.2f} s), "
          f"{g['ratio']:.2f}x{' (bound 2x)' if checks else ''}{ok('generation_within_2x')}")
    for name, o in res["other_robots"].items():
        counts = ", ".join(f"{k} {v}" for k, v in o["instructions"].items())
        print(f"{name} (no previous release): generation from scratch {o['generation_process_wall_s']:.2f} s "
              f"(render {o['generation_render_s']:.2f} s); {o['scenario']} C loop {o['per_period_us']:.2f} us per "
              f"period; instructions: {counts}")
    c = res["checks"]
    changed = f"scenario changed in {len(c['scenarios_changed'])} run(s); " if c["scenarios_changed"] else ""
    print((f"all bounds hold: {c['all_bounds_hold']}; " if checks else "") + f"{changed}benchmark {res['wall_s']:.0f} s")


def spread_row(res: dict) -> dict:
    """What varies between whole runs: (iii) the loop per period of both versions and their ratios,
    and (iv) the generation ratio (``--repeat``)."""
    lp = res["loop_per_period"]
    return {"previous_us": lp["previous"]["us"], "current_us": lp["current"]["us"],
            "current_gradient_law_us": lp["current_gradient_law"]["us"], "change": lp["change"],
            "change_gradient_law": lp["change_gradient_law"], "generation_ratio": res["generation"]["ratio"]}


def main(argv=None) -> int:
    from hydrogen.fileio import atomic_write

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer timing runs")
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    ap.add_argument("--strict", action="store_true", help="exit 1 when a bound does not hold")
    ap.add_argument("--repeat", type=int, default=1, metavar="N",
                    help="run the whole comparison N times; the JSON then holds each run's (iii) and (iv) and "
                         "their medians: the spread between runs on this machine")
    a = ap.parse_args(argv)
    if a.repeat > 1:
        rows = []
        for _ in range(a.repeat):
            res = run(quick=a.quick)
            if "skipped" in res:
                print(res["skipped"])
                return 0
            rows.append(spread_row(res))
            print(json.dumps(rows[-1]), flush=True)
        out = {"runs": rows, **{f"median_{k}": common.median(r[k] for r in rows)
                                for k in ("change", "change_gradient_law", "generation_ratio")}}
        if a.json:
            atomic_write(a.json, json.dumps(out, indent=2) + "\n")
        return 0
    res = run(quick=a.quick)
    print_table(res)
    if a.json:
        atomic_write(a.json, json.dumps(res, indent=2) + "\n")
    return 1 if a.strict and not res.get("checks", {}).get("all_bounds_hold", True) else 0


if __name__ == "__main__":
    sys.exit(main())
