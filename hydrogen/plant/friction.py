"""The plant's friction: each actuator's, in its own unit (N on a cylinder, N m on a rotary
actuator), opposing its motion: f_fric = F_c tanh(l̇ / v_s) + b l̇. No state; its parameters are the
plant's input ``friction``, [F_c, b, v_s] per actuator.
"""
from __future__ import annotations

import numpy as np

from . import PlantParameter

__all__ = ["STATES", "PARAMETERS", "Symbolic", "Numeric"]

STATES = ()

#: Per actuator, in order, each in the actuator's own unit (its kind's TRAVEL).
PARAMETERS = (
    PlantParameter("coulomb", lambda t: t.force_unit, "Coulomb friction (F_c)", per_actuator=True),
    PlantParameter("viscous", lambda t: f"{t.force_unit} s/{t.unit}", "viscous friction coefficient (b)",
                   per_actuator=True),
    PlantParameter("smooth_speed", lambda t: f"{t.unit}/s", "speed of the tanh smoothing of the Coulomb "
                   "friction (v_s)", per_actuator=True),
)


class Symbolic:
    """The friction law over SymPy."""

    @staticmethod
    def parameters(m: int):
        """The symbols of :data:`PARAMETERS` of ``m`` actuators, [F_c, b, v_s] per actuator."""
        from ..actuators.declarations import sp
        return sp.Matrix([s for i in range(m) for s in sp.symbols(f"F_coulomb_{i} b_viscous_{i} v_smooth_{i}",
                                                                  real=True)])

    @staticmethod
    def force(ldot, coulomb, viscous, smooth_speed):
        """The friction force (torque) at rate ``ldot``, opposed to the motion by its user."""
        from ..actuators.declarations import sp
        return coulomb * sp.tanh(ldot / smooth_speed) + viscous * ldot


class Numeric:
    """The friction law over numpy (the same numbers as :class:`Symbolic`)."""

    @staticmethod
    def force(ldot, coulomb, viscous, smooth_speed):
        ldot = np.asarray(ldot, float)
        return coulomb * np.tanh(ldot / smooth_speed) + viscous * ldot
