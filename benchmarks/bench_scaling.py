"""How cost grows with the robot: a synthetic planar chain of n links, n = 2 ... 7.

The chain (:func:`chain_description`, loaded with ``hydrogen.model.model_from_dict``): n links of
1 m and 100 kg (slender rod: I_yy = I_zz = m L²/12 about the centre of mass, which sits at
(0.5, 0, 0.02) m in the link frame), on revolute joints about y in the x-z plane, hanging straight
down at the neutral pose (q_1 = π/2, the others 0; no gravity torque there). One cylinder per
joint, pinned between consecutive links (the first from the base), 0.5 m either side of the joint
and 0.25 m off the links' line: 1.0 m long at the neutral pose (stroke [0.75, 1.25] m), lever arm
0.25 m, so JL is diagonal (cond 1) there. Hydraulics of a mid-size machine (bore 80 mm, P_s 20 MPa).
θ: each link's mcx, mcz and I_yy (3n parameters, bounds ±50 %); joint encoders; one scenario,
``chain-sim``: a 2 s multi-sine of 0.05 rad per joint at 1 kHz, 2 RK4 sub-steps.

For each n, in a fresh Python process:

* the SymPy derivation as ``hydrogen.build`` does by default (the numbers as inputs), timed by
  stage: the cylinder kinematics, the rigid body (D, C, G, the regressor Y, its offset y0: closed
  form for short chains, staged link poses from 4 links on, see ``hydrogen.symbolic.forms``), the
  hydraulics, the plant and each controller; with the SymPy size (``count_ops``, a tree count:
  shared subexpressions count each time they occur) of D and C, whose own time (``count_ops_s``)
  is left out of the stages and of the derivation;
* the generation (``render``: SymPy -> CasADi -> C) and the clean compile (``hydrogen.build`` on the
  rendered folder, a fresh cache: the core library), then the first run of the adaptive-robust
  controller (``ADAPTIVE``, 10 ms of the scenario: mostly the compile of the library of the variant
  its gains run, which a first run waits for);
* each controller's CasADi instruction count (the manifest);
* the C loop's cost per control period, backstepping on chain-sim (no logs).

Each n has a time budget (``--budget`` seconds, default 600; 300 with ``--quick``, which runs n = 2
and 3 only). A process that runs out of it is stopped; the stages it finished and the one it was
in are reported (what bounds the generation), the growth per link is extrapolated to n = 7, and
larger n are not attempted.

Run: ``python benchmarks/bench_scaling.py [--quick] [--budget S] [--json FILE] [--n N ...]`` (``--n 12``:
other chain lengths than 2 ... 7)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

try:  # imported as benchmarks.bench_scaling
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

NS, QUICK_NS = tuple(range(2, 8)), (2, 3)
BUDGET_S, QUICK_BUDGET_S = 600.0, 300.0
#: The generation-time target for n = 7 on 2 cores (s).
TARGET_N, TARGET_S = 7, 120.0
SCENARIO, LOOP_CONTROLLER = "chain-sim", "backstepping"
#: The controller whose first use (its library's compile) is timed.
ADAPTIVE = "adaptive-robust"

LINK_LENGTH, LINK_MASS = 1.0, 100.0
COM = (0.5, 0.0, 0.02)
PIN_ALONG, PIN_OFF = 0.5, 0.25


def chain_description(n: int) -> dict:
    """The description (parsed-TOML form) of the planar chain of ``n`` links."""
    L, m = LINK_LENGTH, LINK_MASS
    rod = m * L * L / 12.0
    links, joints, cylinders = [], [], []
    for i in range(1, n + 1):
        parent = "base" if i == 1 else f"link{i - 1}"
        links.append({"name": f"link{i}", "mass": m, "com": list(COM), "inertia": [1e-2, rod, rod]})
        joints.append({"name": f"j{i}", "type": "revolute", "parent": parent, "child": f"link{i}",
                       "origin_xyz": [0.0, 0.0, 0.0] if i == 1 else [L, 0.0, 0.0], "axis": [0.0, 1.0, 0.0]})
        # The parent's pin: PIN_ALONG back from the joint along the parent, PIN_OFF to its side. The
        # first link hangs along -z from the base at the neutral pose, its side (link z) along +x.
        start = [PIN_OFF, 0.0, PIN_ALONG] if i == 1 else [L - PIN_ALONG, 0.0, PIN_OFF]
        cylinders.append({"name": f"cyl{i}", "from": {"link": parent, "point": start},
                          "to": {"link": f"link{i}", "point": [PIN_ALONG, 0.0, PIN_OFF]}})
    params = [f"link{i}.{k}" for i in range(1, n + 1) for k in ("mcx", "mcz", "Iyy")]
    true = {"mcx": m * COM[0], "mcz": m * COM[2], "Iyy": rod + m * (COM[0] ** 2 + COM[2] ** 2)}
    values = [true[p.split(".")[1]] for p in params]
    return {
        "name": f"chain{n}", "gravity": 9.81, "links": links, "joints": joints,
        "coordinates": {"neutral": [math.pi / 2] + [0.0] * (n - 1)},
        "hydraulics": {"piston_area": 5.0e-3, "rod_area": 2.5e-3, "chamber_length": 0.6,
                       "supply_pressure": 20.0e6, "underlap": 2.0e-5, "flow_gain": 2.0e-4,
                       "bulk_modulus": 7.0e8, "orifice_linear_below": 5.0e4, "stroke": [0.75, 1.25]},
        "cylinders": cylinders,
        "adaptation": {"parameters": params, "theta_min": [0.5 * v for v in values],
                       "theta_max": [1.5 * v for v in values], "gamma1_min": 3.5e8, "gamma1_max": 1.4e9,
                       "gamma2_min": 3.5e4, "gamma2_max": 5.6e5},
        "sensors": {"joint_encoders": True},
        "scenarios": {SCENARIO: {
            "label": f"{n}-link chain: joint-space multi-sine", "duration": 2.0, "control_rate": 1000.0,
            "substeps": 2, "t_adapt": 0.5,
            "theta0_factor": [1.2 if k % 2 else 0.8 for k in range(len(params))], "gamma0_factor": [0.8, 1.2],
            "reference": {"sines": [[i, 0.05, 0.5 + 0.25 * i] for i in range(n)]}}},
    }


def chain_model(n: int):
    from hydrogen.model import model_from_dict

    return model_from_dict(chain_description(n), source=f"<bench_scaling chain{n}>")


#: One n, in a fresh process: every line ``start <stage>`` / ``stage <stage> <s>`` / ``<key> <value>``.
_ONE = """
import json, sys, tempfile, time
from pathlib import Path
sys.path.insert(0, {bench!r})
t0 = time.perf_counter()
import sympy as sp
import hydrogen
import hydrogen.symbolic.functions as F
import hydrogen.symbolic.body_functions as B  # the rigid body's functions, by its stages
from hydrogen.controllers import CONTROLLERS, controller
from hydrogen.codegen.generate import DEFAULT_NUMBERS, derive, render
from bench_scaling import chain_model, SCENARIO, LOOP_CONTROLLER
import common
print("import_s", time.perf_counter() - t0, flush=True)
t0 = time.perf_counter()
model = chain_model({n})
print("load_model_s", time.perf_counter() - t0, flush=True)
sizes = {{}}
counting = [0.0]  # seconds spent in count_ops: measured, then left out of every stage and of derive_s

def timed(stage, f, size=None):
    def wrapper(*a, **k):
        print("start", stage, flush=True)
        t, c0 = time.perf_counter(), counting[0]
        out = f(*a, **k)
        print("stage", stage, time.perf_counter() - t - (counting[0] - c0), flush=True)
        if size:
            t = time.perf_counter()
            print("ops_" + size, sp.count_ops(out), flush=True)
            counting[0] += time.perf_counter() - t
        return out
    return wrapper

for name, size in (("mass_matrix", "D"), ("coriolis_matrix", "C"), ("gravity", None), ("regressor", None),
                   ("regressor_offset", None)):
    setattr(B, name, timed("rigid_body." + {{"mass_matrix": "D", "coriolis_matrix": "C", "gravity": "G",
                                             "regressor": "Y", "regressor_offset": "y0"}}[name],
                           getattr(B, name), size))
for name, stage in (("kinematics_functions", "kinematics"), ("rigid_body_functions", "rigid_body"),
                    ("hydraulic_functions", "hydraulics"), ("plant_functions", "plant")):
    setattr(F, name, timed(stage, getattr(F, name)))
for c in CONTROLLERS:
    mod = controller(c)
    mod.derive = timed("ctrl." + c, mod.derive)
t0 = time.perf_counter()
functions, names = derive(model, DEFAULT_NUMBERS)  # as hydrogen.build generates by default
print("derive_s", time.perf_counter() - t0 - counting[0], flush=True)
print("count_ops_s", counting[0], flush=True)
with tempfile.TemporaryDirectory() as tmp:
    folder = Path(tmp) / "generated" / model.name
    folder.mkdir(parents=True)
    print("start render", flush=True)
    t0 = time.perf_counter()
    manifest = render(model, folder, functions=functions, names=names, numbers=DEFAULT_NUMBERS)
    print("render_s", time.perf_counter() - t0, flush=True)
    print("JSON", json.dumps({{f["name"]: f["instructions"] for f in manifest["functions"]}}), flush=True)
    print("start compile", flush=True)
    t0 = time.perf_counter()
    dyn = hydrogen.build(model, cache=Path(tmp) / "cache", generated=folder)
    print("compile_s", time.perf_counter() - t0, flush=True)
    print("start controller_compile", flush=True)
    t0 = time.perf_counter()
    # its first run compiles the library of the variant the scenario's gains run
    hydrogen.simulate(SCENARIO, {adaptive!r}, dyn=dyn, duration=0.01)
    print("controller_compile_s", time.perf_counter() - t0, flush=True)
    from hydrogen.simulation.simulator import prepare_run
    print("controller_variant", prepare_run(dyn, SCENARIO, {adaptive!r}, None, 0.01, True, {{}}).ctrl.variant or "full",
          flush=True)
    print("start loop", flush=True)
    per = [common.c_loop_per_period(dyn, SCENARIO, LOOP_CONTROLLER, {periods}) for _ in range({repeats})]
    print("loop_us", sorted(per)[len(per) // 2] * 1e6, flush=True)
"""


def _parse(stdout: str) -> dict:
    out = {"stages": {}, "started": [], "sizes": {}}
    for line in stdout.splitlines():
        parts = line.split(None, 2)
        if not parts:
            continue
        if parts[0] == "start" and len(parts) == 2:
            out["started"].append(parts[1])
        elif parts[0] == "stage" and len(parts) == 3:
            out["stages"][parts[1]] = float(parts[2])
        elif parts[0] == "JSON":
            out["instructions"] = json.loads(line.split(None, 1)[1])
        elif parts[0].startswith("ops_") and len(parts) == 2:
            out["sizes"][parts[0][4:]] = int(parts[1])
        elif parts[0] == "controller_variant" and len(parts) == 2:
            out["controller_variant"] = parts[1]
        elif len(parts) == 2:
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                pass
    done = set(out["stages"]) | {"render" if "render_s" in out else "", "compile" if "compile_s" in out else "",
                                 "controller_compile" if "controller_compile_s" in out else "",
                                 "loop" if "loop_us" in out else ""}
    running = [s for s in out["started"] if s not in done]
    out["running"] = running[-1] if running else None
    return out


def run_one(n: int, budget: float, quick: bool) -> dict:
    code = _ONE.format(bench=str(Path(__file__).resolve().parent), n=n, periods=2000, repeats=3 if quick else 5,
                       adaptive=ADAPTIVE)
    env = common.python_env()
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=budget,
                              env=env, cwd=str(common.REPO))
        stdout, timed_out = proc.stdout, False
        if proc.returncode != 0:
            raise RuntimeError(f"chain{n}: the benchmark process failed (exit {proc.returncode}):\n"
                               f"{proc.stderr[-4000:]}")
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout or ""
        stdout, timed_out = out.decode() if isinstance(out, bytes) else out, True
    r = _parse(stdout)
    r.update(n=n, timed_out=timed_out, budget_s=budget, process_wall_s=time.perf_counter() - t0)
    if "derive_s" in r and "render_s" in r:
        r["generate_s"] = r["derive_s"] + r["render_s"]
    if "instructions" in r:
        r["controller_instructions"] = {k: v for k, v in r["instructions"].items() if k.startswith("ctrl_")}
    return r


def _extrapolate(rows: list, key: str, target: int):
    """Growth factor per link of ``key`` over the last two finished n, and its value at ``target``."""
    done = [r for r in rows if r.get(key) is not None]
    if len(done) < 2:
        return None, None
    a, b = done[-2], done[-1]
    factor = (b[key] / a[key]) ** (1.0 / (b["n"] - a["n"]))
    return factor, b[key] * factor ** (target - b["n"])


def run(quick: bool = False, budget: float | None = None, ns: tuple | None = None) -> dict:
    budget = float(budget or os.environ.get("HYDROGEN_BENCH_SCALING_BUDGET") or
                   (QUICK_BUDGET_S if quick else BUDGET_S))
    t_start = time.perf_counter()
    ns = tuple(ns) if ns else (QUICK_NS if quick else NS)
    rows, skipped = [], []
    for n in ns:
        if rows and rows[-1]["timed_out"]:
            skipped.append(n)
            continue
        rows.append(run_one(n, budget, quick))
    partial = [dict(r, derive_s=r.get("derive_s") or sum(v for k, v in r["stages"].items() if "." not in k))
               for r in rows]
    factor, estimate = _extrapolate([r for r in partial if not r["timed_out"]], "derive_s", TARGET_N)
    gen_factor, gen_estimate = _extrapolate([r for r in rows if not r["timed_out"]], "generate_s", TARGET_N)
    target_row = next((r for r in rows if r["n"] == TARGET_N and not r["timed_out"]), None)
    return {"rows": rows, "not_attempted": skipped, "budget_s": budget, "quick": quick,
            "target": {"n": TARGET_N, "seconds": TARGET_S,
                       "measured_generate_s": target_row["generate_s"] if target_row else None,
                       "met": bool(target_row and target_row["generate_s"] < TARGET_S),
                       "derive_growth_per_link": factor, "derive_estimate_s": estimate,
                       "generate_growth_per_link": gen_factor, "generate_estimate_s": gen_estimate},
            "cores": os.cpu_count(), "wall_s": time.perf_counter() - t_start}


#: Stages shown in the profile table, in derivation order.
_PROFILE = ("kinematics", "rigid_body.D", "rigid_body.C", "rigid_body.G", "rigid_body.Y", "rigid_body.y0",
            "rigid_body", "hydraulics", "plant", "ctrl.backstepping", "ctrl.adaptive-robust",
            "ctrl.adaptive-observer", "ctrl.p")


def print_table(res: dict, checks: bool = True) -> None:
    rows = res["rows"]
    ctrls = sorted({k for r in rows for k in r.get("controller_instructions", {})},
                   key=lambda k: ["ctrl_backstepping", "ctrl_adaptive_robust", "ctrl_adaptive_observer",
                                  "ctrl_p"].index(k) if k in ("ctrl_backstepping", "ctrl_adaptive_robust",
                                                               "ctrl_adaptive_observer", "ctrl_p") else 9)
    print(f"planar chain of n links, one cylinder per joint (budget {res['budget_s']:.0f} s per n, "
          f"{res['cores']} cores):")
    short = {"ctrl_backstepping": "bs", "ctrl_adaptive_robust": "ar", "ctrl_adaptive_observer": "ao", "ctrl_p": "p"}
    header = (f"{'n':>2} {'derive s':>9} {'render s':>9} {'generate s':>11} {'compile s':>10} {'ar 1st run s':>12} "
              + " ".join(f"{'instr ' + short.get(c, c):>10}" for c in ctrls) + f" {'loop us':>8}")
    print(header)
    print("-" * len(header))
    f = lambda r, k, spec=".1f": "-" if r.get(k) is None else format(r[k], spec)  # noqa: E731
    for r in rows:
        ins = r.get("controller_instructions", {})
        line = (f"{r['n']:>2} {f(r, 'derive_s'):>9} {f(r, 'render_s'):>9} {f(r, 'generate_s'):>11} "
                f"{f(r, 'compile_s'):>10} {f(r, 'controller_compile_s'):>12} " + " ".join(f"{ins.get(c, '-'):>10}" for c in ctrls)
                + f" {f(r, 'loop_us', '.2f'):>8}")
        if r["timed_out"]:
            line += f"  stopped after {r['budget_s']:.0f} s in '{r['running']}'"
        print(line)
    for n in res["not_attempted"]:
        print(f"{n:>2} not attempted (a smaller chain ran out of the budget)")
    print("derivation profile, seconds per stage (D and C: SymPy count_ops):")
    header = f"{'stage':<24}" + "".join(f"{'n=' + str(r['n']):>10}" for r in rows)
    print(header)
    print("-" * len(header))
    for st in _PROFILE:
        cells = []
        for r in rows:
            v = r["stages"].get(st)
            cells.append(f"{v:>10.2f}" if v is not None else f"{'(running)' if r['running'] == st else '-':>10}")
        print(f"{st:<24}" + "".join(cells))
    for size in ("D", "C"):
        print(f"{'ops of ' + size:<24}" + "".join(f"{r['sizes'].get(size, '-'):>10}" for r in rows))
    t = res["target"]
    if t["measured_generate_s"] is not None:
        print(f"n = {t['n']}: generation {t['measured_generate_s']:.1f} s"
              + (f" (target < {t['seconds']:.0f} s): {'met' if t['met'] else 'NOT met'}" if checks else ""))
    elif t["derive_estimate_s"] is not None:
        print(f"n = {t['n']} not measured; the derivation grows {t['derive_growth_per_link']:.1f}x per link over "
              f"the last finished n: about {t['derive_estimate_s']:.3g} s at n = {t['n']}"
              + (f" (target: generation < {t['seconds']:.0f} s)" if checks else ""))
    print(f"whole benchmark {res['wall_s']:.0f} s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help=f"n = {', '.join(map(str, QUICK_NS))} only")
    ap.add_argument("--budget", type=float, help="seconds per n (default 600; 300 with --quick)")
    ap.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    ap.add_argument("--n", type=int, nargs="+", metavar="N", help="these chain lengths instead (e.g. --n 12)")
    a = ap.parse_args(argv)
    if a.n and min(a.n) < 1:
        ap.error("--n: chain lengths are at least 1")
    res = run(quick=a.quick, budget=a.budget, ns=a.n)
    print_table(res)
    if a.json:
        a.json.write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
