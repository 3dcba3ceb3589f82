"""Where the C templates and the committed generated code are, in a checkout and in an installed wheel.

The repository keeps ``templates/`` and ``generated/`` at its top level. A wheel (and
``pip install .``) ships them inside the package as ``hydrogen/_templates`` and
``hydrogen/_generated`` (``setup.py`` maps the folders). The files are byte-identical in
both places, so the derivation hash and the generated manifests match either way.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["package_dir", "resource_dir", "templates_dir", "committed_generated_dir"]

_PACKAGE = Path(__file__).resolve().parent


def package_dir() -> Path:
    """The ``hydrogen`` package folder."""
    return _PACKAGE


def resource_dir(name: str) -> Path:
    """``hydrogen/_<name>`` when installed from a wheel, else ``<checkout>/<name>``.

    The in-package copy wins when it exists (an installed copy); a source checkout
    (editable install or ``PYTHONPATH``) has none and uses the top-level folder.
    """
    shipped = _PACKAGE / f"_{name}"
    return shipped if shipped.is_dir() else _PACKAGE.parent / name


def templates_dir() -> Path:
    """The C and build-file templates (``templates/``)."""
    return resource_dir("templates")


def committed_generated_dir() -> Path:
    """The committed generated code (``generated/``; may be missing)."""
    return resource_dir("generated")
