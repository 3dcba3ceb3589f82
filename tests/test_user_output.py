"""What a new user reads: no internal tracker numbers, per-coordinate units, estimates only of
controllers that adapt, a default scenario of the model's own, and progress on the long steps."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_no_output_names_an_internal_tracker_item():
    """Messages, templates, tests and benchmarks say what a thing is, never 'issue N'."""
    pattern = re.compile(r"issues? ?#?[0-9]", re.IGNORECASE)
    hits = []
    for folder in ("hydrogen", "tests", "benchmarks", "templates"):
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix not in (".py", ".j2", ".c", ".h", ".toml", ".txt", ".md") or not path.is_file():
                continue
            for no, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                if pattern.search(line) and path.name != Path(__file__).name:
                    hits.append(f"{path.relative_to(ROOT)}:{no}: {line.strip()}")
    assert not hits, "\n".join(hits)
