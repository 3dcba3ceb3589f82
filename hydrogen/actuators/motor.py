"""A constant-displacement hydraulic motor on a continuous (revolute, unlimited) joint, four-way valve.

Displacement D_m = ``displacement`` (m³/rad): torque τ = D_m (p_A − p_B) (N·m, positive turns the
joint the positive way, filling chamber A). The coordinate is the joint angle θ (rad), with no travel
limits: a motor turns without end (:data:`~hydrogen.actuators.declarations.ROTATION`), so the
description gives no angle range. Unlike a vane (:mod:`hydrogen.actuators.rotary`), its chamber
volumes do not change with the angle: V_A = ``volume_A`` and V_B = ``volume_B`` are the oil in the
lines and the motor case on each side (> 0). The laws are
:class:`~hydrogen.actuators.two_chamber.Laws` with both effective areas D_m and these constant
volumes: f0 = −θ̇ D_m² (1/V_A + 1/V_B), a constant spring rate, whose potential is linear in θ.
"""
from __future__ import annotations

from . import orifices as orf
from .declarations import DISPLACEMENT, ROTATION, VOLUME, Parameter, Sensor, State, readers
from .two_chamber import VALVE_PARAMETERS, Laws, displacement_areas

__all__ = ["NAME", "DOC", "MOTION", "TRAVEL", "COUPLING_GAIN", "STATES", "PARAMETERS", "SENSORS", "Symbolic", "Numeric",
           "parameters", "stacked"]

NAME = "motor"
DOC = "Constant-displacement hydraulic motor (continuous rotation) on a revolute joint, four-way valve."
#: The coordinate the actuator moves: the joint angle θ (rad), θ̇ (rad/s).
MOTION = "revolute"
#: Its coordinate, units and no range: the motor turns without limit.
TRAVEL = ROTATION
#: Default Γ_τ⁻¹ of the force loop: none is sound, as for the rotary vane (a torque loop in N·m/rad
#: weighs the force error by the square of a lever no actuator of its own carries).
COUPLING_GAIN = None
STATES = (State("pA", "Pa", "tank_pressure", "supply_pressure", "port A pressure (fills for positive rotation)"),
          State("pB", "Pa", "tank_pressure", "supply_pressure", "port B pressure"))
PARAMETERS = (
    Parameter("displacement", "m^3/rad", None, "D_m, volume the motor passes per radian", range=DISPLACEMENT),
    Parameter("volume_A", "m^3", None, "V_A, oil volume on side A (line and motor case), constant", range=VOLUME),
    Parameter("volume_B", "m^3", None, "V_B, oil volume on side B (line and motor case), constant", range=VOLUME),
    *VALVE_PARAMETERS,
)
SENSORS = (Sensor("q", "rad", "joint angle (encoder), unwrapped"),
           Sensor("pA", "Pa", "port A pressure"),
           Sensor("pB", "Pa", "port B pressure"))


#: Its parameters from a cylinder or joint actuator (or a mapping), defaults filled in; and those of
#: several actuators as arrays (m,), for the numeric laws.
parameters, stacked = readers(__name__)


#: (D_m, D_m), m³/rad: τ = D_m p_A − D_m p_B.
areas = displacement_areas


def volumes(x, P):
    """(V_A, V_B), m³: constant, shaped as the angle ``x`` (rad)."""
    return P["volume_A"] + 0 * x, P["volume_B"] + 0 * x


class _MotorLaws(Laws):
    """The two-chamber laws with constant volumes: only the potential of f0 differs (the general one
    assumes dV_A/dx = a_A)."""

    def f0_potential(self, x, P):
        """Φ(θ) = −θ D_m² (1/V_A + 1/V_B), whose time derivative is f0."""
        return -x * self.spring_rate(x, P)


#: The SymPy laws (the derivation layer).
Symbolic = _MotorLaws(orf.SYMPY, areas, volumes)
#: Their numpy twins.
Numeric = _MotorLaws(orf.NUMPY, areas, volumes)
