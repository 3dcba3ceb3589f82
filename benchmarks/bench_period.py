"""Per-period and per-call cost, side by side with an earlier version in one run.

Three routes, each in its own fresh processes with its own cache: ``current`` (the numbers as
inputs, the default), ``folded`` (the current code built with ``numbers="constants"``: like for like,
the one difference is the numbers) and ``earlier``, git commit ``BASELINE`` of this repository
(the numbers folded, the rigid body without the recursive algorithms, its own gains where they
were tuned since), extracted with ``git archive`` as ``bench_release.py`` does. For every shipped
robot the earlier version knows, in each route:

* every scenario's C loop: ``hydrogen.simulate`` of ``CONTROLLER`` (the scenario's own gains,
  duration and rig), ``loop_wall_s`` over the periods, µs per control period, the fastest of
  ``LOOP_REPEATS`` runs;
* every generated function both versions have with the same caller's inputs: ns per call from
  Python (``dyn.functions[name](*inputs)``, the compiled extension), the best of ``CALL_REPEATS``
  timings of ``CALL_NUMBER`` calls.

The routes rotate (which runs first changes each round) for ``ROUNDS`` rounds (2 with
``--quick``); each figure is the median over the rounds. Reported with the ratios current / folded
(bounded with the release checks: no more than ``BOUND``) and current / earlier.

Run: ``python benchmarks/bench_period.py [--quick] [--json FILE]`` (about 3-5 minutes).
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

try:  # imported as benchmarks.bench_period
    from . import common
    from .bench_release import Version, _extract_previous
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common
    from bench_release import Version, _extract_previous

BASELINE = "05a59d8"
CONTROLLER = "adaptive-robust"
ROUNDS, QUICK_ROUNDS = 5, 2
CALL_NUMBER, CALL_REPEATS = 2000, 5
#: Runs of each scenario per round; the fastest counts (a shared machine only ever slows a run down).
LOOP_REPEATS = 3
#: The bound of the release checks: current / earlier no more than this.
BOUND = 1.10

_MEASURE = """
import json, timeit
import numpy as np
import hydrogen
print("hydrogen_file", 0, hydrogen.__file__)
from hydrogen.simulation.scenarios import scenario_names
out = {{}}
for name in {robots!r}:
    if name not in hydrogen.models():
        continue
    model = hydrogen.load_model(name)
    dyn = hydrogen.build(model, **{build_kw!r})
    loops = {{}}
    for s in scenario_names(model):
        hydrogen.simulate(s, {controller!r}, dyn=dyn, duration=0.2)  # warm-up: its library compiled and loaded
        runs = [hydrogen.simulate(s, {controller!r}, dyn=dyn) for _ in range({loop_repeats})]
        loops[s] = min(r.loop_wall_s / len(r.t) for r in runs) * 1e6  # the least disturbed run
    calls = {{}}
    rng = np.random.default_rng(0)
    for fname in sorted(dyn.functions):
        if fname.startswith("ctrl_"):
            continue  # the controllers: their cost is the loop's
        fn = dyn.functions[fname]
        args = [np.ascontiguousarray(rng.uniform(-0.1, 0.1, shape if shape[1] != 1 else (shape[0],)))
                for shape in fn.in_shapes]
        args = [model.neutral_pose + a if n == "q" else a for n, a in zip(fn.in_names, args)]
        best = min(timeit.repeat(lambda: fn(*args), number={number}, repeat={repeats}))
        calls[fname] = {{"ns": best / {number} * 1e9, "inputs": list(fn.in_names)}}
    out[name] = {{"loops": loops, "calls": calls}}
print("JSON", json.dumps(out))
"""


def _measure(version: Version, robots: list, build_kw: dict) -> dict:
    stdout, _ = version.run(_MEASURE.format(robots=robots, controller=CONTROLLER, number=CALL_NUMBER,
                                            repeats=CALL_REPEATS, loop_repeats=LOOP_REPEATS, build_kw=build_kw))
    line = next(line for line in stdout.splitlines() if line.startswith("JSON "))
    return json.loads(line[5:])


def _median_of(rounds: list, path) -> float | None:
    values = []
    for r in rounds:
        v = r
        for k in path:
            v = v.get(k) if isinstance(v, dict) else None
        if isinstance(v, (int, float)):
            values.append(v)
    return common.median(values) if len(values) == len(rounds) else None


def run(quick: bool = False) -> dict:
    t0 = time.perf_counter()
    robots = common.robots()
    rounds = QUICK_ROUNDS if quick else ROUNDS
    with tempfile.TemporaryDirectory(prefix="bench_period_") as tmp:
        tmp = Path(tmp)
        reason = _extract_previous(tmp / "earlier", BASELINE)
        if reason:
            return {"skipped": f"no side-by-side comparison: {reason}", "baseline": BASELINE}
        routes = {"earlier": (Version(f"commit {BASELINE}", tmp / "earlier", tmp / "cache-earlier"), {}),
                  "folded": (Version("current", common.REPO, tmp / "cache-folded"), {"numbers": "constants"}),
                  "current": (Version("current", common.REPO, tmp / "cache-current"), {})}
        results = {k: [] for k in routes}
        order = list(routes)
        for i in range(rounds):
            for key in order[i % 3:] + order[:i % 3]:
                version, build_kw = routes[key]
                results[key].append(_measure(version, robots, build_kw))
    rows = []
    for name in robots:
        if name not in results["earlier"][0]:
            continue
        for s in results["current"][0][name]["loops"]:
            v = {k: _median_of(results[k], (name, "loops", s)) for k in results}
            if None not in v.values():
                rows.append({"robot": name, "what": "loop", "name": s, **v, "ratio": v["current"] / v["folded"],
                             "ratio_earlier": v["current"] / v["earlier"]})
        for f, c in results["current"][0][name]["calls"].items():
            p = results["earlier"][0][name]["calls"].get(f)
            if p is None or p["inputs"] != c["inputs"]:
                continue  # new, or another caller's signature: not like for like
            v = {k: _median_of(results[k], (name, "calls", f, "ns")) for k in results}
            rows.append({"robot": name, "what": "call", "name": f, **v, "ratio": v["current"] / v["folded"],
                         "ratio_earlier": v["current"] / v["earlier"]})
    return {"baseline": BASELINE, "controller": CONTROLLER, "rounds": rounds, "bound": BOUND, "rows": rows,
            "within_bound": bool(rows) and all(r["ratio"] <= BOUND for r in rows), "wall_s": time.perf_counter() - t0,
            "machine": common.machine_info()}


def print_table(res: dict, checks: bool = False) -> None:
    """The table; with ``checks`` (the project's release checks) the bound of each row."""
    if "skipped" in res:
        print(res["skipped"])
        return
    print(f"The current version (numbers as inputs), the same built folded, and commit {res['baseline']}, in one "
          f"run (median of {res['rounds']} rotating rounds): C loop µs per period of every scenario "
          f"({res['controller']}) and ns per call from Python:")
    header = (f"{'robot':<15} {'what':<5} {'scenario or function':<24} {'earlier':>9} {'folded':>9} {'current':>9} "
              f"{'/folded':>8} {'/earlier':>8}")
    header += f" {'<= ' + format(res['bound'], '.2f'):>7}" if checks else ""
    print(header)
    print("-" * len(header))
    for r in res["rows"]:
        line = (f"{r['robot']:<15} {r['what']:<5} {r['name']:<24} {r['earlier']:>9.2f} {r['folded']:>9.2f} "
                f"{r['current']:>9.2f} {r['ratio']:>8.2f} {r['ratio_earlier']:>8.2f}")
        if checks:
            line += f" {'ok' if r['ratio'] <= res['bound'] else 'FAIL':>7}"
        print(line)
    print(f"whole benchmark {res['wall_s']:.1f} s")


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, lambda r: print_table(r, checks=True)))
