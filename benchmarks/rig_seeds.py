"""The rig results as distributions: for each shipped robot, rig scenario (and each of its
``[variants]``: ``<scenario>.<variant>``) and controller, at the gains the scenario runs with, the max tracking error (% of the reference amplitude) over noise seeds
0..N-1 (median, min, max, the median run's seed) and the stability margin of the main gain judged
over all of them (``hydrogen.simulation.tuning.margins``: stable only when every seed is), and
the adaptive controllers' final estimate errors (median over the seeds; estimates ending at a
projection bound named).

Writes ``docs/rig_seeds.json`` (atomically) and prints the table as Markdown.

Run: ``python benchmarks/rig_seeds.py [--seeds N] [--workers W] [--models M ...] [--controllers C ...]
[--json FILE]`` (about 10 minutes on 2 cores with the default 10 seeds); with ``--models`` or ``--controllers``
the file's rows this run does not redo (same seeds) are kept.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import hydrogen
from hydrogen.fileio import atomic_write
from hydrogen.simulation.scenarios import variant_names
from hydrogen.simulation.seeds import DEFAULT_SEEDS, parse_seeds, seed_list
from hydrogen.simulation.tuning import margins

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import merge_study  # noqa: E402  (run as a script from the repository root)

REPO = Path(__file__).resolve().parents[1]
#: The gain margin a controller should keep (6 dB), judged over every seed.
MARGIN_REQUIRED = 2.0


def collect(seeds, workers=None, models=None, controllers=None, variants=None) -> dict:
    """{"seeds", "margin_required", "models": {model: {"rows": [...], "wall_s"}}} (see the module doc);
    ``controllers``: a function of the Model giving the controllers to run (default: all it lists);
    ``variants``: the variants run besides the plain scenarios (default: every one of the model's)."""
    out = {"seeds": seed_list(seeds), "margin_required": MARGIN_REQUIRED, "models": {}}
    for name in models or hydrogen.models():
        start = time.perf_counter()
        rows = []
        model = hydrogen.load_model(name)
        for variant in (None, *(variant_names(model) if variants is None else variants)):
            pick = {} if controllers is None else {"controllers": controllers(model)}
            res = margins(model=name, seeds=seeds, max_workers=workers, variant=variant, **pick)
            rows += [{"scenario": r["scenario"], "controller": r["controller"], "main_gain": r["main_gain"],
                      "gain": r["gain"], "max_error_pct": r["errors"], "median_seed": r["median_seed"],
                      "margin": r["margin"], "margin_capped": r["margin_capped"],
                      "margin_ok": r["margin"] >= MARGIN_REQUIRED, "limit_reason": r["limit_reason"],
                      "unstable_seeds_at_limit": r["unstable_seeds"], "estimates": r.get("estimates")}
                     for r in res["rows"]]
        out["models"][name] = {"rows": rows, "wall_s": time.perf_counter() - start}
    return out


def markdown(data) -> str:
    """The page docs/rig_seeds.md: one row per robot, rig scenario and controller."""
    n = len(data["seeds"])
    lines = ["# The rig over noise seeds", "",
             "Written by `python benchmarks/rig_seeds.py` (from the data it writes, `docs/rig_seeds.json`). "
             "On the rig the adaptive runs are chaotic (a difference of 1e-15 in the noise grows to a different "
             "run within seconds), so a result is the median and range over seeds, and a gain is stable only "
             "if the stability judge passes on every seed.", "",
             f"Max tracking error (% of amplitude) at the stored gains over {n} noise seeds: median "
             f"[min - max]; margin of the main gain judged over all {n} seeds; the adaptive controllers' final "
             "estimate errors, the median over the seeds of the largest |θ̂ − θ|/|θ| and |γ̂ − γ|/γ (%), "
             "and the estimates that end a run at a projection bound.", "",
             "| robot | scenario | controller | max error % median [range] | median seed | margin | "
             f"margin >= {data['margin_required']:g} | limited by | estimates θ̃ / γ̃ % | at a bound |",
             "|---|---|---|---|---:|---:|---|---|---|---|"]
    for model, d in data["models"].items():
        for r in d["rows"]:
            err = ", ".join(f"{c} {e['median']:.1f} [{e['min']:.1f} - {e['max']:.1f}]"
                            for c, e in r["max_error_pct"].items()) or "-"
            m = f">= {r['margin']:.3g}" if r["margin_capped"] else f"{r['margin']:.3g}"
            est = r.get("estimates")
            e = f"{est['theta_error_pct']:.1f} / {est['gamma_error_pct']:.1f}" if est else "-"
            bound = (", ".join(est["at_bound"][:4]) + (f" (+{len(est['at_bound']) - 4})" if len(est["at_bound"]) > 4
                                                       else "") or "none") if est else "-"
            lines.append(f"| {model} | {r['scenario']} | {r['controller']} | {err} | {r['median_seed']} | {m} | "
                         f"{'yes' if r['margin_ok'] else 'no'} | {r['limit_reason'] or '-'} | {e} | {bound} |")
    return "\n".join(lines) + "\n"


def timing_markdown(data, model: str = "ubc_stewart", variants=("low-latency", "predictor")) -> str:
    """docs/paper.md's table of one robot's rig scenarios at each timing: per controller, the median
    [range] max error of each scenario's moving coordinate over the seeds and the margins, one column
    pair per variant, then the rig's own timing (the comparison table's)."""
    rows = {(r["scenario"], r["controller"]): r for r in data["models"][model]["rows"]}
    plain = list(dict.fromkeys(s for s, _ in rows if "." not in s))
    controllers = list(dict.fromkeys(c for _, c in rows))
    timings = [*(f".{v}" for v in variants), ""]

    def cells(c, t):
        got = [rows.get((s + t, c)) for s in plain]
        if any(r is None for r in got):
            return "-", "-"
        err = " / ".join(", ".join(f"{e['median']:.1f} [{e['min']:.1f}-{e['max']:.1f}]" for e in r["max_error_pct"].values())
                         for r in got)
        mar = " / ".join((f"≥ {r['margin']:.3g}" if r["margin_capped"] else f"{r['margin']:.3g}") for r in got)
        return err, mar

    head = " | ".join(f"`{t}` | margins" if t else "the table | margins" for t in timings)
    lines = [f"| controller | {head} |", "|---|" + "---|" * (2 * len(timings))]
    for c in controllers:
        lines.append(f"| {c} | " + " | ".join(" | ".join(cells(c, t)) for t in timings) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=parse_seeds, default=DEFAULT_SEEDS, help=f"N or a list (default {DEFAULT_SEEDS})")
    ap.add_argument("--workers", type=int, help="processes (default: the core count)")
    ap.add_argument("--models", nargs="+", help="only these robots; the file's other rows (same seeds) are kept")
    ap.add_argument("--controllers", nargs="+", help="only these controllers (of those each robot lists); the "
                    "file's other rows (same seeds) are kept")
    ap.add_argument("--json", default=str(REPO / "docs" / "rig_seeds.json"),
                    help="output (default docs/rig_seeds.json)")
    args = ap.parse_args(argv)
    pick = None if not args.controllers else (lambda m: tuple(c for c in m.controllers if c in args.controllers))
    data = collect(args.seeds, args.workers, models=args.models, controllers=pick)
    path = Path(args.json)
    if (args.models or args.controllers) and path.exists():
        data = merge_study(json.loads(path.read_text()), data)
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    data = json.loads(text)  # the page from the data as written (sorted keys), as its test renders it
    atomic_write(Path(args.json), text)
    page = Path(args.json).with_suffix(".md")
    atomic_write(page, markdown(data))
    print(markdown(data))
    print(f"written to {args.json} and {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
