"""Model numbers as SymPy constants baked into the derivation (one place, one conversion)."""
from __future__ import annotations

from contextlib import contextmanager
from itertools import count

import sympy as sp

__all__ = ["baked", "baked_table", "PRESSURE_EPS", "KEYS", "NumberTable", "numbers_as_symbols", "folded", "mode_key"]

#: Pressure drops below this (Pa) are clipped inside the valve inverse: no root of a
#: negative number, no division by zero when p_c reaches 0 or p_s.
PRESSURE_EPS = 1.0


#: How a NumberTable gives out symbols: one per description number (by its name, a number without
#: one per use), one per distinct value, or one per number met.
KEYS = ("name", "value", "use")


class NumberTable:
    """The description's numbers as symbols, in the order the derivation met them: ``symbols``,
    their ``values`` and ``names`` (None where the number came without one). ``key`` (:data:`KEYS`):
    "name", a symbol per description number, what a vector of runtime parameters would hold;
    "value", a symbol per distinct value (what folding would merge anyway); "use", a symbol for
    every number met (the same description number met in two derivation passes counts twice)."""

    _serials = count(1)

    def __init__(self, key: str = "name"):
        if key not in KEYS:
            raise ValueError(f"NumberTable key must be one of {KEYS}, got {key!r}")
        self.key, self.symbols, self.values, self.names, self._seen = key, [], [], [], {}
        # what the derivation caches key on: never reused, unlike id() of a table freed since
        self.serial = next(NumberTable._serials)

    def symbol(self, value: float, name: str | None = None) -> sp.Symbol:
        ident = {"name": name, "value": value, "use": None}[self.key]
        if ident is not None and ident in self._seen:
            return self._seen[ident]
        s = sp.Symbol(f"number_{len(self.symbols)}", real=True)
        self.symbols.append(s)
        self.values.append(value)
        self.names.append(name)
        if ident is not None:
            self._seen[ident] = s
        return s


_table: NumberTable | None = None


@contextmanager
def _using(table: NumberTable | None):
    """Within the block, :func:`baked` gives out ``table``'s symbols (None: folds numbers)."""
    global _table
    previous, _table = _table, table
    try:
        yield table
    finally:
        _table = previous


def numbers_as_symbols(key: str = "name"):
    """Within the block, :func:`baked` gives each model number as a symbol of the yielded
    :class:`NumberTable` instead of a constant: the same derivation with the numbers left as
    inputs (what folding them into the expressions saves is measured against it)."""
    return _using(NumberTable(key))


def folded():
    """Within the block, :func:`baked` folds numbers again (a decision made on the folded
    derivation, such as the rigid body's form, stays the same in both)."""
    return _using(None)


def mode_key():
    """What the derivation caches add to their keys: None when numbers fold, else the table's serial
    (each table's symbols are its own: number_0 of one table is another number than of the next)."""
    return None if _table is None else _table.serial


def baked(value, name: str | None = None) -> sp.Expr:
    """A model number as an exact SymPy Float (shortest round-trip repr, so the C is deterministic);
    a symbol of the table inside :func:`numbers_as_symbols`. ``name``: the number's place in the
    description (``<link>.mass``, ``<joint>.origin_xyz[0]``, ``<cylinder>.piston_area``)."""
    if _table is not None:
        return _table.symbol(float(value), name)
    return sp.Float(repr(float(value)))


def baked_table(values: dict, prefix: str, zeros=()) -> dict:
    """``{name: baked(value, "<prefix>.<name>")}``: a component's numbers (an actuator's parameters);
    the names in ``zeros`` are structure, an exact 0 (no number, in either mode)."""
    return {k: sp.S.Zero if k in zeros else baked(v, f"{prefix}.{k}") for k, v in values.items()}
