"""Rigid-body dynamics of the platform in task space (SymPy), eqs. (60)-(69).

D(q) q̈ + C(q, q̇) q̇ + G = (JL)ᵀ f, θ = [M_p, I_x, I_y, I_z]. C is derived from
D by Christoffel symbols, so that Ḋ − 2C is skew and C(q, x) y = C(q, y) x
(properties (i), (ii) of eq. (3)); the paper's c22 of eq. (64) gives the same
C(q, q̇) q̇ and is kept for comparison.
"""
from __future__ import annotations

import sympy as sp

from .kinematics import angular_velocity_map, body_angular_velocity_map, rotation

__all__ = [
    "theta_symbols", "mass_matrix", "mass_matrix_inverse", "coriolis", "gravity", "regressor",
    "coriolis_paper",
]


def theta_symbols(prefix: str = "theta") -> sp.Matrix:
    """[M_p, I_x, I_y, I_z] as symbols."""
    return sp.Matrix([sp.Symbol(f"{prefix}_{n}", real=True) for n in ("Mp", "Ix", "Iy", "Iz")])


def mass_matrix(q, theta) -> sp.Matrix:
    """D(q) of eq. (63), using Tᵀ R ᵖI Rᵀ T = T_bᵀ ᵖI T_b (T_b = Rᵀ T)."""
    Mp, Ix, Iy, Iz = theta
    Tb = body_angular_velocity_map(q)
    D = sp.zeros(6, 6)
    D[:3, :3] = Mp * sp.eye(3)
    D[3:, 3:] = Tb.T * sp.diag(Ix, Iy, Iz) * Tb
    return D


def mass_matrix_inverse(q, theta) -> sp.Matrix:
    """D(q)⁻¹ in closed form from the block structure: T_b⁻¹ ᵖI⁻¹ T_b⁻ᵀ (det T_b = cos θ).

    Singular only at θ = ±90° (gimbal lock), far outside the platform's workspace.
    """
    Mp, Ix, Iy, Iz = theta
    psi, th = q[3], q[4]
    c, s, ct, tt = sp.cos(psi), sp.sin(psi), sp.cos(th), sp.tan(th)
    Tb_inv = sp.Matrix([[1, s * tt, c * tt], [0, c, -s], [0, s / ct, c / ct]])
    Dinv = sp.zeros(6, 6)
    Dinv[:3, :3] = sp.eye(3) / Mp
    Dinv[3:, 3:] = Tb_inv * sp.diag(1 / Ix, 1 / Iy, 1 / Iz) * Tb_inv.T
    return Dinv


def coriolis(D: sp.Matrix, q, qdot) -> sp.Matrix:
    """Christoffel-form C(q, q̇): C_ij = Σ_k ½(∂D_ij/∂q_k + ∂D_ik/∂q_j − ∂D_jk/∂q_i) q̇_k."""
    n = D.shape[0]
    dD = [D.diff(q[k]) for k in range(n)]  # dD[k][i, j] = ∂D_ij/∂q_k
    C = sp.zeros(n, n)
    for i in range(n):
        for j in range(n):
            C[i, j] = sum(
                (sp.Rational(1, 2) * (dD[k][i, j] + dD[j][i, k] - dD[i][j, k]) * qdot[k]
                 for k in range(n)), sp.S.Zero)
    return C


def gravity(theta, g) -> sp.Matrix:
    """G of eq. (65): [0, 0, M_p g, 0, 0, 0] (gravity along −z)."""
    return sp.Matrix([0, 0, theta[0] * g, 0, 0, 0])


def regressor(q, v, w, a, theta, g) -> sp.Matrix:
    """Y(q, v, w, a) (6×4) with Y θ = D(q) a + C(q, v) w + G(q)."""
    D = mass_matrix(q, theta)
    expr = D * sp.Matrix(a) + coriolis(D, q, v) * sp.Matrix(w) + gravity(theta, g)
    return expr.jacobian(sp.Matrix(theta))


def coriolis_paper(q, qdot, theta) -> sp.Matrix:
    """C of eq. (64) with c22 = Tᵀ S(ω) ᵇI T + Tᵀ ᵇI Ṫ (right C q̇, but not property (ii))."""
    Mp, Ix, Iy, Iz = theta
    R = rotation(q)
    T = angular_velocity_map(q)
    Ib = R * sp.diag(Ix, Iy, Iz) * R.T
    eta_dot = sp.Matrix(qdot[3:])
    w = T * eta_dot
    S = sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    Tdot = sum((T.diff(q[k]) * qdot[k] for k in range(3, 6)), sp.zeros(3, 3))
    C = sp.zeros(6, 6)
    C[3:, 3:] = T.T * S * Ib * T + T.T * Ib * Tdot
    return C
