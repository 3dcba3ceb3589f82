"""Friction compensation (a deviation from the paper, off by default) measured on the rig scenarios:
for each robot's rig scenarios (the Stewart platform's also at ``.low-latency``) and adaptive
controller, the max tracking error (% of the reference amplitude, the worst moving coordinate)
over noise seeds, median [min - max], with the shipped gains (no compensation) and with the
compensation of :data:`COMPENSATION` on top of them.

The compensation gains were chosen on seeds 0-9 (``--tune``); the measurement runs seeds 100-119,
never tuned on. Prints the table as Markdown; ``--json FILE`` also writes the numbers (atomically).

Run: ``python benchmarks/friction_compensation.py [--seeds 100-119] [--workers W] [--json FILE]``
(about 10 minutes on 2 cores); ``--tune`` prints the grid on seeds 0-9 instead.
"""
from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's hydrogen, run from anywhere

from benchmarks.common import merge_rows  # noqa: E402
from hydrogen.fileio import atomic_write  # noqa: E402
import hydrogen  # noqa: E402
from hydrogen.runtime.build import default_dynamics  # noqa: E402
from hydrogen.simulation.seeds import parse_seeds, seed_list  # noqa: E402
from hydrogen.simulation.simulator import simulate  # noqa: E402

#: (robot, scenarios, controllers) measured.
CASES = (("ubc_stewart", ("z-1hz", "z-2hz", "psi-1hz", "z-1hz.low-latency", "z-2hz.low-latency",
                          "psi-1hz.low-latency"), ("adaptive-robust",)),
         ("excavator_arm", ("arm-dig",), ("adaptive-robust", "adaptive-observer")),
         ("loader_crane", ("crane-load",), ("adaptive-robust", "adaptive-observer")))

#: The compensation switched on, per robot, over the gains each scenario runs with: the adaptation
#: rate of the friction estimates (1/J, normalised by their bounds) and the smooth sign's width
#: (m/s or rad/s), chosen on seeds 0-9 with ``--tune``. The estimates start at 0 (no prior friction
#: knowledge) and are bounded by the defaults (5 % of each actuator's force range; 10 % per unit/s).
COMPENSATION = {
    # tune: worst median over z-1hz / z-2hz / psi-1hz 3.25 % (0.74 / 3.25 / 1.46), worst seed 3.90 %; the
    # next best 0.3 and 0.03: 3.86 %
    "ubc_stewart": {"rate_friction": 1.0, "friction_speed": 0.01},
    "excavator_arm": {"rate_friction": 0.003, "friction_speed": 0.03},   # 0.54 / 0.80 % (robust / observer)
    "loader_crane": {"rate_friction": 0.03, "friction_speed": 0.003},    # 0.16 / 0.80 %; 0.1 rings
}

#: The grid ``--tune`` searches per robot (each point on top of the shipped gains): the rate is
#: normalised by the bounds, which scale with the actuators' force, not with the robot's inertia, so
#: each robot has its own range (probed on seeds 0 and 1 first).
TUNE_GRID = {"ubc_stewart": {"rate_friction": (0.1, 0.3, 1.0), "friction_speed": (0.003, 0.01, 0.03)},
             "excavator_arm": {"rate_friction": (0.001, 0.003, 0.01), "friction_speed": (0.003, 0.01, 0.03)},
             "loader_crane": {"rate_friction": (0.01, 0.03, 0.1), "friction_speed": (0.003, 0.01, 0.03)}}
TUNE_SEEDS = "0-9"


def parse_range(text: str):
    """``--seeds``: ``100-119`` (inclusive) or what :func:`parse_seeds` reads (``10``, ``0,3,7``)."""
    a, sep, b = text.partition("-")
    return list(range(int(a), int(b) + 1)) if sep and a.isdigit() and b.isdigit() else parse_seeds(text)


def worst_error(metrics) -> float:
    """The worst moving coordinate's max error (% of its reference amplitude)."""
    return max(v for v in metrics["max_error_pct"].values() if v is not None)


def errors(robot, scenario, controller, seeds, gains, workers) -> dict:
    """{"median", "min", "max", "failed"} of the worst error over ``seeds`` (a failed seed counts as inf).
    ``gains`` None: the shipped robot (the paper's laws, generated without compensation); else the
    robot generated with it (``[control] friction_compensation``) and these gains."""
    if gains:
        model = dataclasses.replace(hydrogen.load_model(robot), friction_compensation=True)
        dyn = hydrogen.build(model, controllers=[controller])
    else:
        dyn = default_dynamics(robot, None, controller)
    res = simulate(dyn, scenario, controller, gains=gains or None, seeds=seeds, max_workers=workers)
    e = np.array([worst_error(r.metrics) if r is not None else np.inf for r in res.results])
    return {"median": float(np.median(e)), "min": float(e.min()), "max": float(e.max()),
            "failed": sorted(res.failures), "per_seed": e.tolist()}


def measure(seeds, workers, robots=None) -> list:
    rows = []
    for robot, scenarios, controllers in CASES:
        if robots and robot not in robots:
            continue
        for scenario, controller in itertools.product(scenarios, controllers):
            off = errors(robot, scenario, controller, seeds, None, workers)
            on = errors(robot, scenario, controller, seeds, COMPENSATION[robot], workers)
            rows.append({"robot": robot, "scenario": scenario, "controller": controller, "off": off, "on": on,
                         "gains": COMPENSATION[robot]})
            print(_row(rows[-1]), flush=True)
    return rows


def _cell(e) -> str:
    fail = f", {len(e['failed'])} failed" if e["failed"] else ""
    return f"{e['median']:.2f} [{e['min']:.2f} - {e['max']:.2f}]{fail}"


def _row(r) -> str:
    ratio = r["off"]["median"] / r["on"]["median"] if r["on"]["median"] > 0 else float("inf")
    return (f"| {r['robot']} | {r['scenario']} | {r['controller']} | {_cell(r['off'])} | {_cell(r['on'])} | "
            f"{ratio:.2f} |")


def markdown(rows, seeds) -> str:
    s = seed_list(seeds)
    head = [f"Max tracking error (% of amplitude, worst moving coordinate) over seeds {s[0]}-{s[-1]}: "
            "median [min - max]; ratio = median without / median with.", "",
            "| robot | scenario | controller | without | with compensation | ratio |", "|---|---|---|---|---|---:|"]
    return "\n".join(head + [_row(r) for r in rows]) + "\n"


def tune(workers, robots=None) -> None:
    """The grid on seeds 0-9: per robot and point, the median worst error per scenario and controller."""
    seeds = parse_range(TUNE_SEEDS)
    for robot, scenarios, controllers in CASES:
        if robots and robot not in robots:
            continue
        grid = TUNE_GRID[robot]
        keys = list(grid)
        tuned = [s for s in scenarios if "." not in s]  # the full-period rig only
        for point in itertools.product(*grid.values()):
            gains = dict(zip(keys, point))
            cells = {f"{s} {c}": errors(robot, s, c, seeds, gains, workers)
                     for s, c in itertools.product(tuned, controllers)}
            worst = max(e["median"] for e in cells.values())
            print(robot, gains, f"worst median {worst:.2f}",
                  "; ".join(f"{k} {e['median']:.2f} (max {e['max']:.2f})" for k, e in cells.items()), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-119", help="noise seeds (default 100-119, never tuned on)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--robot", action="append", help="only this robot (repeatable; --json keeps the others' rows)")
    ap.add_argument("--json", type=Path, help="also write the numbers here")
    ap.add_argument("--tune", action="store_true", help="print the tuning grid on seeds 0-9 instead")
    args = ap.parse_args(argv)
    if args.tune:
        tune(args.workers, args.robot)
        return 0
    seeds = parse_range(args.seeds)
    rows = measure(seeds, args.workers, args.robot)
    print(markdown(rows, seeds))
    if args.json:
        if args.robot and args.json.exists():  # the file's rows of the other robots (same seeds) are kept
            old = json.loads(args.json.read_text())
            if old.get("seeds") == seed_list(seeds):
                rows = merge_rows(old["rows"], rows, lambda r: (r["robot"], r["scenario"], r["controller"]))
        atomic_write(args.json, json.dumps({"seeds": seed_list(seeds), "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
