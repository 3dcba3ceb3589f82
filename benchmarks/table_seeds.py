"""The comparison table's distributions over 50 seeds no search saw: for the default robot's rig
scenarios with a periodic reference (the Stewart platform's z-1hz, z-2hz, psi-1hz) at the table's
timing (the rig as described: a full-period computation delay), every controller it lists at the
gains the scenario runs with, the max tracking error (% of the reference amplitude) of the
coordinate the reference moves over seeds :data:`SEEDS` (100-149; the searches tune on 0-9): its
median, range, the worst seed and the number of seeds above 1.5 times the median (the tail).

Writes ``docs/table_seeds.json`` (atomically) and prints the table as Markdown (docs/paper.md holds
it as printed).

Run: ``python benchmarks/table_seeds.py [--workers W] [--variants low-latency predictor]`` (about a
minute on 2 cores, three with both variants): ``--variants`` adds the other timings' rows.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import hydrogen
from hydrogen.simulation.tuning import rig_scenarios

try:  # imported as benchmarks.<name>
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

REPO = common.REPO
#: The seeds the table's distributions are taken over: none of the tuning seeds 0..9.
SEEDS = list(range(100, 150))
#: A seed is in the tail when its max error exceeds the median by this factor.
TAIL = 1.5


def collect(seeds=SEEDS, workers: int = 2, variants=()) -> dict:
    """{"model", "seeds", "tail", "variants", "rows": [{scenario, coordinate, controller, median, min, max,
    worst_seed, tail_seeds, failed}], "wall_s"} (module doc); ``variants``: the description's variants
    (other timings) run too, each scenario as ``<scenario>.<variant>``."""
    start = time.perf_counter()
    model = hydrogen.load_model()
    variants = list(variants or ())
    cases = [(name, moving[0], c) for v in (None, *variants) for name, moving in rig_scenarios(model, v).items()
             for c in model.controllers]
    out = hydrogen.sweep([dict(scenario=s, controller=c) for s, _, c in cases], seeds=list(seeds),
                         max_workers=workers, model=model)
    rows = []
    for (scenario, coord, c), m in zip(cases, out):
        done = [(s, r["max_error_pct"][coord]) for s, r in zip(m["seeds"], m["per_seed"]) if "error" not in r]
        errs = np.array([e for _, e in done])
        med = float(np.median(errs)) if done else None
        rows.append({"scenario": scenario, "coordinate": coord, "controller": c, "median": med,
                     "min": float(errs.min()) if done else None, "max": float(errs.max()) if done else None,
                     "worst_seed": int(done[int(np.argmax(errs))][0]) if done else None,
                     "tail_seeds": [int(s) for s, e in done if e > TAIL * med] if done else [],
                     "failed": [int(s) for s in m.get("failed", [])]})
    return {"model": model.name, "seeds": list(seeds), "tail": TAIL, "variants": variants, "rows": rows,
            "wall_s": time.perf_counter() - start}


def markdown(data) -> str:
    """The docs' table: per controller and scenario, median [range], the worst seed, the tail."""
    s = data["seeds"]
    lines = [f"| controller | scenario | max error %, median [min - max] over seeds {s[0]}-{s[-1]} | worst seed | "
             f"seeds above {data['tail']:g} x the median |", "|---|---|---|---:|---|"]
    for r in sorted(data["rows"], key=lambda r: (r["controller"], r["scenario"])):
        if r["median"] is None:
            lines.append(f"| {r['controller']} | {r['scenario']} | every seed failed | - | - |")
            continue
        tail = ", ".join(map(str, r["tail_seeds"])) or "none"
        failed = f" ({len(r['failed'])} failed)" if r["failed"] else ""
        lines.append(f"| {r['controller']} | {r['scenario']} ({r['coordinate']}) | {r['median']:.1f} "
                     f"[{r['min']:.1f} - {r['max']:.1f}]{failed} | {r['worst_seed']} | {tail} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    return common.json_study_main(__doc__, collect, markdown, REPO / "docs" / "table_seeds.json", argv,
                                  {"--variants": dict(nargs="*", default=[], help="variants (timings) run too")})


if __name__ == "__main__":
    sys.exit(main())
