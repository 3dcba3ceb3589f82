"""Coordinate symbols and the rotations of a floating joint (SymPy), below the kinematic tree
(:mod:`hydrogen.symbolic.tree`), which builds on them; :mod:`hydrogen.symbolic.kinematics` lists
them with the cylinders' stages.

A floating joint's coordinates are [x, y, z, ψ, θ, φ]: position in the parent frame (m) and
angles (rad) with R = Rz(φ) Ry(θ) Rx(ψ) mapping child-frame vectors to the parent frame.
"""
from __future__ import annotations

import sympy as sp

__all__ = ["pose_symbols", "rate_symbols", "rotation", "angular_velocity_map", "body_angular_velocity_map", "task_map",
           "matrix_symbols"]


def pose_symbols(model, prefix: str = "q") -> sp.Matrix:
    """Column of the model's coordinate symbols ``prefix_<coordinate name>``."""
    return sp.Matrix([sp.Symbol(f"{prefix}_{n}", real=True) for n in model.coordinate_names])


def rate_symbols(prefix: str, n: int) -> sp.Matrix:
    """Column of ``n`` real symbols ``prefix_0 … prefix_{n-1}``."""
    return sp.Matrix([sp.Symbol(f"{prefix}_{i}", real=True) for i in range(n)])


def _rx(a):
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rotation(q) -> sp.Matrix:
    """R = Rz(φ) Ry(θ) Rx(ψ): platform-frame coordinates → base frame."""
    return _rz(q[5]) * _ry(q[4]) * _rx(q[3])


def angular_velocity_map(q) -> sp.Matrix:
    """T of eq. (62): ω (base frame, rad/s) = T [ψ̇ θ̇ φ̇]ᵀ."""
    th, ph = q[4], q[5]
    return sp.Matrix([
        [sp.cos(th) * sp.cos(ph), -sp.sin(ph), 0],
        [sp.cos(th) * sp.sin(ph), sp.cos(ph), 0],
        [-sp.sin(th), 0, 1],
    ])


def body_angular_velocity_map(q) -> sp.Matrix:
    """T_b = Rᵀ T: angular velocity in the platform frame; depends on ψ and θ only."""
    psi, th = q[3], q[4]
    return sp.Matrix([
        [1, 0, -sp.sin(th)],
        [0, sp.cos(psi), sp.sin(psi) * sp.cos(th)],
        [0, -sp.sin(psi), sp.cos(psi) * sp.cos(th)],
    ])


def task_map(q) -> sp.Matrix:
    """L of eq. (61): [ṗ; ω] = L q̇."""
    L = sp.zeros(6, 6)
    L[:3, :3] = sp.eye(3)
    L[3:, 3:] = angular_velocity_map(q)
    return L


def matrix_symbols(prefix: str, rows: int, cols: int) -> sp.Matrix:
    """rows × cols real symbols ``prefix_ij`` (vectors: :func:`rate_symbols`)."""
    return sp.Matrix(rows, cols, lambda i, j: sp.Symbol(f"{prefix}_{i}{j}", real=True))
