"""Tracking error when the pump's flow runs out: the excavator arm and the loader crane on a pump of
their class instead of the shipped constant supply, each in a scenario whose motion asks for more oil
than the pump gives, every controller the robot lists, with the measured supply pressure and with the
same controller assuming a constant supply.

Each robot's description is copied to a temporary folder with a ``[supply]`` table (:data:`ROBOTS`:
its figures and their sources; what was chosen is said so) and one rig scenario (``rig = true``: the
robot's rig, sensors and delay) appended; the shipped descriptions are not changed. Three supplies:

* ``constant``: the copy without ``[supply]``: the shipped constant supply pressure, unlimited flow
  (the reference);
* ``measured``: the pump; the controllers read the measured supply pressure (``supply_feedback``
  true, the default);
* ``assumed``: the pump; the same controllers fed the description's ``supply_pressure`` instead
  (``supply_feedback`` false): a controller that assumes a constant supply.

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

#: Each robot: its pump (a ``[supply]`` table), the scenario in which the pump's flow runs out (a
#: ``[scenarios.<name>]`` table on the rig), and where the pump's figures come from.
ROBOTS = {
    "excavator_arm": {
        "scenario": "arm-flow",
        "supply": """
[supply]
# Caterpillar 320: main system maximum flow (implement) 429 L/min, two pumps of 214.5 L/min, taken as
# one pump-limited supply; main relief valve 35 000 kPa (= the maximum equipment pressure, normal mode).
# hose_volume chosen: two pump-to-valve lines of about 3 m of 1 1/4" hose and the valve's passages.
kind = "pump"
pump_flow = 7.15e-3                 # m^3/s (429 L/min)
relief_pressure = 35.0e6            # Pa
hose_volume = 5.0e-3                # m^3, chosen
""",
        "table": """
[scenarios.arm-flow]
rig = true
label = "arm-flow: boom and stick together, fast"
duration = 6.0
reference.sines = [["boom", -0.20, 0.25], ["stick", -0.35, 0.25]]
""",
        "sources": "Caterpillar 320 technical specifications (main system maximum flow, implement, 429 L/min = "
                   "2 x 214.5; maximum equipment pressure 35 000 kPa) and Cat service data for the 320 GC/320/323 "
                   "(main relief valve 35 000 kPa); hose volume chosen",
    },
    "loader_crane": {
        "scenario": "crane-flow",
        "supply": """
[supply]
# Chosen, not published (docs/loader_crane.md lists what was searched): a pressure-compensated
# piston pump of a 5 t m forestry / trailer crane's class, 80 L/min (a tractor-driven pump's upper
# end), holding the crane's working pressure of 24 MPa, its relief 2 MPa above; hose_volume chosen.
kind = "compensated_pump"
pump_flow = 1.3333e-3               # m^3/s (80 L/min), chosen
set_pressure = 24.0e6               # Pa: the description's supply_pressure
relief_pressure = 26.0e6            # Pa, chosen
hose_volume = 2.0e-3                # m^3, chosen
""",
        "table": """
[scenarios.crane-flow]
rig = true
label = "crane-flow: slew and lift together"
duration = 6.0
reference.sines = [["slew", 0.30, 0.25], ["slew", -0.15, 0.50], ["boom", 0.30, 0.25]]
""",
        "sources": "chosen: no published pump data of a crane of its class was found (docs/loader_crane.md); "
                   "an 80 L/min pressure-compensated pump at the crane's 24 MPa, relief 26 MPa, 2 L of hose",
    },
}


def _copy(name: str, folder: Path, pump: bool) -> Path:
    """Robot ``name``'s description copied into ``folder`` with its study scenario and, with ``pump``,
    its ``[supply]`` appended."""
    r = ROBOTS[name]
    return common.copy_description(name, folder, lambda text: text + r["table"] + (r["supply"] if pump else ""))


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
            moving = rig_scenarios(pumped)[sname]
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
