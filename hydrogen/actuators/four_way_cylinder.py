"""A double-acting cylinder on a four-way valve: both chamber pressures are states.

Cap side (chamber A, area A_A = ``cap_area``) and rod side (chamber B, the annulus, area
A_B = ``annulus_area`` = cap area − the rod's own section); f = p_A A_A − p_B A_B (N, positive
extends the cylinder). Length l pin to pin (m), between ``stroke_min`` (piston at the cap end) and
``stroke_max`` (at the rod end); chamber volumes

    V_A(l) = V_A0 + A_A (l − l_min),   V_B(l) = V_B0 + A_B (l_max − l),

V_A0, V_B0 the dead volumes (hoses, ports: each > 0, so no chamber ever empties). The valve: four
orifices, critically centred (``underlap`` 0) or underlapped, supply P_s and tank P_t. The laws,
f0, g0 and the valve inverse are :class:`~hydrogen.actuators.two_chamber.Laws` on this geometry
(see that module for their derivation); :data:`Symbolic` gives SymPy, :data:`Numeric` numpy.
"""
from __future__ import annotations

from . import orifices as orf
from .declarations import AREA, LENGTH, PIN_LENGTH, VOLUME, Parameter, Sensor, State, readers
from .two_chamber import VALVE_PARAMETERS, Laws

__all__ = ["NAME", "DOC", "MOTION", "TRAVEL", "COUPLING_GAIN", "STATES", "PARAMETERS", "SENSORS", "Symbolic", "Numeric",
           "parameters", "stacked"]

NAME = "four_way_cylinder"
DOC = "Double-acting cylinder on a four-way valve (cap- and rod-side pressures both states)."
MOTION = "prismatic"
#: Its coordinate, units and range key (messages and rig settings name them).
TRAVEL = LENGTH
#: Default Γ_τ⁻¹ of the force loop (N/m, as the three-way cylinder).
COUPLING_GAIN = 1.0e4
STATES = (State("pA", "Pa", "tank_pressure", "supply_pressure", "cap-side chamber pressure"),
          State("pB", "Pa", "tank_pressure", "supply_pressure", "rod-side (annulus) chamber pressure"))
PARAMETERS = (
    Parameter("cap_area", "m^2", None, "A_A, piston area on the cap side", range=AREA),
    Parameter("annulus_area", "m^2", None, "A_B, piston area on the rod side = cap area - rod section",
              range=AREA),
    Parameter("stroke_min", "m", None, "length pin to pin with the piston at the cap end", range=PIN_LENGTH),
    Parameter("stroke_max", "m", None, "length pin to pin with the piston at the rod end", range=PIN_LENGTH),
    Parameter("dead_volume_A", "m^3", None, "V_A0, cap-side volume at the shortest length", range=VOLUME),
    Parameter("dead_volume_B", "m^3", None, "V_B0, rod-side volume at the longest length", range=VOLUME),
    *VALVE_PARAMETERS,
)
SENSORS = (Sensor("l", "m", "cylinder length, pin to pin"),
           Sensor("pA", "Pa", "cap-side chamber pressure"),
           Sensor("pB", "Pa", "rod-side chamber pressure"))


#: Its parameters from a cylinder or joint actuator (or a mapping), defaults filled in; and those of
#: several actuators as arrays (m,), for the numeric laws.
parameters, stacked = readers(__name__)


def areas(P):
    """(A_A, A_B), m²."""
    return P["cap_area"], P["annulus_area"]


def volumes(x, P):
    """(V_A, V_B) at length ``x``, m³."""
    return (P["dead_volume_A"] + P["cap_area"] * (x - P["stroke_min"]),
            P["dead_volume_B"] + P["annulus_area"] * (P["stroke_max"] - x))


#: The SymPy laws (the derivation layer).
Symbolic = Laws(orf.SYMPY, areas, volumes)
#: Their numpy twins.
Numeric = Laws(orf.NUMPY, areas, volumes)
