"""A scenario setting's declaration (plain data): a number or switch that a description's
``[scenarios.<name>]``, ``[rig]`` or ``[variants.<name>]`` table may set, declared once by the part of
the loop that reads it (a plant block such as :mod:`hydrogen.plant.valve`, the Kalman filter, or the
loop's own parts in :mod:`hydrogen.scenario_settings`), which assembles them into the scenario's
fields.
"""
from __future__ import annotations

from dataclasses import field

__all__ = ["setting"]


def setting(default, unit: str, meaning: str, check: str | None = None, default_text: str | None = None):
    """A scenario setting: its default (None: required), unit and meaning (the description table's row,
    rendered by :func:`hydrogen.schema.description_table`) and its check: ``"number"`` a finite number,
    ``">=0"`` also not negative (None: checked by
    :meth:`hydrogen.simulation.scenarios.Scenario.validated` itself). A :class:`dataclasses.Field` of the
    scenario's fields (mutable defaults as given: the settings hold numbers, strings and tuples)."""
    meta = {"unit": unit, "meaning": meaning, "check": check, "default_text": default_text}
    return field(metadata=meta) if default is None else field(default=default, metadata=meta)
