"""The documented search for the "well-tuned" P controller the paper compares against.

For each candidate gain K (one value for all legs) every experiment scenario is run
(in parallel, through :func:`hydrogen.sweep`). A gain is *stable* on a scenario when the
run does not diverge, the valves saturate in at most 1 % of the periods, and the error
in the coordinates the reference does not move stays within twice its value at the
smallest gain of the grid (the plain coupling floor) or 1 mm / 1 mrad, whichever is
larger: beyond that an off-axis oscillation has started. The P error only falls as K
grows, so the well-tuned gain is the largest gain stable on every scenario.
"""
from __future__ import annotations

import numpy as np

__all__ = ["tune_p", "P_SCENARIOS"]

#: scenario -> the coordinate its reference moves
P_SCENARIOS = {"z-1hz": "z", "z-2hz": "z", "psi-1hz": "psi"}


def tune_p(gains=None, scenarios=None, *, executor=None, max_workers=None, model=None,
           progress: bool = False) -> dict:
    """Run the sweep; return {"gains", "table": [...], "best": K, "best_errors": {scenario: %}}."""
    from .sweep import sweep

    gains = np.round(np.geomspace(0.01, 0.3, 25), 5) if gains is None else np.asarray(gains, float)
    gains = np.sort(gains)
    scenarios = dict(scenarios or P_SCENARIOS)
    runs = [dict(scenario=s, controller="p", gains={"Kleg": float(k)}) for s in scenarios for k in gains]
    out = iter(sweep(runs, executor=executor, max_workers=max_workers, model=model, progress=progress))
    table, stable = [], {}
    for s, coord in scenarios.items():
        floor = None
        for k in gains:
            m = next(out)
            row = {"scenario": s, "Kleg": float(k)}
            if "error" in m:
                row.update(stable=False, reason=m["error"])
            else:
                off = max(v for c, v in m["max_error"].items() if c != coord)
                floor = off if floor is None else floor
                ok_sat = m["u_saturation_frac"] <= 0.01
                ok_off = off <= max(2 * floor, 1e-3)
                row.update(max_error_pct=m["max_error_pct"][coord], off_axis_max=off,
                           saturation=m["u_saturation_frac"], stable=ok_sat and ok_off,
                           reason="" if ok_sat and ok_off else ("saturates" if not ok_sat else "off-axis oscillation"))
            table.append(row)
            stable.setdefault(float(k), []).append(row["stable"])
    ok = [k for k in map(float, gains) if all(stable[k])]
    best = max(ok) if ok else None
    best_errors = {r["scenario"]: r.get("max_error_pct") for r in table if r["Kleg"] == best}
    return {"gains": gains.tolist(), "table": table, "best": best, "best_errors": best_errors}
