"""Per-period and per-call cost, side by side with an earlier version in one run.

Four routes, each in its own fresh processes with its own cache: ``current`` (the numbers as
inputs, the default), ``folded`` (the current code built with ``numbers="constants"``: like for like,
the one difference is the numbers), ``earlier``, git commit ``--baseline`` (default :data:`BASELINE`)
of this repository (its own default build, descriptions and gains; 6480770 has the numbers as
inputs too), extracted with ``git archive`` as ``bench_release.py`` does, and ``described``, the
current code on the earlier version's own descriptions (the keys renamed since migrated,
:data:`RENAMED`, the defaults changed since stated as they were, :data:`FORMER_DEFAULTS`, and the rig's
settings now given per joint actuator, :func:`own_rig_settings`):
like for like with ``earlier`` by construction. For every shipped robot the earlier version knows,
in each route:

* every scenario's C loop: ``hydrogen.simulate`` of ``CONTROLLER`` (the scenario's own gains,
  duration and rig), ``loop_wall_s`` over the periods, µs per control period, the fastest of
  ``LOOP_REPEATS`` runs;
* every generated function both versions have with the same caller's inputs: ns per call from
  Python (``dyn.functions[name](*inputs)``, the compiled extension), the best of ``CALL_REPEATS``
  timings of ``CALL_NUMBER`` calls.

The routes rotate (which runs first changes each round) for ``--rounds`` rounds (default
``ROUNDS``, 2 with ``--quick``; more where other work shares the cores); each figure is the median
over the rounds. Reported with the ratios current / folded, current / earlier and described /
earlier, all bounded with the release checks where they are like
for like (current / folded by :data:`FOLDED_BOUND`, the others by ``--bound``, default
:data:`BOUND`): current / earlier only for the same robot in the description (links, joints,
hydraulics, cylinders, an included URDF; not its controllers list), and for a loop the same rig,
timing and scenario and the same controller variant (gains tuned since may run the lean one, or no
longer); described / earlier unless the current code runs another controller variant.

Run: ``python benchmarks/bench_period.py [--quick] [--json FILE] [--baseline COMMIT] [--bound RATIO]
[--rounds N]`` (about 5-8 minutes on an idle machine, 9 minutes for 9 rounds at a load of 8).
``--json docs/bench.json`` (``hydrogen bench``'s results) replaces only this module's section
there and renders the page beside it again.
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

#: The earlier commit compared with (``--baseline COMMIT``): the version measured when the blocks'
#: contract work was asked for, whose tracker entry asks for per-period and per-call cost within
#: 5 % of it like for like (:data:`BOUND`). Its numbers are inputs, as the current code's default.
BASELINE = "6480770"
CONTROLLER = "adaptive-robust"
ROUNDS, QUICK_ROUNDS = 5, 2
CALL_NUMBER, CALL_REPEATS = 2000, 5
#: Runs of each scenario per round; the fastest counts (a shared machine only ever slows a run down).
LOOP_REPEATS = 3
#: The bound of the release checks against the earlier commit (``--bound``): current / earlier and
#: described / earlier, where like for like, no more than this (1.05 for :data:`BASELINE`).
BOUND = 1.05
#: The bound of current / folded (the numbers as inputs against folded, the same code): the release
#: checks' own, whatever the earlier commit.
FOLDED_BOUND = 1.10

_MEASURE = """
import hashlib, json, timeit, tomllib
from pathlib import Path
import numpy as np
import hydrogen
from hydrogen.model import model_path
from hydrogen.simulation.simulator import prepare_run
print("hydrogen_file", 0, hydrogen.__file__)
def digest(x):
    return hashlib.sha256(json.dumps(x, sort_keys=True, default=str).encode()).hexdigest()
from hydrogen.simulation.scenarios import scenario_names
out = {{}}
described = {described!r}  # robot name -> the description file to load in its place (None: the shipped one)
for name in {robots!r}:
    if name not in hydrogen.models():
        continue
    path = described.get(name)
    model = hydrogen.load_model(path or name)
    dyn = hydrogen.build(model, **{build_kw!r})
    # what the generated functions depend on (not the gains, rig, timing or scenarios), and per scenario
    # what its loop's cost depends on besides (the variant is recorded on its own)
    toml = tomllib.loads((Path(path) if path else model_path(name)).read_text())
    # the controllers list only picks which controllers are generated: not the other functions' cost,
    # nor the loop's of the one timed (both versions generate it)
    robot = {{k: v for k, v in toml.items()
              if k not in ("gains", "variants", "scenarios", "rig", "control", "controllers")}}
    # a kinematic tree read from a URDF beside the description: its text is part of the robot
    urdf = toml.get("urdf")
    if isinstance(urdf, str):
        robot["urdf text"] = ((Path(path) if path else model_path(name)).parent / urdf).read_text()
    loops, variants, setups = {{}}, {{}}, {{}}
    for s in scenario_names(model):
        hydrogen.simulate(s, {controller!r}, dyn=dyn, duration=0.2)  # warm-up: its library compiled and loaded
        runs = [hydrogen.simulate(s, {controller!r}, dyn=dyn) for _ in range({loop_repeats})]
        loops[s] = min(r.loop_wall_s / len(r.t) for r in runs) * 1e6  # the least disturbed run
        variants[s] = prepare_run(dyn, s, {controller!r}, None, 0.05, True, {{}}).ctrl.variant or "full"
        setups[s] = digest([robot, toml.get("rig"), toml.get("control"), toml.get("scenarios", {{}}).get(s)])
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
    out[name] = {{"loops": loops, "variants": variants, "setups": setups, "calls": calls, "robot": digest(robot)}}
print("JSON", json.dumps(out))
"""


def _measure(version: Version, robots: list, build_kw: dict, described: dict | None = None) -> dict:
    stdout, _ = version.run(_MEASURE.format(robots=robots, controller=CONTROLLER, number=CALL_NUMBER,
                                            repeats=CALL_REPEATS, loop_repeats=LOOP_REPEATS, build_kw=build_kw,
                                            described={k: str(v) for k, v in (described or {}).items()}))
    line = next(line for line in stdout.splitlines() if line.startswith("JSON "))
    return json.loads(line[5:])


#: Description keys renamed since ``BASELINE``: (table, old key, new key, new value from the old one
#: and the table), so the current code loads the earlier version's descriptions.
RENAMED = (("rig", "delay_periods", "delay", lambda v, table: v / table["control_rate"]),)
#: Scenario fields whose default changed since ``BASELINE``, with the value that computes what it did:
#: set in the earlier descriptions' [rig] and [scenarios.*] tables (like for like: the same integration).
FORMER_DEFAULTS = {"pressure_bounds": "step"}


def own_rig_settings(toml: Path) -> str:
    """The tables a description written before the rig's travel settings were given per actuator
    needs for the current code: each joint actuator (a travel not in m) with the rig's own friction
    and sensor settings, the same numbers, as the earlier version applied them to every actuator in
    its own coordinate ('' when none is needed)."""
    import tomllib

    import hydrogen
    from hydrogen.actuators import actuator
    from hydrogen.actuators.declarations import LENGTH
    from hydrogen.simulation.scenarios import PER_ACTUATOR

    rig = tomllib.loads(toml.read_text(encoding="utf-8")).get("rig", {})
    given = {k: rig[k] for k in PER_ACTUATOR if k in rig}
    if not given or "actuators" in rig:
        return ""
    joints = [c.name for c in hydrogen.load_model(toml).cylinders if actuator(c.kind).TRAVEL != LENGTH]
    return "".join(f"\n[rig.actuators.{json.dumps(name)}]\n" + "".join(f"{k} = {v!r}\n" for k, v in given.items())
                   for name in joints)


def earlier_descriptions(data: Path, dest: Path) -> dict:
    """The descriptions shipped in ``data`` (the earlier version's ``hydrogen/data``) copied into
    ``dest`` with the keys of :data:`RENAMED` migrated and the joint actuators' rig settings given
    (:func:`own_rig_settings`): {robot name: TOML path}."""
    import re
    import shutil
    import tomllib

    shutil.copytree(data, dest)
    out = {}
    for toml in sorted(dest.glob("*.toml")):
        text = toml.read_text(encoding="utf-8")
        parsed = tomllib.loads(text)
        for table, old, new, value in RENAMED:
            if old not in parsed.get(table, {}):
                continue
            head = re.search(rf"^\[{table}\]\s*$", text, re.M)
            key = re.compile(rf"^{old}\s*=.*$", re.M).search(text, head.end())
            text = f"{text[:key.start()]}{new} = {value(parsed[table][old], parsed[table])!r}{text[key.end():]}"
        for field, value in FORMER_DEFAULTS.items():  # each table that runs a scenario states the old default
            text = re.sub(r"^(\[(?:rig|scenarios\.[A-Za-z0-9_-]+)\][ \t]*)$", rf"\1\n{field} = {json.dumps(value)}",
                          text, flags=re.M)
        toml.write_text(text, encoding="utf-8")
        extra = own_rig_settings(toml)  # read from the renamed file: the current code loads it
        if extra:
            toml.write_text(text + extra, encoding="utf-8")
        out[toml.stem] = toml
    return out


def _median_of(rounds: list, path) -> float | None:
    values = []
    for r in rounds:
        v = r
        for k in path:
            v = v.get(k) if isinstance(v, dict) else None
        if isinstance(v, (int, float)):
            values.append(v)
    return common.median(values) if len(values) == len(rounds) else None


def run(quick: bool = False, baseline: str = BASELINE, bound: float = BOUND, rounds: int | None = None) -> dict:
    """The figures of every route against commit ``baseline`` over ``rounds`` rounds (default
    :data:`ROUNDS`, :data:`QUICK_ROUNDS` with ``quick``), each like-for-like ratio against it checked
    against ``bound`` (``within_bound``; current / folded against :data:`FOLDED_BOUND`)."""
    t0 = time.perf_counter()
    robots = common.robots()
    rounds = rounds or (QUICK_ROUNDS if quick else ROUNDS)
    with tempfile.TemporaryDirectory(prefix="bench_period_") as tmp:
        tmp = Path(tmp)
        reason = _extract_previous(tmp / "earlier", baseline)
        if reason:
            return {"skipped": f"no side-by-side comparison: {reason}", "baseline": baseline}
        described = earlier_descriptions(tmp / "earlier" / "hydrogen" / "data", tmp / "described")
        routes = {"earlier": (Version(f"commit {baseline}", tmp / "earlier", tmp / "cache-earlier"), {}, {}),
                  "folded": (Version("current", common.REPO, tmp / "cache-folded"), {"numbers": "constants"}, {}),
                  "current": (Version("current", common.REPO, tmp / "cache-current"), {}, {}),
                  # the current code on the earlier version's descriptions: like for like with it
                  "described": (Version("current", common.REPO, tmp / "cache-described"), {}, described)}
        results = {k: [] for k in routes}
        order = list(routes)
        for i in range(rounds):
            for key in order[i % len(order):] + order[:i % len(order)]:
                version, build_kw, files = routes[key]
                results[key].append(_measure(version, robots, build_kw, files))
    rows = []
    for name in robots:
        if name not in results["earlier"][0]:
            continue
        now, then = results["current"][0][name], results["earlier"][0][name]
        same = results["described"][0].get(name, {})  # the current code, the earlier description
        # Against the earlier version, like for like only where it describes the same robot (links,
        # joints, hydraulics, cylinders: what the functions depend on) and, for a loop, the same rig,
        # timing and scenario, run with the same controller variant (gains tuned since may switch the
        # lean one on or off).
        same_robot = now.get("robot") == then.get("robot")
        for s in dict.fromkeys([*now["loops"], *then["loops"]]):
            v = {k: _median_of(results[k], (name, "loops", s)) for k in results}
            variants = (then.get("variants", {}).get(s), now.get("variants", {}).get(s))
            setups = (then.get("setups", {}).get(s), now.get("setups", {}).get(s))
            rows.append(_ratios({"robot": name, "what": "loop", "name": s, **v, "variants": list(variants),
                                 "like_for_like": same_robot and variants[0] == variants[1] and setups[0] == setups[1],
                                 "same_setup": setups[0] == setups[1],
                                 # the same description file: like for like unless another variant runs
                                 "described_like_for_like": same.get("variants", {}).get(s) == variants[0]}))
        for f in dict.fromkeys([*now["calls"], *same.get("calls", {})]):
            p = then["calls"].get(f)
            if p is None:
                continue  # new since
            v = {k: _median_of(results[k], (name, "calls", f, "ns")) for k in results}
            # another caller's signature is not like for like
            like = {k: r.get("calls", {}).get(f, {}).get("inputs") == p["inputs"] for k, r in (("now", now), ("same", same))}
            rows.append(_ratios({"robot": name, "what": "call", "name": f, **v,
                                 "like_for_like": same_robot and like["now"], "described_like_for_like": like["same"]}))
    rows = [r for r in rows if "ratio" in r or "ratio_described" in r]
    for r in rows:
        r["unlike"] = unlike(r)  # why current / earlier is not like for like, '' when it is
        r["above_bound"] = above_bound(r, bound, FOLDED_BOUND)
    return {"baseline": baseline, "controller": CONTROLLER, "rounds": rounds, "bound": bound,
            "bound_folded": FOLDED_BOUND, "rows": rows,
            "within_bound": bool(rows) and all(within_bound(r, bound, FOLDED_BOUND) for r in rows),
            "wall_s": time.perf_counter() - t0, "machine": common.machine_info()}


def _ratios(row: dict) -> dict:
    """``row`` with the ratios its figures give: current / folded (``ratio``), current / earlier
    (``ratio_earlier``) and, on the earlier descriptions, current / earlier (``ratio_described``)."""
    for key, (a, b) in {"ratio": ("current", "folded"), "ratio_earlier": ("current", "earlier"),
                        "ratio_described": ("described", "earlier")}.items():
        if row.get(a) is not None and row.get(b) is not None:
            row[key] = row[a] / row[b]
    return row


def above_bound(row: dict, bound: float, folded_bound: float = FOLDED_BOUND) -> list:
    """The row's ratios above their bound: ``ratio`` (current / folded) above ``folded_bound``, and
    ``ratio_earlier`` (shipped descriptions) and ``ratio_described`` (the earlier descriptions run by
    both versions) above ``bound`` where that is like for like."""
    return [key for key, like, b in (("ratio", None, folded_bound), ("ratio_earlier", "like_for_like", bound),
                                     ("ratio_described", "described_like_for_like", bound))
            if row.get(key, 0.0) > b and (like is None or row.get(like, True))]


def within_bound(row: dict, bound: float, folded_bound: float = FOLDED_BOUND) -> bool:
    """Every ratio of the row within its bound (:func:`above_bound`)."""
    return not above_bound(row, bound, folded_bound)


def unlike(row: dict) -> str:
    """Why the row's comparison with the earlier version is not like for like ('' when it is)."""
    if "ratio_earlier" not in row:
        return "one version has no such scenario or function"
    if row.get("like_for_like", True):
        return ""
    v = row.get("variants")
    if v and v[0] != v[1]:
        return f"{v[0]} vs {v[1]} variant"
    return "other rig, timing or scenario" if row.get("same_setup") is False else "other robot description"


def print_table(res: dict, checks: bool = False) -> None:
    """The table; with ``checks`` (the project's release checks) the bound of each row."""
    if "skipped" in res:
        print(res["skipped"])
        return
    print(f"The current version (numbers as inputs), the same built folded, and commit {res['baseline']}, in one "
          f"run (median of {res['rounds']} rotating rounds): C loop µs per period of every scenario "
          f"({res['controller']}) and ns per call from Python:")
    print("'described': the current code on the commit's own descriptions (renamed keys migrated), like for like "
          "with it unless another controller variant runs ('*').")
    num = lambda v, w=9: f"{v:>{w}.2f}" if v is not None else f"{'–':>{w}}"  # noqa: E731
    header = (f"{'robot':<15} {'what':<5} {'scenario or function':<24} {'earlier':>9} {'folded':>9} {'current':>9} "
              f"{'described':>9} {'/folded':>8} {'/earlier':>8} {'desc./earlier':>13}")
    header += f" {'<= ' + format(res['bound'], '.2f'):>7}" if checks else ""
    if checks:
        print(f"Bounds where like for like: /earlier and desc./earlier <= {res['bound']:.2f}, "
              f"/folded <= {res.get('bound_folded', FOLDED_BOUND):.2f}.")
    print(header)
    print("-" * len(header))
    for r in res["rows"]:
        line = (f"{r['robot']:<15} {r['what']:<5} {r['name']:<24} {num(r.get('earlier'))} {num(r.get('folded'))} "
                f"{num(r.get('current'))} {num(r.get('described'))} {num(r.get('ratio'), 8)} "
                f"{num(r.get('ratio_earlier'), 8)} {num(r.get('ratio_described'), 12)}"
                f"{'*' if 'ratio_described' in r and not r.get('described_like_for_like', True) else ' '}")
        if checks:
            line += f" {'ok' if within_bound(r, res['bound'], res.get('bound_folded', FOLDED_BOUND)) else 'FAIL':>7}"
        why = r.get("unlike") or unlike(r)
        print(line + (f"  (/earlier not like for like: {why})" if why else ""))
    print(f"whole benchmark {res['wall_s']:.1f} s")


def _commit(text: str) -> str:
    """``--baseline``: a commit of this repository (its abbreviation as given), checked before the run."""
    import argparse
    import subprocess

    ok = subprocess.run(["git", "-C", str(common.REPO), "cat-file", "-e", f"{text}^{{commit}}"],
                        capture_output=True, text=True, timeout=60)
    if ok.returncode != 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a commit of {common.REPO}")
    return text


def _rounds(text: str) -> int:
    """``--rounds``: a whole number of rounds, at least 1."""
    import argparse

    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of rounds (a whole number, at least 1)")
    return int(text)


def _bound(text: str) -> float:
    """``--bound``: a ratio of at least 1 (1.05: within 5 %)."""
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 1.0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a ratio of at least 1 (1.05: within 5 %)")
    return value


#: The script's own options, passed to :func:`run`.
OPTIONS = {"--baseline": {"type": _commit, "default": BASELINE, "metavar": "COMMIT",
                          "help": f"the earlier commit compared with (default {BASELINE})"},
           "--bound": {"type": _bound, "default": BOUND, "metavar": "RATIO",
                       "help": f"the bound of every like-for-like ratio (default {BOUND}: within 5 %%)"},
           "--rounds": {"type": _rounds, "default": None, "metavar": "N",
                        "help": f"rotating rounds, each figure their median (default {ROUNDS}; {QUICK_ROUNDS} "
                                "with --quick): more where other work shares the cores"}}

if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, lambda r: print_table(r, checks=True), options=OPTIONS))
