"""Tracking error when the pump's flow runs out: the excavator arm and the loader crane on their
shipped pumps (each description's ``[supply]``), in each robot's scenario whose motion asks for more
oil than the pump gives (``arm-flow``, ``crane-flow``: rig scenarios no gain is chosen for), every
controller the robot lists, with the measured supply pressure, the same controller assuming a constant
supply, and the robot on a constant supply of unlimited flow. Three supplies:

* ``constant``: a copy of the description without its ``[supply]`` table: the description's
  ``supply_pressure``, unlimited flow (the reference);
* ``measured``: the shipped pump; the controllers read the measured supply pressure
  (``supply_feedback`` true, the default);
* ``assumed``: the shipped pump; the same controllers fed the description's ``supply_pressure``
  instead (``supply_feedback`` false): a controller that assumes a constant supply.

Over noise seeds :data:`SEEDS` (not the seeds 0-9 the gains were tuned on). Reported per controller
and supply: the max tracking error (% of the reference amplitude) of each coordinate the reference
moves, median, min and max over the seeds; the lowest supply pressure reached (MPa) and the fraction
of the run it spends below :data:`LOW` of its nominal value; and, per robot, the peak oil flow the
reference motion asks for (the cylinders' and motors' displacement: a_A ẋ extending, a_B |ẋ|
retracting, no leakage or compressibility) and the fraction of the run it exceeds the pump's flow.
A failed (diverged) run is counted in ``failed`` and left out of the statistics.

Run: ``python benchmarks/supply_limits.py [--quick] [--json FILE]`` (about 2 minutes on 2 cores with
the builds cached; ``--quick``: the crane only, two controllers, one seed, 3 s runs).
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import hydrogen

try:  # imported as benchmarks.supply_limits
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

SEEDS, QUICK_SEEDS = (100, 101, 102, 103, 104), (100,)
QUICK_DURATION = 3.0  # s: past the rig's metric_start (2 s)
#: A supply pressure below this fraction of its nominal value counts as starved.
LOW = 0.9
#: The supplies compared: label -> (the copy has the pump, supply_feedback).
SUPPLIES = {"constant": (False, True), "measured": (True, True), "assumed": (True, False)}

#: Each robot: its scenario in which the pump's flow runs out, and where its pump's figures come from
#: (the description's ``[supply]`` table says the same).
ROBOTS = {
    "excavator_arm": {
        "scenario": "arm-flow",
        "sources": "Caterpillar 320 technical specifications (main system maximum flow, implement, 429 L/min = "
                   "2 x 214.5; maximum equipment pressure 35 000 kPa) and Cat service data for the 320 GC/320/323 "
                   "(main relief valve 35 000 kPa); hose volume chosen",
    },
    "loader_crane": {
        "scenario": "crane-flow",
        "sources": "chosen: no published pump data of a crane of its class was found (docs/loader_crane.md); "
                   "a 160 L/min pressure-compensated pump at the crane's 24 MPa, relief 26 MPa, 2 L of hose",
    },
}


def without_supply(text: str) -> str:
    """A description's TOML text without its ``[supply]`` table (the table's header, a comment after it
    allowed, to the next table's): the same robot on a constant supply. The result is checked to parse
    to the description's data less ``supply`` (a ValueError otherwise: never a silently wrong robot)."""
    import tomllib

    out, skipping = [], False
    for line in text.splitlines(keepends=True):
        head = line.split("#", 1)[0].strip()
        if head.startswith("["):
            name = head.strip("[]").strip()
            skipping = name == "supply" or name.startswith("supply.")
        if not skipping:
            out.append(line)
    result = "".join(out)
    want = {k: v for k, v in tomllib.loads(text).items() if k != "supply"}
    if tomllib.loads(result) != want:
        raise ValueError("the description's [supply] table is not one block of lines this edit can remove "
                         "(written inline or as dotted keys?)")
    return result


def _copy(name: str, folder: Path, pump: bool) -> Path:
    """Robot ``name``'s description copied into ``folder``, without its ``[supply]`` unless ``pump``."""
    return common.copy_description(name, folder, lambda text: text if pump else without_supply(text))


def reference_flow(dyn, scenario, t) -> np.ndarray:
    """The oil flow (m³/s) the reference motion of ``scenario`` (a Scenario) asks at times ``t`` (s): each
    actuator's displacement, a_A ẋ extending and a_B |ẋ| retracting (its kind's areas), summed."""
    from hydrogen.actuators import actuator

    model = dyn.model
    areas = np.array([actuator(c.kind).Numeric.areas(c.table) for c in model.cylinders], float)
    out = np.empty(len(t))
    for k, tk in enumerate(t):
        ref = scenario.reference(tk)
        rate = np.asarray(dyn.leg_jacobian(ref[0]) @ ref[1], float)
        out[k] = np.where(rate > 0, areas[:, 0] * rate, -areas[:, 1] * rate).sum()
    return out


def _supply_metrics(res, nominal: float) -> dict:
    """The run's lowest supply pressure (MPa) and the fraction of its periods below LOW x nominal."""
    ps = res.supply_pressure
    if ps is None:
        return {}
    return {"ps_min_mpa": float(ps.min()) / 1e6, "ps_low_frac": float((ps < LOW * nominal).mean())}


def run(quick: bool = False) -> dict:
    from hydrogen.plant import supply
    from hydrogen.simulation.scenarios import scenario as named_scenario
    from hydrogen.simulation.seeds import summarize
    from hydrogen.simulation.tuning import rig_scenarios

    start = time.perf_counter()
    seeds = QUICK_SEEDS if quick else SEEDS
    robots = ["loader_crane"] if quick else list(ROBOTS)
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in robots:
            r = ROBOTS[name]
            models = {}
            for pump in (False, True):
                folder = Path(tmp) / f"{name}-{'pump' if pump else 'constant'}"
                folder.mkdir()
                models[pump] = hydrogen.load_model(_copy(name, folder, pump))
                hydrogen.build(models[pump])  # once here, before the workers load it
            pumped = models[True]
            sname = r["scenario"]
            moving = rig_scenarios(pumped, untuned=True)[sname]
            sc = named_scenario(sname, pumped)
            duration = QUICK_DURATION if quick else sc.duration
            controllers = list(pumped.controllers)[:2 if quick else None]
            q_p = float(pumped.supply.values["pump_flow"])
            nominal = supply.nominal(pumped)
            t = np.arange(0.0, duration, 1.0 / sc.control_rate)
            demand = reference_flow(hydrogen.build(pumped), sc, t)
            row = {"scenario": sname, "label": sc.label, "coordinates": list(moving), "supply": pumped.supply.kind,
                   "values": dict(pumped.supply.values), "nominal_mpa": nominal / 1e6, "sources": r["sources"],
                   "demand_peak_l_min": float(demand.max()) * 6e4, "pump_l_min": q_p * 6e4,
                   "demand_over_frac": float((demand > q_p).mean()), "controllers": {}}
            for label, (pump, feedback) in SUPPLIES.items():
                entries = [dict(scenario=sname, controller=c, seed=s, duration=duration,
                                **({} if feedback else {"supply_feedback": False}))
                           for c in controllers for s in seeds]
                out = hydrogen.sweep(entries, max_workers=min(2, os.cpu_count() or 1), model=models[pump],
                                     results=True)
                for i, c in enumerate(controllers):
                    per = [o if isinstance(o, dict) else {**o.metrics, **_supply_metrics(o, nominal)}
                           for o in out[i * len(seeds):(i + 1) * len(seeds)]]
                    summary = summarize(seeds, per)
                    point = common.spread_point(summary, moving, supply=label)
                    for key in ("ps_min_mpa", "ps_low_frac"):
                        point[key] = {stat: summary[stat].get(key) for stat in ("median", "min", "max")}
                    row["controllers"].setdefault(c, []).append(point)
            res[name] = row
    return {"robots": robots, "supplies": list(SUPPLIES), "low": LOW, "seeds": list(seeds), "quick": quick,
            "duration_s": QUICK_DURATION if quick else None, "scenarios": res, "cores": os.cpu_count(),
            "wall_s": time.perf_counter() - start}


def cell(p, coord) -> str:
    """``median [min-max]`` of one point's max error, ``fail`` when every seed failed, ``!`` when one did."""
    text = f"{p['median'][coord]:.3g} [{p['min'][coord]:.3g}-{p['max'][coord]:.3g}]" \
        if p["median"][coord] is not None else "fail"
    return text + ("!" if p["failed"] else "")


def supply_cell(p) -> str:
    """The lowest supply pressure (MPa, median [min-max]) and the median fraction of time starved."""
    s, f = p["ps_min_mpa"], p["ps_low_frac"]
    if s["median"] is None:
        return "-"
    return f"{s['median']:.3g} [{s['min']:.3g}-{s['max']:.3g}] MPa, {100 * f['median']:.0f} %"


def print_table(res):
    print(f"max tracking error (% of amplitude), median [min - max] over seeds {', '.join(map(str, res['seeds']))}; "
          f"lowest supply pressure and the time below {res['low']:g} x nominal")
    for name, row in res["scenarios"].items():
        print(f"\n{name} {row['scenario']}: {row['supply']} of {row['pump_l_min']:.0f} L/min; the reference asks up to "
              f"{row['demand_peak_l_min']:.0f} L/min, above the pump {100 * row['demand_over_frac']:.0f} % of the time")
        coords = row["coordinates"]
        print(f"{'controller':20} {'supply':10} " + " ".join(f"{c:>22}" for c in coords) + "  supply pressure")
        for c, points in row["controllers"].items():
            for p in points:
                print(f"{c:20} {p['supply']:10} " + " ".join(f"{cell(p, k):>22}" for k in coords)
                      + f"  {supply_cell(p)}")
    print("\n'!': a seed's run failed (diverged); the statistics are over the others")


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
