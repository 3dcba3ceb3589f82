"""A scenario setting's declaration (plain data): a number or switch that a description's
``[scenarios.<name>]``, ``[rig]`` or ``[variants.<name>]`` table may set, declared once by the part of
the loop that reads it (a plant block such as :mod:`hydrogen.plant.valve`, an estimator, or the
loop's own parts in :mod:`hydrogen.scenario_settings`), which assembles them into the scenario's
fields.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import field

import numpy as np

__all__ = ["setting", "failed_check", "words", "WORDS", "is_number"]


def is_number(value) -> bool:
    """Whether ``value`` is a real number (Python's or numpy's), not a bool: what a number given in
    Python (a setting, a gain, an option) may be before its range is checked."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def setting(default, unit: str, meaning: str, check: str | None = None, default_text: str | None = None,
            entries: bool = False):
    """A scenario setting: its default (None: required), unit and meaning (the description table's row,
    rendered by :func:`hydrogen.schema.description_table`) and its check: ``"number"`` a finite number,
    ``">=0"`` also not negative, ``">0"`` also above 0 (None: checked by
    :meth:`hydrogen.simulation.scenarios.Scenario.validated` itself). ``entries``: the value may also be
    a list, one number per entry of what it sets (a plant part's start per actuator,
    :attr:`hydrogen.plant.PlantState.initial`), each held to the check; the reader checks the count. A
    :class:`dataclasses.Field` of the scenario's fields (mutable defaults as given: the settings hold
    numbers, strings and tuples)."""
    meta = {"unit": unit, "meaning": meaning, "check": check, "default_text": default_text, "entries": entries}
    return field(metadata=meta) if default is None else field(default=default, metadata=meta)


def failed_check(decl, value) -> str | None:
    """The declared check of setting ``decl`` (a field made by :func:`setting`) that ``value`` fails:
    ``"number"`` (not a finite real number; a bool is not one), ``">=0"`` (a finite number below 0),
    ``">0"`` (a finite number not above 0), or None (it passes, or the setting declares no check). Each
    caller words the failure its own way (:data:`WORDS`, :func:`words`). A setting of ``entries`` may be
    a non-empty list, each entry held to the check."""
    check = decl.metadata.get("check")
    if check is None:
        return None
    if decl.metadata.get("entries") and isinstance(value, (list, tuple, np.ndarray)):
        value = list(np.ravel(value)) if isinstance(value, np.ndarray) else value
        if not value:
            return "number"
        return next((f for f in (_failed_one(check, v) for v in value) if f), None)
    return _failed_one(check, value)


def _failed_one(check: str, value) -> str | None:
    """:func:`failed_check` of one value against ``check``."""
    # numpy's bools are not numbers.Real; Python's are, and are refused by name
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        return "number"
    if check == ">=0" and value < 0:
        return ">=0"
    return ">0" if check == ">0" and value <= 0 else None


#: Each failed check in words: what the value must be.
WORDS = {"number": "a finite number", ">=0": ">= 0", ">0": "> 0"}


def words(decl, failed: str) -> str:
    """What setting ``decl`` must be, its check ``failed``: :data:`WORDS`, and for a setting of
    ``entries`` that a list of them is taken too."""
    what = WORDS[failed]
    return f"{what}, or a list of such, one per entry" if decl.metadata.get("entries") else what
