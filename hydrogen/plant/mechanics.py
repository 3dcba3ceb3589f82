"""The plant's mechanics: the pose q and its rate q̇, moved by the actuators' joint forces.

q̇ = q̇, q̈ = D(q)⁻¹ (τ − C(q, q̇) q̇ − G(q)), τ = JLᵀ f (f the actuators' forces less their friction).
"""
from __future__ import annotations

from . import PlantState

__all__ = ["POSITION", "STATES", "PARAMETERS", "Symbolic"]

#: Its place among the plant's blocks (:data:`hydrogen.plant.BLOCKS`): the pose and its rate first.
POSITION = 10

STATES = (
    PlantState("q", "n", lambda model: list(model.coordinate_units),
               "pose: each coordinate, rad (a revolute joint) or m (a prismatic one)"),
    PlantState("qdot", "n", lambda model: [f"{u}/s" for u in model.coordinate_units], "velocity: q's rate"),
)

#: The inertial parameters θ are the model's (the plant's input ``theta``), not the block's own.
PARAMETERS = ()


class Symbolic:
    """The mechanics over SymPy. In the plant (:mod:`hydrogen.symbolic.plant`) it gives the actuators'
    travel ``l`` (m or rad), its Jacobian ``JL`` and rate ``ldot`` at the pose, and moves the pose
    under the sum of every block's force along each actuator's travel, ``leg_force`` (N or N m)."""

    READS = ("q", "qdot")
    WRITES = ("l", "JL", "ldot")
    #: The forces along each actuator's travel (N or N m), the sum of what each block adds (its
    #: chambers' force, less its friction): one intermediate.
    SUMS = {"leg_force": "plant_fleg"}

    @staticmethod
    def outputs(c) -> None:
        from ..symbolic.kinematics import leg_intermediates
        l, JL, _, kin = leg_intermediates(c.model, c["q"], c["qdot"], rates=False)  # the plant needs no J̇L
        c.stage(kin)
        c.provide("l", l)
        c.provide("JL", JL)
        c.provide("ldot", JL * c["qdot"], prefix="plant_ldot")

    @staticmethod
    def derivatives(c) -> None:
        rates, stages = Symbolic.rates(c.model, c["q"], c["qdot"], c["JL"].T * c["leg_force"], c["theta"])
        c.stage(stages)
        for name, value in rates.items():
            c.rate(name, value)

    @staticmethod
    def states(model) -> dict:
        """``{name: column of symbols}`` of the block's states."""
        from ..symbolic.kinematics import pose_symbols, rate_symbols
        return {"q": pose_symbols(model), "qdot": rate_symbols("qdot", model.n)}

    @staticmethod
    def rates(model, q, qdot, tau, theta) -> tuple:
        """``({"q": q̇, "qdot": q̈}, stages)``: q̈ by the model's forward dynamics under joint forces
        ``tau`` (N m or N), its stages (intermediates) to evaluate first."""
        from ..symbolic.rigid_body import forward_dynamics
        qdd, stages = forward_dynamics(model, q, qdot, tau, theta, prefix="plant_aba", solve="plant_qdd")
        return {"q": qdot, "qdot": qdd}, stages
