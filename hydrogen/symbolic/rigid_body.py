"""Rigid-body dynamics of a description's tree (SymPy), eqs. (1)-(3) and (60)-(69).

D(q) q̈ + C(q, q̇) q̇ + G(q) = (JL)ᵀ f. D and G come from the tree
(:class:`~hydrogen.symbolic.tree.SymbolicTree`); C is the Christoffel one, so that Ḋ − 2C is skew
and C(q, x) y = C(q, y) x (properties (i), (ii) of eq. (3)); the paper's c22 of eq. (64) for the
floating platform gives the same C(q, q̇) q̇ and is kept for comparison.

Two forms (:meth:`SymbolicTree.staged`; the description's ``rigid_body_form``, for "auto" the one
of fewer CasADi instructions, :mod:`hydrogen.symbolic.forms`): the closed form (D from expanded
link Jacobians, C by differentiating D, G = ∂V/∂q), the only one for floating bodies, and the
staged form (D, C, G and Y by spatial algebra over link poses bound to
intermediate symbols; :func:`rigid_body_stages` lists those stages, which every function using
these expressions must evaluate first, and :func:`~hydrogen.symbolic.kinematics.pose_rates` their
time derivatives).
θ are the adapted inertial parameters (``model.theta_names``); D, C, G are affine in θ, and the
regressor Y = ∂(D a + C(q, v) w + G)/∂θ.
"""
from __future__ import annotations

import sympy as sp

from .calculus import diff_matrix, matmul
from .constants import baked, mode_key
from .coordinates import angular_velocity_map, rate_symbols, rotation
from .tree import SymbolicTree

__all__ = [
    "theta_symbols", "mass_matrix", "mass_matrix_inverse", "coriolis", "coriolis_matrix", "gravity", "regressor",
    "regressor_offset", "coriolis_paper", "symbolic_tree", "inverse_dynamics", "bias_forces", "rigid_body_stages",
    "recursive_forward_dynamics", "recursive_inverse_dynamics", "recursive_mass_matrix", "forward_dynamics",
]

_TREES = {}


def theta_symbols(model, prefix: str = "theta") -> sp.Matrix:
    """The adapted parameters θ as symbols ``prefix_0 …`` (``model.theta_names`` order)."""
    return sp.Matrix([sp.Symbol(f"{prefix}_{k}", real=True) for k in range(len(model.theta_names))])


def symbolic_tree(model, q, theta) -> SymbolicTree:
    """The :class:`SymbolicTree` for these symbols, built once (its closed form is reused)."""
    key = (model.baked_hash(), mode_key(), tuple(sp.Matrix(q)), tuple(sp.Matrix(theta)))
    if key not in _TREES:
        _TREES[key] = SymbolicTree(model, q, theta)
    return _TREES[key]


def rigid_body_stages(model, q) -> list:
    """The intermediate stages the rigid-body expressions of this module refer to: every link's
    pose (:meth:`SymbolicTree.pose_stages`) for a staged tree, none for the closed form."""
    tree = symbolic_tree(model, q, theta_symbols(model))
    return tree.pose_stages() if tree.staged() else []


def mass_matrix(model, q, theta) -> sp.Matrix:
    """D(q) (n×n) for parameters θ."""
    tree = symbolic_tree(model, q, theta)
    return tree.staged_mass_matrix() if tree.staged() else tree.mass_matrix()


def mass_matrix_inverse(model, q, theta):
    """D(q)⁻¹ in closed form where the tree allows it (a single floating body at its centre of
    mass: singular only at θ = ±90°, gimbal lock), else None: solve numerically."""
    return symbolic_tree(model, q, theta).mass_matrix_inverse()


def coriolis_matrix(model, q, qdot, theta) -> sp.Matrix:
    """Christoffel-form C(q, q̇) (n×n) for parameters θ, in the tree's form."""
    tree = symbolic_tree(model, q, theta)
    if tree.staged():
        return tree.staged_coriolis(sp.Matrix(qdot))
    return coriolis(tree.mass_matrix(), q, qdot, tree.mass_matrix_partials())


def coriolis(D: sp.Matrix, q, qdot, partials=None) -> sp.Matrix:
    """Christoffel-form C(q, q̇) of an explicit D(q): C_ij = Σ_k ½(∂D_ij/∂q_k + ∂D_ik/∂q_j − ∂D_jk/∂q_i) q̇_k.
    ``partials``: ∂D/∂q_k for each k when made already (:meth:`SymbolicTree.mass_matrix_partials`)."""
    n = D.shape[0]
    dD = [diff_matrix(D, q[k]) for k in range(n)] if partials is None else partials  # dD[k][i, j] = ∂D_ij/∂q_k
    C = sp.zeros(n, n)
    for i in range(n):
        for j in range(n):
            C[i, j] = sum(
                (sp.Rational(1, 2) * (dD[k][i, j] + dD[j][i, k] - dD[i][j, k]) * qdot[k]
                 for k in range(n)), sp.S.Zero)
    return C


def gravity(model, q, theta) -> sp.Matrix:
    """G(q) = ∂V/∂q, gravity along −z of the base frame (N or N m)."""
    tree = symbolic_tree(model, q, theta)
    g = baked(model.gravity, "gravity")
    return tree.staged_gravity(g) if tree.staged() else tree.gravity(g)


def inverse_dynamics(model, q, v, w, a, theta) -> sp.Matrix:
    """D(q) a + C(q, v) w + G(q) (n) for parameters θ: one Newton-Euler pass on a staged tree."""
    return _dynamics_of(symbolic_tree(model, q, theta), q, v, w, a, baked(model.gravity, "gravity"))


def bias_forces(model, q, qdot, theta) -> sp.Matrix:
    """C(q, q̇) q̇ + G(q) (n), N or N m: the forces q̈ = D⁻¹ (τ − C q̇ − G) subtracts."""
    tree = symbolic_tree(model, q, theta)
    if tree.staged():
        return tree.staged_inverse_dynamics(qdot, qdot, sp.zeros(len(qdot), 1), baked(model.gravity, "gravity"))
    return matmul(coriolis(tree.mass_matrix(), q, qdot, tree.mass_matrix_partials()), sp.Matrix(qdot)) \
        + gravity(model, q, theta)


def _dynamics_of(tree, q, v, w, a, g):
    if tree.staged():
        return tree.staged_inverse_dynamics(sp.Matrix(v), sp.Matrix(w), sp.Matrix(a), g)
    D = tree.mass_matrix()
    return matmul(D, sp.Matrix(a)) + matmul(coriolis(D, q, v, tree.mass_matrix_partials()), sp.Matrix(w)) \
        + tree.gravity(g)


def recursive_forward_dynamics(model, q, qdot, tau, theta, prefix: str = "aba"):
    """q̈ = D⁻¹ (τ − C q̇ − G) by the articulated-body algorithm: ``(qdd, stages)``
    (:func:`~hydrogen.symbolic.articulated.articulated_body_stages`, linear in the number of links
    where the solve of D is cubic), on any tree the staged form applies to, whichever form D, C, G
    take (it works in link frames from the joint angles, not from either form's expressions); None
    for a floating joint (a symbolic solve, or a single floating body's closed-form D⁻¹).
    ``tau``: joint forces, N m or N."""
    tree = symbolic_tree(model, q, theta)
    if not tree.staged_applies():
        return None
    from .articulated import articulated_body_stages

    return articulated_body_stages(tree, qdot, tau, baked(model.gravity, "gravity"), prefix)


def forward_dynamics(model, q, qdot, tau, theta, poses=(), prefix: str = "aba", solve: str = "fd_qdd"):
    """q̈ = D⁻¹ (τ − C q̇ − G) and the stages it needs: ``(qdd, stages)``. The articulated-body
    algorithm where the tree allows it (its own stages), else the closed-form D⁻¹ of a single
    floating body, else a linear solve of D into symbols ``<solve>_i``; these two refer to the link
    ``poses`` (:func:`rigid_body_stages`), which lead their stages (pass none when the caller's
    stages hold them already). ``tau``: joint forces, N m or N; ``prefix``: of the ABA's symbols."""
    recursive = recursive_forward_dynamics(model, q, qdot, tau, theta, prefix)
    if recursive is not None:
        return recursive
    rhs = tau - bias_forces(model, q, qdot, theta)
    Dinv = mass_matrix_inverse(model, q, theta)
    if Dinv is not None:
        return Dinv * rhs, [*poses]
    qdd = rate_symbols(solve, model.n)
    return qdd, [*poses, (qdd, ("solve", mass_matrix(model, q, theta), rhs))]


def recursive_inverse_dynamics(model, q, qdot, qddot, theta, prefix: str = "rnea"):
    """τ = D q̈ + C q̇ + G by recursive Newton-Euler in link frames: ``(tau, stages)``
    (:func:`~hydrogen.symbolic.articulated.newton_euler_stages`, linear in the number of links), on
    the trees :func:`recursive_forward_dynamics` takes, in either form; else None. Only at w = v:
    the Christoffel slots C(q, v) w of :func:`inverse_dynamics` need the forms' own passes."""
    tree = symbolic_tree(model, q, theta)
    if not tree.staged_applies():
        return None
    from .articulated import newton_euler_stages

    return newton_euler_stages(tree, qdot, qddot, baked(model.gravity, "gravity"), prefix)


def recursive_mass_matrix(model, q, theta, prefix: str = "crba"):
    """D(q) by composite rigid bodies in link frames: ``(D, stages)``
    (:func:`~hydrogen.symbolic.articulated.composite_body_stages`), on the trees
    :func:`recursive_forward_dynamics` takes, in either form; else None. The form's own D
    (:func:`mass_matrix`) is the one C, G and the controllers are derived with."""
    tree = symbolic_tree(model, q, theta)
    if not tree.staged_applies():
        return None
    from .articulated import composite_body_stages

    return composite_body_stages(tree, prefix)


def regressor(model, q, v, w, a, theta) -> sp.Matrix:
    """Y(q, v, w, a) (n×p) with Y θ + y0 = D(q) a + C(q, v) w + G(q) (y0: the parts of the
    non-adapted parameters; zero when θ holds every parameter that moves the robot).

    D, C and G are linear in the inertial parameters, so column k is the dynamics of a robot whose
    only parameter is θ_k = 1: small expressions, where differentiating the whole dynamics by θ
    costs SymPy seconds per controller on a serial arm."""
    p, g = len(model.theta_names), baked(model.gravity, "gravity")
    tree = symbolic_tree(model, q, theta)
    if tree.staged():  # one pass over the links' motion, each column one link's unit-parameter force
        return tree.staged_regressor(sp.Matrix(v), sp.Matrix(w), sp.Matrix(a), g, model.theta_names)
    cols = []
    for k in range(p):
        unit = [sp.S.One if i == k else sp.S.Zero for i in range(p)]
        cols.append(_dynamics_of(SymbolicTree(model, q, unit, baked_parameters=False), q, v, w, a, g))
    return sp.Matrix.hstack(*cols)


def regressor_offset(model, q, v, w, a, theta) -> sp.Matrix:
    """y0 = D a + C(q, v) w + G − Y θ: the non-adapted parameters' share (n), the dynamics at θ = 0."""
    zero = [sp.S.Zero] * len(model.theta_names)
    return _dynamics_of(SymbolicTree(model, q, zero), q, v, w, a, baked(model.gravity, "gravity"))


def coriolis_paper(q, qdot, theta) -> sp.Matrix:
    """C of eq. (64) for the floating platform, θ = [M_p, I_x, I_y, I_z]:
    c22 = Tᵀ S(ω) ᵇI T + Tᵀ ᵇI Ṫ (the right C q̇, but not property (ii))."""
    Mp, Ix, Iy, Iz = theta
    R = rotation(q)
    T = angular_velocity_map(q)
    Ib = R * sp.diag(Ix, Iy, Iz) * R.T
    eta_dot = sp.Matrix(qdot[3:])
    w = T * eta_dot
    S = sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    Tdot = sum((diff_matrix(T, q[k]) * qdot[k] for k in range(3, 6)), sp.zeros(3, 3))
    C = sp.zeros(6, 6)
    C[3:, 3:] = T.T * S * Ib * T + T.T * Ib * Tdot
    return C
