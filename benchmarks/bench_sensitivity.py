"""Tracking error against the rig's friction level and valve bandwidth: how much of each controller's
error the plant's unmodelled parts cause.

The default robot's rig scenarios with a periodic reference (``rig = true``; the Stewart platform's
z-1hz, z-2hz, psi-1hz), every controller it lists with the description's gains at the rig, over
noise seeds :data:`SEEDS` (not the seeds 0-9 the gains were tuned on), varying one rig element at a
time from the rig as described:

* ``friction``: each actuator's friction as the rig applies it (its description's seal table, else the
  rig's setting) with its force levels (Coulomb, breakaway, viscous, pressure coefficient; the speeds
  kept) times each of :data:`FRICTION_SCALES` (1: the rig's; 0: none);
* ``valve``: the servo-valve's natural frequency (``valve_bandwidth_hz``, and each datasheet valve's
  ``actuators.<name>.valve.bandwidth_hz``: the spool lagging 90° there; damping as described) at
  each of :data:`BANDWIDTHS` Hz (the rig's among them), with the plant's sub-steps raised where a valve
  faster than the rig's needs more than the scenario's to be resolved (:func:`resolving_substeps`).

No controller models either (the paper's ideal valve, no friction), unless a description turns
friction compensation on. Reported: the max tracking error (% of the reference amplitude) of the
coordinate the reference moves, median, min and max over the seeds; a failed (diverged) run is
counted in ``failed`` and left out of the statistics. Writes the figure :data:`FIGURE`.

Run: ``python benchmarks/bench_sensitivity.py [--quick] [--json FILE]`` (a few minutes on 2 cores;
``--quick``: the first scenario, two values of each element, two seeds, 3 s runs, no figure).
"""
from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

import hydrogen
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.tuning import rig_scenarios

try:  # imported as benchmarks.bench_sensitivity
    from . import common
    from .bench_delay import _gains_used
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common
    from bench_delay import _gains_used

#: Multiples of the rig's friction (the force levels of every actuator's).
FRICTION_SCALES, QUICK_FRICTION_SCALES = (0.0, 0.5, 1.0, 1.5, 2.0), (0.0, 1.0)
#: Servo-valve natural frequencies, Hz.
BANDWIDTHS, QUICK_BANDWIDTHS = (20.0, 40.0, 80.0, 160.0, 320.0), (40.0, 80.0)
SEEDS, QUICK_SEEDS = (100, 101, 102, 103, 104), (100, 101)
QUICK_DURATION = 3.0  # s: past the rig's metric_start (2 s)
FIGURE = common.REPO / "docs" / "sensitivity.png"
#: Each element: (its label, the axis title, the values, the scenario fields a value sets).
ELEMENTS = {
    "friction": ("friction (x the rig's)", lambda sc, s, model: scaled_friction(sc, model, s)),
    "valve": ("valve natural frequency (Hz)", lambda sc, f, model: {
        "valve_bandwidth_hz": f,  # the rig's; an actuator's datasheet valve is set by its own response
        "actuators": {c.name: {"valve": {"bandwidth_hz": f}} for c in model.cylinders if c.valve is not None},
        "substeps": resolving_substeps(sc, f)}),
}


def resolving_substeps(sc, f: float) -> int:
    """The scenario's sub-steps, or the fewest that resolve a valve of natural frequency ``f`` Hz where it
    asks more (the scenario check's bound: 2 pi f h / substeps <= 1): a faster valve than the rig's must
    not be refused for the rig's cheaper integration."""
    return max(sc.substeps, math.ceil(2 * math.pi * f / sc.control_rate))
#: The friction row's force levels (hydrogen.plant.friction.PARAMETERS), scaled by a friction multiple.
LEVELS = ("coulomb", "breakaway", "viscous", "pressure_coefficient")


def scaled_friction(sc, model, scale: float) -> dict:
    """The scenario fields giving every actuator of ``model`` ``scale`` times the friction force levels
    it has in scenario ``sc`` (its description's seal table, else the rig's setting, key by key): each
    actuator's own table, with only the keys of the terms its plant is built with; 0: no friction."""
    from hydrogen.plant import friction
    from hydrogen.simulation.scenarios import actuator_settings

    if scale == 0.0:
        return {"friction": [0.0, 0.0, sc.friction[2]]}
    names = [p.name for p in friction.PARAMETERS]
    rows = actuator_settings(sc, model)["friction"]
    out = {}
    for c, row in zip(model.cylinders, rows):
        values = dict(zip(names, (float(v) for v in row)))
        stribeck, pressure = c.seal_terms
        keys = [k for k in LEVELS if k in ("coulomb", "viscous") or (k == "breakaway" and stribeck)
                or (k == "pressure_coefficient" and pressure)]
        out[c.name] = {"friction": {k: values[k] * scale for k in keys}}
    return {"actuators": out}


def run(quick: bool = False) -> dict:
    start = time.perf_counter()
    model = hydrogen.load_model()
    dyn = hydrogen.build(model)
    names = list(rig_scenarios(model))[:1 if quick else None]
    values = {"friction": QUICK_FRICTION_SCALES if quick else FRICTION_SCALES,
              "valve": QUICK_BANDWIDTHS if quick else BANDWIDTHS}
    seeds = QUICK_SEEDS if quick else SEEDS
    cases, entries = [], []
    for name in names:
        sc = named_scenario(name, model)
        for c in model.controllers:
            for element, (_, fields) in ELEMENTS.items():
                for v in values[element]:
                    cases.append((name, c, element, v))
                    entries.append(dict(scenario=name, controller=c, **fields(sc, v, model),
                                        **({"duration": QUICK_DURATION} if quick else {})))
    out = hydrogen.sweep(entries, seeds=list(seeds), max_workers=min(2, os.cpu_count() or 1), model=model)
    res = {}
    for (name, c, element, v), m in zip(cases, out):
        sc = named_scenario(name, model)
        moving = rig_scenarios(model)[name]
        row = res.setdefault(name, {"scenario": name, "coordinates": list(moving), "controllers": {},
                                    "rig": {"friction": list(sc.friction), "valve": sc.valve_bandwidth_hz}})
        ctrl = row["controllers"].setdefault(c, {"gains": _gains_used(dyn, c, name, model)})
        ctrl.setdefault(element, []).append(common.spread_point(m, moving, value=v))
    out = common.study_result(model, seeds, quick, QUICK_DURATION, res, FIGURE, start,
                              values={k: list(v) for k, v in values.items()})
    if not quick:
        figure(out)
    return out


def figure(res, path=FIGURE):
    """Max error against each element, a row of panels per element and a column per scenario, one line
    (median) and band (min-max) per controller; written atomically as PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(res["scenarios"].values())
    fig, axes = plt.subplots(len(ELEMENTS), len(rows), figsize=(5 * len(rows), 4.2 * len(ELEMENTS)), squeeze=False)
    colour = {c: f"C{i}" for i, c in enumerate(rows[0]["controllers"])}
    for r, (element, (title, _)) in enumerate(ELEMENTS.items()):
        for ax, row in zip(axes[r], rows):
            coord = row["coordinates"][0]
            for c, e in row["controllers"].items():
                common.spread_line(ax, [p["value"] for p in e[element]], e[element], coord, colour[c], c)
            ax.axvline(1.0 if element == "friction" else row["rig"]["valve"], color="k", lw=0.6, ls=":")
            if element == "valve":
                ax.set_xscale("log")
            common.error_axes(ax, coord, row["scenario"], title)
    return common.save_figure(fig, axes, path, f"{res['model']}: tracking error against the rig's friction and valve "
                              f"bandwidth, seeds {', '.join(map(str, res['seeds']))} (median, min-max band; dotted: "
                              "the rig's)", 5, 0.05)


def cell(p, coord) -> str:
    """``median [min-max]`` of one point, ``fail`` when every seed failed, ``!`` when one did."""
    text = f"{p['median'][coord]:.3g} [{p['min'][coord]:.3g}-{p['max'][coord]:.3g}]" \
        if p["median"][coord] is not None else "fail"
    return text + ("!" if p["failed"] else "")


#: The columns of docs/paper.md's table: (element, value; None: the rig's own).
PAPER_COLUMNS = (("friction", 0.0), ("friction", 1.0), ("friction", 2.0), ("valve", 40.0), ("valve", None),
                 ("valve", 320.0))


def column_title(element, value, rig) -> str:
    if element == "friction":
        return {0.0: "no friction", 1.0: "the rig's", 2.0: "twice the rig's"}.get(value, f"{value:g} x the rig's")
    return f"the rig's {rig:g} Hz" if value == rig else f"valve {value:g} Hz"


def paper_markdown(res, columns=PAPER_COLUMNS) -> str:
    """The table of docs/paper.md: per controller, the median max error (%) of every rig scenario at
    each column's friction multiple or valve natural frequency."""
    rows = list(res["scenarios"].values())
    rig = rows[0]["rig"]["valve"]
    cols = [(e, rig if v is None and e == "valve" else v) for e, v in columns]
    out = ["Median max error, %, " + " / ".join(r["scenario"] for r in rows) + ":", "",
           "| controller | " + " | ".join(column_title(e, v, rig) for e, v in cols) + " |",
           "|---|" + "---|" * len(cols)]
    missing = [f"{e} {v:g}" for e, v in cols if v not in res["values"][e]]
    if missing:
        raise ValueError(f"the study ran no {', '.join(missing)}")
    for c in rows[0]["controllers"]:
        cells = []
        for e, v in cols:
            points = {r["scenario"]: next(p for p in r["controllers"][c][e] if p["value"] == v) for r in rows}
            cells.append(common.medians_cell(points, [(r["scenario"], r["coordinates"][0]) for r in rows]))
        out.append(f"| {c} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def print_table(res):
    print(f"{res['model']}: max tracking error (% of amplitude), median [min - max] over seeds "
          f"{', '.join(map(str, res['seeds']))}, one rig element varied at a time")
    for row in res["scenarios"].values():
        coord = row["coordinates"][0]
        for element, (title, _) in ELEMENTS.items():
            vals = res["values"][element]
            print(f"\n{row['scenario']} ({coord}), {title}")
            print(f"{'controller':20} " + " ".join(f"{v:>18g}" for v in vals))
            for c, e in row["controllers"].items():
                print(f"{c:20} " + " ".join(f"{cell(p, coord):>18}" for p in e[element]))
    if res.get("figure"):
        print(f"\nfigure: {res['figure']}")
    print("\n'!': a seed's run failed (diverged) there; the statistics are over the others")
    if not res["quick"]:  # a quick run has not the paper's columns
        print("\n" + paper_markdown(res))


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
