"""Render the committed documentation pages from the committed data, with the same functions the runs
call at their end (hydrogen.pages): docs/figures/results.md (and each model's figure folder) from the
table and figures `hydrogen figures` wrote there, docs/benchmarks.md from docs/bench.json.

Run from the repository root: ``python tools/render_pages.py``.
"""
from __future__ import annotations

from pathlib import Path

import hydrogen
from hydrogen.pages import figures_folder, write_benchmarks_page, write_results_page

ROOT = Path(__file__).resolve().parents[1]
#: model -> the folder its `hydrogen figures --out` writes (each built-in model that has one)
FIGURES = {m: figures_folder(m) for m in hydrogen.models() if (ROOT / figures_folder(m) / "table.md").is_file()}


def main() -> None:
    for model, folder in FIGURES.items():
        print(write_results_page(hydrogen.load_model(model), ROOT / folder))
    print(write_benchmarks_page(Path("docs/bench.json") if Path.cwd() == ROOT else ROOT / "docs/bench.json"))


if __name__ == "__main__":
    main()
