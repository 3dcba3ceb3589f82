"""Where the adaptive controllers' estimates end, one rig element switched at a time: the evidence for
what docs/paper.md says of the estimates.

The default robot's rig scenarios with a periodic reference (the Stewart platform's z-1hz, z-2hz,
psi-1hz), each adaptive controller it lists at the gains the scenario runs with, over noise seeds
:data:`SEEDS` (not the tuning seeds 0-9), on the rig as described and with one element changed at a
time (:data:`ELEMENTS`): no friction, an ideal valve, no sensor noise or resolution, a near-zero
computation latency; and with all of those at once. For each: the final estimate of every
parameter as a multiple of its true value (median over the seeds), the hydraulic estimates'
largest error, and the estimates that end a run at a projection bound (with the seeds' count).

Writes ``docs/estimates_elements.json`` (atomically) and prints the table as Markdown (docs/paper.md
holds it as printed).

Run: ``python benchmarks/estimates_elements.py [--workers W]`` (a minute or two on 2 cores).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import hydrogen
from hydrogen.simulation.checks import adapts
from hydrogen.simulation.tuning import AT_BOUND, rig_scenarios

try:  # imported as benchmarks.<name>
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

REPO = common.REPO
SEEDS = list(range(100, 110))
#: Each configuration: its label and the scenario fields it changes from the rig.
ELEMENTS = {
    "rig": {},
    "no friction": {"friction": [0.0, 0.0, 1e-3]},
    "ideal valve": {"valve_bandwidth_hz": 0.0, "valve_lag": 0.0},
    "no noise": {"noise_l": 0.0, "noise_p": 0.0, "quantization_l": 0.0},
    "low latency": {"delay": 5e-6},
    "all four off": {"friction": [0.0, 0.0, 1e-3], "valve_bandwidth_hz": 0.0, "valve_lag": 0.0, "noise_l": 0.0,
                     "noise_p": 0.0, "quantization_l": 0.0, "delay": 5e-6},
}


def _row(model, scenario, controller, element, m) -> dict:
    done = [r for r in m["per_seed"] if "error" not in r]
    names = list(done[0]["theta_names"]) if done else []
    theta = np.array([np.divide(r["theta_hat_final"], r["theta_true"], out=np.full(len(names), np.nan),
                                where=np.asarray(r["theta_true"]) != 0) for r in done])
    gamma = np.array([np.asarray(r["gamma_hat_final"]) / np.asarray(r["gamma_true"]) for r in done])
    at = {}
    for r in done:
        bounds = list(zip(names, r["theta_hat_final"], model.theta_min, model.theta_max))
        for k, (lo, hi) in enumerate([(model.gamma1_min, model.gamma1_max), (model.gamma2_min, model.gamma2_max)]):
            bounds += [(f"gamma{k + 1}", v, lo, hi) for v in r["gamma_hat_final"][k]]
        for name in {n for n, v, lo, hi in bounds if min(v - lo, hi - v) <= AT_BOUND * (hi - lo)}:
            at[name] = at.get(name, 0) + 1
    return {"scenario": scenario, "controller": controller, "element": element, "completed": len(done),
            "theta_ratio": {n: (None if np.isnan(v) else float(v)) for n, v in
                            zip(names, np.nanmedian(theta, axis=0) if done else [])},
            "gamma_error_pct": float(np.median(np.max(np.abs(gamma - 1), axis=(1, 2))) * 100) if done else None,
            "at_bound": dict(sorted(at.items()))}


def collect(seeds=SEEDS, workers: int = 2) -> dict:
    """{"model", "seeds", "elements", "rows": [...], "wall_s"} (module doc)."""
    start = time.perf_counter()
    model = hydrogen.load_model()
    cases = [(s, c, e) for s in rig_scenarios(model) for c in model.controllers if adapts(c, model)
             for e in ELEMENTS]
    out = hydrogen.sweep([dict(scenario=s, controller=c, **ELEMENTS[e]) for s, c, e in cases], seeds=list(seeds),
                         max_workers=workers, model=model)
    return {"model": model.name, "seeds": list(seeds), "elements": ELEMENTS,
            "rows": [_row(model, s, c, e, m) for (s, c, e), m in zip(cases, out)],
            "wall_s": time.perf_counter() - start}


def markdown(data) -> str:
    """The docs' table: per controller, scenario and configuration, each θ̂/θ, γ̃ and what ends at a bound."""
    n = len(data["seeds"])
    names = list(data["rows"][0]["theta_ratio"])
    lines = ["| controller | scenario | rig elements | " + " | ".join(f"{k} θ̂/θ" for k in names)
             + " | γ̃ % | at a bound (seeds of " + str(n) + ") |", "|---|---|---|" + "---:|" * (len(names) + 1) + "---|"]
    for r in data["rows"]:
        ratios = " | ".join("-" if r["theta_ratio"].get(k) is None else f"{r['theta_ratio'][k]:.2f}" for k in names)
        at = ", ".join(f"{k} ({v})" for k, v in r["at_bound"].items()) or "none"
        g = "-" if r["gamma_error_pct"] is None else f"{r['gamma_error_pct']:.0f}"
        lines.append(f"| {r['controller']} | {r['scenario']} | {r['element']} | {ratios} | {g} | {at} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    return common.json_study_main(__doc__, collect, markdown, REPO / "docs" / "estimates_elements.json", argv)


if __name__ == "__main__":
    sys.exit(main())
