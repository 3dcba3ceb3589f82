"""What an actuator kind declares (chamber states, parameters, sensors), and reading its parameters.

Plain data, no SymPy: the numeric layer (simulator, identification) imports this without the
derivation layer. :data:`sp` gives the kind modules SymPy on first use, so a kind module can be
imported by numeric code and still hold its SymPy expressions.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["State", "Range", "Parameter", "Sensor", "Travel", "LENGTH", "ANGLE", "UNDERLAP", "ORIFICE_LINEAR_BELOW",
           "ROTATION", "SUPPLY_PRESSURE", "TANK_PRESSURE", "BULK_MODULUS", "FLOW_GAIN", "AREA", "PIN_LENGTH", "CHAMBER_LENGTH",
           "VOLUME", "DISPLACEMENT", "TURNS", "LEAKAGE", "exact_zeros", "parameter_values", "readers", "stacked_parameters", "state_bounds", "sp"]


@dataclass(frozen=True)
class State:
    """A chamber pressure state of the plant: ``name``, ``unit``, bounds ``lower``/``upper`` (a number,
    or the name of the parameter that holds it, e.g. ``"supply_pressure"``)."""

    name: str
    unit: str
    lower: float | str
    upper: float | str
    doc: str = ""


@dataclass(frozen=True)
class Range:
    """The values a constant may take: its sign rule ``sign`` ("positive", "nonnegative" or None) and
    the plausible range [``low``, ``high``] (SI, in the constant's unit), generous enough for any real
    hydraulic machine, from micro-actuators to 100-t excavators and presses: a value outside is a slip
    of unit or a typo (1e308 overflows the plant's arithmetic). The loader refuses one outside with
    the range; an exported program (C, FMU) refuses an edited number outside it."""

    sign: str | None
    low: float
    high: float


#: Pa: 1 bar (low-pressure water hydraulics) .. 1000 bar (above the 700 bar of the highest-pressure tools)
SUPPLY_PRESSURE = Range("positive", 1e5, 1e8)
#: Pa (gauge): the return line's pressure, 0 .. the largest supply
TANK_PRESSURE = Range("nonnegative", 0.0, 1e8)
#: Pa: oil full of entrained air (1e7) .. 5x the stiffest hydraulic fluids (water, oil: ~2e9)
BULK_MODULUS = Range("positive", 1e7, 1e10)
#: m^2/(s sqrt(Pa)): c = c_d w sqrt(2/rho), q = c u sqrt(dp): a 10 um-wide micro-valve port (3e-7) .. a
#: 30 m port periphery
FLOW_GAIN = Range("positive", 1e-9, 1.0)
#: m^2: a piston's area, a 0.1 mm bore (8e-9) .. a 3.5 m press bore (10)
AREA = Range("positive", 1e-8, 10.0)
#: m, pin to pin: 10 um (a micro-actuator) .. 100 m (longer than any telescopic cylinder's stroke)
PIN_LENGTH = Range("positive", 1e-5, 100.0)
#: m: the length at which a three-way cylinder's control chamber would be empty
CHAMBER_LENGTH = Range("nonnegative", 0.0, 100.0)
#: m^3: a chamber's dead volume (hoses, ports): 1 mm^3 (a micro-actuator) .. 100 m^3
VOLUME = Range("positive", 1e-9, 100.0)
#: m^3/rad: a rotary actuator's displacement: a 1 mm^3/rad micro-actuator .. 1 m^3/rad
DISPLACEMENT = Range("positive", 1e-9, 1.0)
#: rad: an angle within two turns either way
TURNS = Range(None, -4 * math.pi, 4 * math.pi)
#: m^3/(s Pa): a laminar leakage coefficient, Q = C_l dp: 0 (none) .. 1e-6 (100 L/s per bar, an open
#: line rather than a leak; worn seals leak ~1e-11)
LEAKAGE = Range("nonnegative", 0.0, 1e-6)


@dataclass(frozen=True)
class Parameter:
    """A constant of the actuator: ``name``, ``unit``, ``default`` (None: required), ``doc``, and
    ``range`` (:class:`Range`, in ``unit``; None: any finite number): the loader and the exported
    programs hold the value to it.

    ``gamma``: one of the paper's hydraulic parameters γ = [β, βc] (the bulk modulus β or the flow gain
    c): the model holds its true value, but the symbolic laws take β and c as arguments, since the
    controllers adapt them.

    ``zero_is_structure``: a value of exactly 0 is structure, not a number (as a zero coordinate of a
    joint origin): the derivation holds it as an exact 0, so the terms it multiplies drop out and the
    generated code and the description's hash are those of a kind without it; any other value is a
    number like the rest (a leakage coefficient, default 0)."""

    name: str
    unit: str
    default: float | None
    doc: str
    gamma: bool = False
    range: Range | None = None
    zero_is_structure: bool = False


#: The valve constants every kind with an orifice valve takes, with one default each (the three-way
#: cylinder's and the two-chamber kinds' alike).
#: m of spool travel: 0 (critical centre) .. 1 cm (spools travel millimetres)
UNDERLAP = Parameter("underlap", "m", 0.0, "d, valve underlap (0: critically centred)",
                     range=Range("nonnegative", 0.0, 1e-2))
#: Pa: the pressure drop below which the plant's orifice roots turn linear: up to the largest supply
ORIFICE_LINEAR_BELOW = Parameter("orifice_linear_below", "Pa", 5.0e4,
                                 "the simulated plant's orifice roots turn linear below this drop",
                                 range=Range("positive", 1.0, 1e8))


@dataclass(frozen=True)
class Sensor:
    """A signal the robot measures on this actuator: ``name`` (prefix of its columns), ``unit``, ``doc``."""

    name: str
    unit: str
    doc: str


@dataclass(frozen=True)
class Travel:
    """What an actuator's coordinate is and in which units, for the description, the rig settings and
    every message about its travel: ``quantity`` ("length", "angle"), ``unit`` of the coordinate,
    ``force_unit`` of what it exerts, the description ``key`` of its range as [min, max] and the
    parameter names of its ``ends``, ``range_word`` for that range in messages ("stroke"), and
    ``misread``: units a log may hold it in by mistake, as (name, size in ``unit``): a rig log's
    check names the one its numbers fit. ``limits``: the :class:`Range` each end of its range is held to.

    Unlimited travel (a motor on a continuous joint) has no ``key`` (None) and no ``ends``: the
    description gives no range, and every check of travel (stroke at load and along a reference, a
    rig log's columns, the FMU's start pose) takes its range as (−∞, ∞)."""

    quantity: str
    unit: str
    force_unit: str
    key: str | None
    ends: tuple
    range_word: str
    doc: str
    misread: tuple = ()
    limits: Range | None = None

    @property
    def limited(self) -> bool:
        """Whether the coordinate has a range (the description gives ``key``), else it travels freely."""
        return self.key is not None

    def value(self, x, fmt: str = ".4f") -> str:
        """``x`` named in this travel for a message: "length 0.4512 m", "angle -0.5000 rad"."""
        return f"{self.quantity} {float(x):{fmt}} {self.unit}"

    def span(self, lo, hi, fmt: str = "") -> str:
        """The range [lo, hi] named for a message: "stroke [0.4, 0.8] m", "angle range [-1.8, 1.8] rad"."""
        return f"{self.range_word} [{float(lo):{fmt}}, {float(hi):{fmt}}] {self.unit}"

    def rate_unit(self, power: int = 1) -> str:
        """The coordinate's unit per s^power (m/s, rad/s^3)."""
        return f"{self.unit}/s" if power == 1 else f"{self.unit}/s^{power}"


#: A cylinder's travel: its pin-to-pin length l (m) within its stroke, force in N.
LENGTH = Travel("length", "m", "N", "stroke", ("stroke_min", "stroke_max"), "stroke",
                "[shortest, longest] pin-to-pin length", (("mm", 1e-3),), PIN_LENGTH)
#: A joint actuator's travel: its joint angle θ (rad) within its angle range, torque in N m.
ANGLE = Travel("angle", "rad", "N m", "angle", ("angle_min", "angle_max"), "angle range",
               "[lowest, highest] joint angle", (("degrees", math.pi / 180.0),), TURNS)
#: A joint actuator turning without limit (a motor on a continuous joint): its joint angle θ (rad),
#: torque in N m, no range.
ROTATION = Travel("angle", "rad", "N m", None, (), "rotation", "continuous rotation: no travel limits",
                  (("degrees", math.pi / 180.0),))


class _LazySympy:
    """SymPy, imported when a symbolic law first uses it (numeric users never pay for it)."""

    def __getattr__(self, name):
        import sympy
        return getattr(sympy, name)


#: SymPy for the kind modules' symbolic laws (imported on first attribute access).
sp = _LazySympy()


def exact_zeros(parameters, values: Mapping) -> set:
    """The names of ``parameters`` whose value in ``values`` is structure: an exact 0 of a parameter
    declared ``zero_is_structure``."""
    return {p.name for p in parameters if p.zero_is_structure and float(values[p.name]) == 0.0}


def parameter_values(kind: str, parameters, source, convert=float) -> dict:
    """``{name: convert(value)}`` of the declared ``parameters`` of actuator ``kind`` from ``source``
    (a mapping, or an object with the parameters as attributes, such as a model's cylinder); a
    parameter absent from ``source`` takes its default. Raises ValueError naming the kind and the
    parameter when a required one is missing or a value is not a finite number."""
    out = {}
    for par in parameters:
        if isinstance(source, Mapping):
            value = source.get(par.name, par.default)
        else:
            value = getattr(source, par.name, par.default)
        if value is None:
            raise ValueError(f"actuator '{kind}': parameter '{par.name}' ({par.unit}, {par.doc}) is missing "
                             "and has no default")
        try:
            ok = math.isfinite(float(value))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"actuator '{kind}': parameter '{par.name}' must be a finite number "
                             f"({par.unit}), got {value!r}")
        out[par.name] = convert(value)
    return out


def readers(module: str) -> tuple:
    """``(parameters, stacked)`` of the actuator kind of ``module`` (its ``__name__``), read from its
    ``NAME`` and ``PARAMETERS`` when called: ``parameters(source, convert=float)``, its parameters
    from a cylinder or joint actuator (or a mapping), defaults filled in (:func:`parameter_values`);
    ``stacked(sources)``, those of several actuators as arrays (m,), for the numeric laws
    (:func:`stacked_parameters`)."""
    import sys

    def values(source, convert=float) -> dict:
        kind = sys.modules[module]
        return parameter_values(kind.NAME, kind.PARAMETERS, source, convert)

    def stacked(sources) -> dict:
        kind = sys.modules[module]
        return stacked_parameters(kind.NAME, kind.PARAMETERS, sources)

    return values, stacked


def stacked_parameters(kind: str, parameters, sources) -> dict:
    """``{name: array (m,)}``: the parameters of each of ``sources`` (one per actuator), stacked, for
    numeric laws that broadcast over actuators."""
    rows = [parameter_values(kind, parameters, s) for s in sources]
    return {par.name: np.array([r[par.name] for r in rows], float) for par in parameters}


def state_bounds(states, values: Mapping) -> list:
    """``[(lower, upper)]`` of each state, the bounds that name a parameter read from ``values``."""
    def bound(b):
        return values[b] if isinstance(b, str) else b
    return [(bound(s.lower), bound(s.upper)) for s in states]
