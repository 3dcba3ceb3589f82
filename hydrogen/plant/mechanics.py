"""The plant's mechanics: the pose q and its rate q̇, moved by the actuators' joint forces.

q̇ = q̇, q̈ = D(q)⁻¹ (τ − C(q, q̇) q̇ − G(q)), τ = JLᵀ f (f the actuators' forces less their friction).
"""
from __future__ import annotations

from . import PlantState

__all__ = ["STATES", "PARAMETERS", "Symbolic"]

STATES = (
    PlantState("q", "n", lambda model: list(model.coordinate_units),
               "pose: each coordinate, rad (a revolute joint) or m (a prismatic one)"),
    PlantState("qdot", "n", lambda model: [f"{u}/s" for u in model.coordinate_units], "velocity: q's rate"),
)

#: The inertial parameters θ are the model's (the plant's input ``theta``), not the block's own.
PARAMETERS = ()


class Symbolic:
    """The mechanics over SymPy."""

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
