"""Kinematics of the Stewart platform (SymPy).

q = [x, y, z, ψ, θ, φ]: platform centre-of-mass position in the base frame (m,
z up) and angles (rad) with R = Rz(φ) Ry(θ) Rx(ψ) mapping platform-frame
vectors to the base frame.
"""
from __future__ import annotations

import sympy as sp

__all__ = [
    "pose_symbols", "rate_symbols", "rotation", "angular_velocity_map",
    "body_angular_velocity_map", "task_map", "leg_vectors", "leg_lengths", "leg_jacobian",
]


def pose_symbols(prefix: str = "q") -> sp.Matrix:
    """Column of the six pose symbols ``prefix_x … prefix_phi``."""
    names = ("x", "y", "z", "psi", "theta", "phi")
    return sp.Matrix([sp.Symbol(f"{prefix}_{n}", real=True) for n in names])


def rate_symbols(prefix: str, n: int = 6) -> sp.Matrix:
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


def leg_vectors(q, base_joints, platform_joints) -> list:
    """Base joint → platform joint vectors (base frame, m), one 3×1 Matrix per leg."""
    R = rotation(q)
    p = sp.Matrix(q[:3])
    return [p + R * sp.Matrix(pj) - sp.Matrix(bj) for bj, pj in zip(base_joints, platform_joints)]


def leg_lengths(q, base_joints, platform_joints) -> sp.Matrix:
    """l(q): the six leg lengths, m."""
    return sp.Matrix([sp.sqrt(v.dot(v)) for v in leg_vectors(q, base_joints, platform_joints)])


def leg_jacobian(q, base_joints, platform_joints) -> sp.Matrix:
    """JL = ∂l/∂q (6×6): l̇ = JL q̇; the generalised force of leg forces f is (JL)ᵀ f."""
    return leg_lengths(q, base_joints, platform_joints).jacobian(sp.Matrix(q))


def leg_intermediates(q, qdot, base_joints, platform_joints):
    """Leg lengths, JL and d/dt JL as intermediate symbols (keeps SymPy expressions small).

    Returns ``(l, JL, JL_dot, intermediates)`` where ``l`` (6×1), ``JL`` and
    ``JL_dot`` (6×6) are Matrices of symbols and ``intermediates`` lists
    ``(symbols, expression)`` pairs to be evaluated in order: row i of JL is
    vᵢᵀ ∂vᵢ/∂q / lᵢ for the leg vector vᵢ, and J̇L follows by the chain rule
    through q (rate q̇) and l (rate JL q̇).
    """
    vs = leg_vectors(q, base_joints, platform_joints)
    l = sp.Matrix([sp.Symbol(f"legl_{i}", real=True) for i in range(6)])
    JL = sp.Matrix(6, 6, lambda i, j: sp.Symbol(f"JL_{i}{j}", real=True))
    JL_dot = sp.Matrix(6, 6, lambda i, j: sp.Symbol(f"JLdot_{i}{j}", real=True))
    qm = sp.Matrix(q)
    l_value = sp.Matrix([sp.sqrt(v.dot(v)) for v in vs])
    JL_value = sp.Matrix.vstack(*[(v.T * v.jacobian(qm)) / l[i] for i, v in enumerate(vs)])
    ldot = JL * sp.Matrix(qdot)
    JL_dot_value = sum((JL_value.diff(q[k]) * qdot[k] for k in range(6)), sp.zeros(6, 6)) \
        + sum((JL_value.diff(l[i]) * ldot[i] for i in range(6)), sp.zeros(6, 6))
    return l, JL, JL_dot, [(l, l_value), (JL, JL_value), (JL_dot, JL_dot_value)]
