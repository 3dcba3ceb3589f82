"""MkDocs hook: pages render tables from the code's own definitions, so they cannot go stale.

``<!-- hydrogen:description-table -->`` becomes :func:`hydrogen.schema.description_table`.
"""
from __future__ import annotations

MARKERS = {"<!-- hydrogen:description-table -->": "hydrogen.schema:description_table"}


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001 - MkDocs' hook signature
    import importlib

    for marker, target in MARKERS.items():
        if marker in markdown:
            module, func = target.split(":")
            markdown = markdown.replace(marker, getattr(importlib.import_module(module), func)())
    return markdown
