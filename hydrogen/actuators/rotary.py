"""A rotary vane actuator on a revolute joint, driven by a four-way valve.

Displacement D_m = ``displacement`` (m³/rad): torque τ = D_m (p_A − p_B) (N·m, positive turns the
joint the positive way, filling chamber A). The coordinate is the joint angle θ (rad) between
``angle_min`` and ``angle_max``. Chosen model: a *vane* actuator (limited travel), whose chamber
volumes change with the angle,

    V_A(θ) = V_A0 + D_m (θ − θ_min),   V_B(θ) = V_B0 + D_m (θ_max − θ),

V_A0, V_B0 the dead volumes (> 0). A hydraulic *motor* (unlimited rotation) has constant chamber
volumes instead: it is not this kind (its f0 would be −ω D_m² (1/V_A + 1/V_B) with constant V).
The laws are :class:`~hydrogen.actuators.two_chamber.Laws` with both effective areas D_m.
"""
from __future__ import annotations

from . import orifices as orf
from .declarations import ANGLE, DISPLACEMENT, TURNS, VOLUME, Parameter, Sensor, State, readers
from .two_chamber import VALVE_PARAMETERS, Laws, displacement_areas

__all__ = ["NAME", "DOC", "MOTION", "TRAVEL", "COUPLING_GAIN", "STATES", "PARAMETERS", "SENSORS", "Symbolic", "Numeric",
           "parameters", "stacked"]

NAME = "rotary"
DOC = "Rotary vane actuator (displacement per radian) on a revolute joint, four-way valve."
#: The coordinate the actuator moves: the joint angle θ (rad), θ̇ (rad/s).
MOTION = "revolute"
#: Its coordinate, units and range key (messages and rig settings name them).
TRAVEL = ANGLE
#: Default Γ_τ⁻¹ of the force loop (no sound default: about 1e4 r² N·m/rad, r the lever (m) of a cylinder doing the same job).
COUPLING_GAIN = None
STATES = (State("pA", "Pa", "tank_pressure", "supply_pressure", "chamber A pressure (fills for positive rotation)"),
          State("pB", "Pa", "tank_pressure", "supply_pressure", "chamber B pressure"))
PARAMETERS = (
    Parameter("displacement", "m^3/rad", None, "D_m, volume swept per radian", range=DISPLACEMENT),
    Parameter("angle_min", "rad", None, "joint angle with chamber A at its dead volume", range=TURNS),
    Parameter("angle_max", "rad", None, "joint angle with chamber B at its dead volume", range=TURNS),
    Parameter("dead_volume_A", "m^3", None, "V_A0, chamber A volume at angle_min", range=VOLUME),
    Parameter("dead_volume_B", "m^3", None, "V_B0, chamber B volume at angle_max", range=VOLUME),
    *VALVE_PARAMETERS,
)
SENSORS = (Sensor("q", "rad", "joint angle (encoder)"),
           Sensor("pA", "Pa", "chamber A pressure"),
           Sensor("pB", "Pa", "chamber B pressure"))


#: Its parameters from a cylinder or joint actuator (or a mapping), defaults filled in; and those of
#: several actuators as arrays (m,), for the numeric laws.
parameters, stacked = readers(__name__)


#: (D_m, D_m), m³/rad: τ = D_m p_A − D_m p_B.
areas = displacement_areas


def volumes(x, P):
    """(V_A, V_B) at angle ``x``, m³."""
    D = P["displacement"]
    return P["dead_volume_A"] + D * (x - P["angle_min"]), P["dead_volume_B"] + D * (P["angle_max"] - x)


#: The SymPy laws (the derivation layer).
Symbolic = Laws(orf.SYMPY, areas, volumes)
#: Their numpy twins.
Numeric = Laws(orf.NUMPY, areas, volumes)
