"""The gain margins checked on seeds the tuning never saw: for each shipped robot, each nonlinear
controller it lists (those not ``compared``: the fixed-gain P controllers are not claimed a margin)
and each rig scenario (and the variants asked for), the margin of the main gain at the robot's
gains, judged over the checking seeds 100..119 (the searches tune on seeds 0..9) by the stability
judge of ``hydrogen.simulation.tuning`` (its 4 s average and its worst short window: bursts).

Writes ``docs/margins_checking.json`` (atomically) and prints the table as Markdown; ``--update``
keeps the rows of the file already there that this run does not redo (e.g. a variant run later).

Run: ``python benchmarks/margins_checking.py [--models M ...] [--variants V ...] [--workers W]``
(about 10 minutes for the three robots' plain rig scenarios on 2 cores).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import hydrogen
from hydrogen.controllers import spec
from hydrogen.fileio import atomic_write
from hydrogen.simulation.seeds import parse_seeds

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import merge_study  # noqa: E402
from rig_seeds import collect  # noqa: E402  (a sibling script: the same rows)

REPO = Path(__file__).resolve().parents[1]
#: The seeds every claimed margin is checked on: none of the tuning seeds 0..9.
CHECKING_SEEDS = list(range(100, 120))


def nonlinear(model) -> tuple:
    """The controllers of ``model`` a margin is claimed for: all it lists but the compared P ones."""
    return tuple(c for c in model.controllers if not spec(c).compared)


def markdown(data) -> str:
    """The table of the docs: robot, controller, scenario, margin, whether it holds, why it ends."""
    lines = [f"| robot | controller | scenario | margin on seeds {data['seeds'][0]}-{data['seeds'][-1]} | "
             f">= {data['margin_required']:g} | limited by | unstable seeds at the limit |",
             "|---|---|---|---:|---|---|---|"]
    for model, d in data["models"].items():
        for r in sorted(d["rows"], key=lambda r: (r["controller"], r["scenario"])):
            m = f">= {r['margin']:.3g}" if r["margin_capped"] else f"{r['margin']:.3g}"
            seeds = ", ".join(map(str, r["unstable_seeds_at_limit"])) or "-"
            lines.append(f"| {model} | {r['controller']} | {r['scenario']} | {m} | "
                         f"{'yes' if r['margin_ok'] else '**no**'} | {r['limit_reason'] or '-'} | {seeds} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=parse_seeds, default=CHECKING_SEEDS, help="N or a list (default 100..119)")
    ap.add_argument("--models", nargs="+", help="robots (default: every shipped one)")
    ap.add_argument("--variants", nargs="*", default=[], help="variants run besides the plain scenarios (default none)")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--controllers", nargs="+", help="only these of the nonlinear controllers")
    ap.add_argument("--update", action="store_true", help="keep the rows of the file this run does not redo")
    ap.add_argument("--json", default=str(REPO / "docs" / "margins_checking.json"),
                    help="output (default docs/margins_checking.json)")
    args = ap.parse_args(argv)
    pick = nonlinear if not args.controllers else (lambda m: tuple(c for c in nonlinear(m) if c in args.controllers))
    data = collect(args.seeds, args.workers, args.models or hydrogen.models(), pick, args.variants)
    path = Path(args.json)
    if args.update and path.exists():
        data = merge_study(json.loads(path.read_text()), data)
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    atomic_write(path, text)
    print(markdown(json.loads(text)))
    print(f"written to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
