"""Model numbers as SymPy constants baked into the derivation (one place, one conversion)."""
from __future__ import annotations

import sympy as sp

__all__ = ["baked", "PRESSURE_EPS"]

#: Pressure drops below this (Pa) are clipped inside the valve inverse: no root of a
#: negative number, no division by zero when p_c reaches 0 or p_s.
PRESSURE_EPS = 1.0


def baked(value) -> sp.Float:
    """A model number as an exact SymPy Float (shortest round-trip repr, so the C is deterministic)."""
    return sp.Float(repr(float(value)))
