"""Model numbers as SymPy constants baked into the derivation (one place, one conversion)."""
from __future__ import annotations

from contextlib import contextmanager

import sympy as sp

__all__ = ["baked", "PRESSURE_EPS", "NumberTable", "numbers_as_symbols", "folded", "mode_key"]

#: Pressure drops below this (Pa) are clipped inside the valve inverse: no root of a
#: negative number, no division by zero when p_c reaches 0 or p_s.
PRESSURE_EPS = 1.0


class NumberTable:
    """The description's numbers as symbols, in the order the derivation met them: ``symbols``
    and their ``values``. ``shared``: one symbol per distinct value (what folding would merge
    anyway), else one per number met (each number a parameter of its own)."""

    def __init__(self, shared: bool = False):
        self.shared, self.symbols, self.values, self._by_value = shared, [], [], {}

    def symbol(self, value: float) -> sp.Symbol:
        if self.shared and value in self._by_value:
            return self._by_value[value]
        s = sp.Symbol(f"number_{len(self.symbols)}", real=True)
        self.symbols.append(s)
        self.values.append(value)
        self._by_value.setdefault(value, s)
        return s


_table: NumberTable | None = None


@contextmanager
def numbers_as_symbols(shared: bool = False):
    """Within the block, :func:`baked` gives each model number as a symbol of the yielded
    :class:`NumberTable` instead of a constant: the same derivation with the numbers left as
    inputs (what folding them into the expressions saves is measured against it)."""
    global _table
    previous, _table = _table, NumberTable(shared)
    try:
        yield _table
    finally:
        _table = previous


@contextmanager
def folded():
    """Within the block, :func:`baked` folds numbers again (a decision made on the folded
    derivation, such as the rigid body's form, stays the same in both)."""
    global _table
    previous, _table = _table, None
    try:
        yield
    finally:
        _table = previous


def mode_key():
    """What the derivation caches add to their keys: None when numbers fold, else the table's id."""
    return None if _table is None else id(_table)


def baked(value) -> sp.Expr:
    """A model number as an exact SymPy Float (shortest round-trip repr, so the C is deterministic);
    a symbol of the table inside :func:`numbers_as_symbols`."""
    if _table is not None:
        return _table.symbol(float(value))
    return sp.Float(repr(float(value)))
