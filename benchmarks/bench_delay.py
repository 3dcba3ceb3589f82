"""Tracking error against the computation delay: the default robot's rig scenarios with a periodic
reference (``rig = true``; the Stewart platform's z-1hz, z-2hz, psi-1hz), every controller it lists,
the command applied a fraction :data:`FRACTIONS` of a control period after its measurement (the
scenario's ``delay``; 1 is the rig's one full period, 5 us the ``low-latency`` variant), over noise
seeds :data:`SEEDS` (not the seeds 0-9 the gains were tuned on).

The paper states no computation delay; this shows what the choice costs. Each controller runs with
the gains the description gives it at the rig (``[gains]`` under the scenario's own) and, where the
:data:`VARIANT` variant gives it other gains, with those too (``<scenario>.<variant>`` with the same
delays): which gains each row uses is in the results (``gains``: their source and main gain).
Reported: the max tracking error (% of the reference amplitude) of the coordinate the reference
moves, median, min and max over the seeds; a run that fails (diverges) is counted in ``failed`` and
left out of the statistics. Writes the figure :data:`FIGURE` (median line, min-max band).

Run: ``python benchmarks/bench_delay.py [--quick] [--json FILE]`` (about a minute on 2 cores;
``--quick``: the first scenario, three delays, two seeds, 3 s runs, no figure).
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

import hydrogen
from hydrogen.controllers import spec as controller_spec
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.tuning import main_gain, rig_scenarios

try:  # imported as benchmarks.bench_delay
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

#: Delays, in control periods (0: applied at the measurement; 1: the rig's full period).
FRACTIONS, QUICK_FRACTIONS = (0.0, 0.125, 0.25, 0.5, 0.75, 1.0), (0.0, 0.5, 1.0)
SEEDS, QUICK_SEEDS = (100, 101, 102, 103, 104), (100, 101)
#: The variant whose gains run beside the rig's (where it gives a controller its own).
VARIANT = "low-latency"
QUICK_DURATION = 3.0  # s: past the rig's metric_start (2 s)
FIGURE = common.REPO / "docs" / "delay.png"


def gain_sets(model, name: str) -> dict:
    """{controller: {label: scenario name}}: the rig's gains (``name``) and, where the variant gives
    the controller gains of its own, the variant's (``name.variant``)."""
    own = (model.variants.get(VARIANT) or {}).get("gains", {})
    return {c: {"rig": name, **({VARIANT: f"{name}.{VARIANT}"} if c in own else {})} for c in model.controllers}


def _gains_used(dyn, controller, name, model) -> dict:
    from hydrogen.simulation.tuning import _own_gains
    g = main_gain(controller)
    values = np.atleast_1d(np.asarray(_own_gains(dyn, controller, name, model)[g], float))
    # per_axis: the main gain differs between coordinates (p-task's Kq), so "value" is their mean
    return {"scenario": name, "main_gain": g, "value": float(np.mean(values)),
            "per_axis": bool(np.ptp(values) > 0)}


def run(quick: bool = False) -> dict:
    start = time.perf_counter()
    model = hydrogen.load_model()
    dyn = hydrogen.build(model)
    names = list(rig_scenarios(model))[:1 if quick else None]
    fractions, seeds = (QUICK_FRACTIONS, QUICK_SEEDS) if quick else (FRACTIONS, SEEDS)
    cases, entries = [], []
    for name in names:
        moving = rig_scenarios(model)[name]
        period = 1.0 / named_scenario(name, model).control_rate
        for c, sets in gain_sets(model, name).items():
            for label, sname in sets.items():
                for f in fractions:
                    cases.append((name, moving, c, label, sname, f))
                    entries.append(dict(scenario=sname, controller=c, delay=f * period,
                                        **({"duration": QUICK_DURATION} if quick else {})))
    out = hydrogen.sweep(entries, seeds=list(seeds), max_workers=min(2, os.cpu_count() or 1), model=model)
    res = {}
    for (name, moving, c, label, sname, f), m in zip(cases, out):
        row = res.setdefault(name, {"scenario": name, "coordinates": list(moving), "controllers": {},
                                    "period_s": 1.0 / named_scenario(name, model).control_rate})
        ctrl = row["controllers"].setdefault(c, {})
        entry = ctrl.setdefault(label, {"gains": _gains_used(dyn, c, sname, model), "delays": []})
        entry["delays"].append(common.spread_point(m, moving, periods=f,
                                                   delay_s=f / named_scenario(sname, model).control_rate))
    out = common.study_result(model, seeds, quick, QUICK_DURATION, res, FIGURE, start, variant=VARIANT,
                              fractions=list(fractions))
    if not quick:
        figure(out)
    return out


def figure(res, path=FIGURE):
    """Max error against delay, one panel per scenario, one line (median) and band (min-max) per
    controller and gain set; written atomically as PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(res["scenarios"].values())
    fig, axes = plt.subplots(1, len(rows), figsize=(5 * len(rows), 4.8), squeeze=False)
    colour = {c: f"C{i}" for i, c in enumerate(rows[0]["controllers"])}  # one per controller, both gain sets
    for ax, row in zip(axes[0], rows):
        coord = row["coordinates"][0]
        for c, sets in row["controllers"].items():
            for label, e in sets.items():
                common.spread_line(ax, [p["periods"] for p in e["delays"]], e["delays"], coord, colour[c],
                                   c if label == "rig" else f"{c} ({label} gains)", "o-" if label == "rig" else "s--")
        common.error_axes(ax, coord, row["scenario"],
                          f"computation delay (control periods, 1 = {row['period_s'] * 1e3:.3g} ms)")
    return common.save_figure(fig, axes, path, f"{res['model']}: tracking error against computation delay, seeds "
                              f"{', '.join(map(str, res['seeds']))} (median, min-max band)", 4, 0.12)


#: The delays (periods) docs/paper.md's table shows.
PAPER_FRACTIONS = (0.0, 0.25, 0.5, 1.0)


def paper_markdown(res, fractions=PAPER_FRACTIONS) -> str:
    """The table of docs/paper.md: per controller and gain set, the median max error (%) at each of
    ``fractions`` of a period (each among the run's), one column per rig scenario; a cell where seeds
    diverged says how many runs did."""
    rows = list(res["scenarios"].values())
    head = " / ".join(common.fraction_text(f) for f in fractions)
    out = [f"Median max error, %, at {head} period:", "",
           "| controller (gains) | " + " | ".join(r["scenario"] for r in rows) + " |",
           "|---|" + "---|" * len(rows)]
    missing = sorted(set(fractions) - set(res["fractions"]))
    if missing:
        raise ValueError(f"the study ran no delay of {', '.join(map(common.fraction_text, missing))} period")
    first = rows[0]["controllers"]
    for c, sets in first.items():
        for label in sets:
            g = sets[label]["gains"]
            cells = []
            for r in rows:
                at = {p["periods"]: p for p in r["controllers"][c][label]["delays"]}
                cells.append(common.medians_cell({f: at[f] for f in fractions},
                                                 [(f, r["coordinates"][0]) for f in fractions]))
            spec = controller_spec(c)  # the controller's own symbol for its main gain
            name = spec.main_gain_label if g["main_gain"] == spec.main_gain else g["main_gain"]
            name = f"mean {name}" if g.get("per_axis") else name
            out.append(f"| {c} ({label}, {name} = {g['value']:.3g}) | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def print_table(res):
    fr = res["fractions"]
    print(f"{res['model']}: max tracking error (% of amplitude), median [min - max] over seeds "
          f"{', '.join(map(str, res['seeds']))}, at computation delays of {', '.join(f'{f:g}' for f in fr)} periods")
    for row in res["scenarios"].values():
        coord = row["coordinates"][0]
        print(f"\n{row['scenario']} ({coord})")
        print(f"{'controller':20} {'gains':12} {'main gain':>16} " + " ".join(f"{f:>18g}" for f in fr))
        for c, sets in row["controllers"].items():
            for label, e in sets.items():
                g = e["gains"]
                cells = [(f"{p['median'][coord]:.3g} [{p['min'][coord]:.3g}-{p['max'][coord]:.3g}]"
                          if p["median"][coord] is not None else "fail") + ("!" * (p["failed"] > 0))
                         for p in e["delays"]]
                print(f"{c:20} {label:12} {g['main_gain'] + ' ' + format(g['value'], '.4g'):>16} "
                      + " ".join(f"{x:>18}" for x in cells))
    if res.get("figure"):
        print(f"\nfigure: {res['figure']}")
    print("\n'!': a seed's run failed (diverged) at that delay; the statistics are over the others")
    if not res["quick"]:  # a quick run has not the paper's delays
        print("\n" + paper_markdown(res))


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
