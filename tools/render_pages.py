"""Render the committed documentation pages from the committed data, with the same functions the runs
call at their end (hydrogen.pages): docs/figures/results.md (and each model's figure folder) from the
table and figures `hydrogen figures` wrote there, docs/benchmarks.md from docs/bench.json, and the
study tables of docs/paper.md and docs/guide/controllers.md from the studies' data files (each by its
script's own renderer, the one tests/test_docs.py checks the page against).

Run from the repository root: ``python tools/render_pages.py``.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import hydrogen
from hydrogen.fileio import atomic_write
from hydrogen.pages import figures_folder, write_benchmarks_page, write_results_page

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mkdocs_hooks import BLOCKS, render_blocks  # noqa: E402 - the hook beside this script

ROOT = Path(__file__).resolve().parents[1]
#: model -> the folder its `hydrogen figures --out` writes (each built-in model that has one)
FIGURES = {m: figures_folder(m) for m in hydrogen.models() if (ROOT / figures_folder(m) / "table.md").is_file()}


def splice(text: str, table: str) -> str:
    """``text`` with the block that starts with ``table``'s first line (a caption or a header row)
    replaced by ``table``: the block runs through its caption lines and its rows (lines starting with
    '|'). A ValueError unless that first line occurs exactly once."""
    lines, new = text.split("\n"), table.rstrip("\n").split("\n")
    at = [i for i, line in enumerate(lines) if line == new[0]]
    if len(at) != 1:
        raise ValueError(f"{len(at)} blocks start with {new[0][:60]!r}: expected one")
    end = at[0]
    while end < len(lines) and not lines[end].startswith("|"):
        end += 1
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    return "\n".join(lines[:at[0]] + new + lines[end:])


def study_tables() -> dict:
    """{page: [table]}: each study table a page shows, rendered from its committed data."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_delay
    import bench_sensitivity
    import estimates_elements
    import friction_compensation
    import margins_checking
    import rig_seeds
    import table_seeds

    def data(name):
        return json.loads((ROOT / "docs" / name).read_text(encoding="utf-8"))

    bench, fc = data("bench.json"), data("friction_compensation.json")
    rows_only = "\n".join(line for line in friction_compensation.markdown(fc["rows"], fc["seeds"]).splitlines()
                          if line.startswith("|"))  # the guide gives its own caption
    return {"docs/paper.md": [bench_delay.paper_markdown(bench["bench_delay"]),
                              bench_sensitivity.paper_markdown(bench["bench_sensitivity"]),
                              rig_seeds.timing_markdown(data("rig_seeds.json")),
                              margins_checking.markdown(data("margins_checking.json")),
                              table_seeds.markdown(data("table_seeds.json")),
                              estimates_elements.markdown(data("estimates_elements.json"))],
            "docs/guide/controllers.md": [rows_only]}


def main() -> None:
    for model, folder in FIGURES.items():
        print(write_results_page(hydrogen.load_model(model), ROOT / folder))
    print(write_benchmarks_page(Path("docs/bench.json") if Path.cwd() == ROOT else ROOT / "docs/bench.json"))
    for page, tables in study_tables().items():
        path = ROOT / page
        text = path.read_text(encoding="utf-8")
        for table in tables:
            text = splice(text, table)
        atomic_write(path, text)
        print(path)
    for path in block_pages():  # the tables rendered from the code's definitions (mkdocs_hooks.BLOCKS)
        text = path.read_text(encoding="utf-8")
        atomic_write(path, render_blocks(text))
        print(path)


def block_pages() -> list:
    """The documentation pages that hold a block of :data:`mkdocs_hooks.BLOCKS`."""
    marks = tuple(f"<!-- hydrogen:{name} -->" for name in BLOCKS)
    return [p for p in sorted((ROOT / "docs").rglob("*.md")) if any(m in p.read_text(encoding="utf-8") for m in marks)]


if __name__ == "__main__":
    main()
