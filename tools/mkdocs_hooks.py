"""MkDocs hook: pages render tables from the code's own definitions, so they cannot go stale.

A page holds each such table between ``<!-- hydrogen:NAME -->`` and ``<!-- /hydrogen:NAME -->``:
``description-table`` is :func:`hydrogen.schema.description_table`, ``cli-reference`` is
:func:`hydrogen.cli.reference_markdown`. The committed page holds the rendered table too (readable
where the site is not built), ``python tools/render_pages.py`` renders it again, and
``tests/test_docs.py`` checks that the committed one is current; the site build renders it afresh.
"""
from __future__ import annotations

import importlib
import re

BLOCKS = {"description-table": "hydrogen.schema:description_table", "cli-reference": "hydrogen.cli:reference_markdown"}


def _render(name: str) -> str:
    module, func = BLOCKS[name].split(":")
    return getattr(importlib.import_module(module), func)()


def render_blocks(markdown: str) -> str:
    """``markdown`` with every block's content rendered again (a ValueError for an unclosed block)."""
    for name in BLOCKS:
        start, end = f"<!-- hydrogen:{name} -->", f"<!-- /hydrogen:{name} -->"
        if start not in markdown:
            continue
        if end not in markdown:
            raise ValueError(f"{start} has no {end} after it")
        pattern = re.compile(re.escape(start) + r".*?" + re.escape(end), re.DOTALL)
        markdown = pattern.sub(lambda _: f"{start}\n{_render(name).rstrip()}\n{end}", markdown)
    return markdown


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001 - MkDocs' hook signature
    return render_blocks(markdown)
