"""Kinematics of the Stewart platform (SymPy).

q = [x, y, z, ψ, θ, φ]: platform centre-of-mass position in the base frame (m,
z up) and angles (rad) with R = Rz(φ) Ry(θ) Rx(ψ) mapping platform-frame
vectors to the base frame.
"""
from __future__ import annotations

import sympy as sp

__all__ = [
    "pose_symbols", "rate_symbols", "rotation", "angular_velocity_map",
    "body_angular_velocity_map", "task_map", "leg_vectors", "leg_lengths", "leg_jacobian", "leg_stages",
    "leg_intermediates", "matrix_symbols",
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


def matrix_symbols(prefix: str, rows: int, cols: int) -> sp.Matrix:
    """rows × cols real symbols ``prefix_ij`` (vectors: :func:`rate_symbols`)."""
    return sp.Matrix(rows, cols, lambda i, j: sp.Symbol(f"{prefix}_{i}{j}", real=True))


def leg_stages(q, base_joints, platform_joints):
    """Leg lengths and JL as intermediate symbols, in stages: ``(R, l, JL, stages)``.

    ``stages`` lists ``(symbols, expression)`` pairs to evaluate in order: the rotation R,
    then l_i = ‖v_i‖ with v_i = p + R p_i − b_i, then row i of JL,
    [n_iᵀ, ((R p_i) × n_i)ᵀ T] with n_i = v_i / l_i: the leg force along n_i acts on the
    platform's centre as a force n_i and a moment (R p_i) × n_i, and T maps Euler rates to ω
    (l̇_i = n_iᵀ (ṗ + ω × R p_i)). Each leg refers to the nine symbols of R instead of
    SymPy's expanded products of sines and cosines, so the legs share R: JL takes 392 CasADi
    instructions this way against 744 for the symbolic Jacobian of l(q).
    """
    qm = sp.Matrix(q)
    R, l, JL = matrix_symbols("R", 3, 3), rate_symbols("legl"), matrix_symbols("JL", 6, 6)
    T = angular_velocity_map(qm)
    l_value, JL_rows = [], []
    for i, (bj, pj) in enumerate(zip(base_joints, platform_joints)):
        r = R * sp.Matrix(pj)
        v = sp.Matrix(qm[:3]) + r - sp.Matrix(bj)
        l_value.append(sp.sqrt(v.dot(v)))
        n = v / l[i]
        JL_rows.append(sp.Matrix([*n, *(T.T * r.cross(n))]).T)
    stages = [(R, rotation(qm)), (l, sp.Matrix(l_value)), (JL, sp.Matrix.vstack(*JL_rows))]
    return R, l, JL, stages


def leg_intermediates(q, qdot, base_joints, platform_joints, rates: bool = True):
    """Leg lengths, JL and d/dt JL as intermediate symbols (keeps SymPy expressions small).

    Returns ``(l, JL, JL_dot, stages)``: ``l`` (6×1), ``JL`` and ``JL_dot`` (6×6) are Matrices
    of symbols and ``stages`` lists ``(symbols, expression)`` pairs to evaluate in order (see
    :func:`leg_stages`). J̇L is the forward-mode time derivative of JL's stage, with q̇ for q,
    Ṙ = S(ω) R for R (ω = T η̇) and l̇ = JL q̇ for l. With ``rates=False`` (the plant) there
    is no J̇L: ``JL_dot`` is None and its stages are left out.
    """
    from .calculus import time_derivative

    R, l, JL, stages = leg_stages(q, base_joints, platform_joints)
    if not rates:
        return l, JL, None, stages
    qm, qdm = sp.Matrix(q), sp.Matrix(qdot)
    w = angular_velocity_map(qm) * sp.Matrix(qdm[3:])
    S = sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    R_dot, JL_dot = matrix_symbols("Rdot", 3, 3), matrix_symbols("JLdot", 6, 6)
    JL_dot_value = time_derivative(stages[2][1], [(qm, qdm), (R, R_dot), (l, JL * qdm)])
    return l, JL, JL_dot, [*stages, (R_dot, S * R), (JL_dot, JL_dot_value.reshape(6, 6))]
