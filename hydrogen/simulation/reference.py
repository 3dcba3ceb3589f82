"""The reference kinds' former home: :mod:`hydrogen.references` holds them, one module each
(``MultiSine`` is :class:`hydrogen.references.sines.Reference`, ``Step`` :class:`hydrogen.references.step.Reference`)."""
from __future__ import annotations

from ..references.sines import MultiSine
from ..references.step import Step

__all__ = ["MultiSine", "Step"]
