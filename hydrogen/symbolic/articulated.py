"""Featherstone's recursive algorithms, traced in SymPy with per-link stages.

q̈ = D(q)⁻¹ (τ − C(q, q̇) q̇ − G(q)) without forming D by the articulated-body algorithm (ABA,
*Rigid Body Dynamics Algorithms* 2008, Table 7.1: velocities and bias terms root to leaves,
articulated inertias and bias forces leaves to root, accelerations root to leaves); τ = D q̈ + C q̇ + G
by recursive Newton-Euler (Table 5.1) and D by composite rigid bodies (Table 6.2). All in local link
frames (each link's own axes and origin; motion vectors [ω; v], forces [n; f], Plücker
coordinates), on trees of revolute, prismatic and fixed joints; a link on a fixed joint is merged into
the body it is fixed to (:meth:`~hydrogen.symbolic.tree.SymbolicTree.link_inertia`), as Pinocchio does.

Every link's quantities are bound to intermediate symbols as they are computed (:func:`_bind`), so
each expression refers to its parent's or children's symbols, never to their expansions: the stages
and CasADi's instructions grow linearly with the number of links (a symbolic linear solve of D
grows as n³). Local frames keep the joint axes and the links' inertias constant (the parameters θ
and numbers), so their zeros fold, as in Pinocchio; the transform between a link and its parent
holds the joint's sine and cosine and the constant origin.

Gravity acts along −z of the base frame: the base accelerates up at g.
"""
from __future__ import annotations

import sympy as sp

from .tree import (_apply_inertia, _axis_rotation, _axis_vec, _cross, _cross_force, _cross_motion, _dot, _mm, _mul,
                   _rot_xyz, _vec)

__all__ = ["articulated_body_stages", "newton_euler_stages", "composite_body_stages"]


def articulated_body_stages(tree, qdot, tau, g, prefix: str = "aba"):
    """q̈ of ``tree`` (a :class:`~hydrogen.symbolic.tree.SymbolicTree`) at rates ``qdot`` (rad/s or
    m/s) and joint forces ``tau`` (N m or N), gravity ``g`` (m/s², along −z of the base frame):
    ``(qdd, stages)``, qdd an n×1 Matrix of symbols that ``stages`` (``(symbols, expression)`` pairs,
    evaluated in order) define. Symbol names start with ``prefix``."""
    return _Articulated(tree, sp.Matrix(qdot), sp.Matrix(tau), g, prefix).run()


def newton_euler_stages(tree, qdot, qddot, g, prefix: str = "rnea"):
    """τ = D(q) q̈ + C(q, q̇) q̇ + G(q) of ``tree`` by recursive Newton-Euler (Featherstone 2008,
    Table 5.1) in link frames, each link's velocity, acceleration and force (its subtree's) bound to
    symbols: ``(tau, stages)`` as :func:`articulated_body_stages`; τ in N m or N."""
    qdot, qddot = sp.Matrix(qdot), sp.Matrix(qddot)
    stages, root, joints = [], tree.model.root, tree.model.joints
    X = {j.child: _joint_transform(tree, j) for j in joints}
    S = {j.child: _motion_axis(j) for j in joints}
    vel, acc, force = {root: sp.zeros(6, 1)}, {root: sp.Matrix([0, 0, 0, 0, 0, g])}, {}
    for k, j in enumerate(joints):
        lk, i = j.child, tree.columns[j.name]
        v, a = X[lk].motion(vel[j.parent]), X[lk].motion(acc[j.parent])
        if j.dof:
            vJ = S[lk] * qdot[i]
            v = v + vJ
            a = a + S[lk] * qddot[i] + _cross_motion(v, vJ)
        vel[lk], acc[lk] = _bind(f"{prefix}_v{k}", v, stages), _bind(f"{prefix}_a{k}", a, stages)
        inertia = tree.link_inertia(lk)
        force[lk] = _apply_inertia(inertia, acc[lk]) + _cross_force(vel[lk], _apply_inertia(inertia, vel[lk]))
    tau = sp.zeros(tree.n, 1)
    for k in reversed(range(len(joints))):
        j = joints[k]
        lk = j.child
        force[lk] = _bind(f"{prefix}_f{k}", force[lk], stages)  # with its children's, added below
        if j.dof:
            tau[tree.columns[j.name]] = _dot(S[lk], force[lk])
        if j.parent != root:
            force[j.parent] = force[j.parent] + X[lk].force_up(force[lk])
    return tau, stages


def composite_body_stages(tree, prefix: str = "crba"):
    """D(q) (n×n, symmetric) of ``tree`` by composite rigid bodies (Featherstone 2008, Table 6.2) in
    link frames: ``(D, stages)`` as :func:`articulated_body_stages`. Each link's composite inertia
    (its subtree's, upper triangle) and each force F = I^c S carried up the path are bound to
    symbols; D_ij = S_jᵀ F (kg m², kg m or kg)."""
    stages, root, joints = [], tree.model.root, tree.model.joints
    X = {j.child: _joint_transform(tree, j) for j in joints}
    S = {j.child: _motion_axis(j) for j in joints}
    parent = {j.child: j for j in joints}
    Ic = {j.child: _inertia6(*tree.link_inertia(j.child)) for j in joints}
    D = sp.zeros(tree.n, tree.n)
    for k in reversed(range(len(joints))):
        j = joints[k]
        lk = j.child
        Ic[lk] = _bind(f"{prefix}_Ic{k}", Ic[lk], stages)  # with its children's, added below
        if j.dof:
            i = tree.columns[j.name]
            F = _bind(f"{prefix}_F{k}_{k}", _apply6(Ic[lk], S[lk]), stages)
            D[i, i] = _dot(S[lk], F)
            up = j
            while up.parent != root:  # the same force, seen by each joint above
                F = X[up.child].force_up(F)
                up = parent[up.parent]
                if up.dof:
                    F = _bind(f"{prefix}_F{k}_{joints.index(up)}", F, stages)
                    D[i, tree.columns[up.name]] = D[tree.columns[up.name], i] = _dot(S[up.child], F)
        if j.parent != root:
            Ic[j.parent] = Ic[j.parent] + X[lk].inertia_up(Ic[lk])
    return D, stages


class _Articulated:
    def __init__(self, tree, qdot, tau, g, prefix):
        self.tree, self.qdot, self.tau, self.g, self.prefix = tree, qdot, tau, g, prefix
        self.stages = []
        self.joints = tree.model.joints
        self.X = {j.child: _joint_transform(tree, j) for j in self.joints}
        self.S = {j.child: _motion_axis(j) for j in self.joints}

    def bind(self, name, values):
        return _bind(f"{self.prefix}_{name}", values, self.stages)

    def run(self):
        root = self.tree.model.root
        bias, IA, pA = self._outward(root)
        U, dinv, u = self._inward(root, bias, IA, pA)
        qdd = self._accelerations(root, bias, U, dinv, u)
        return qdd, self.stages

    def _outward(self, root):
        """Pass 1: link velocities v, bias accelerations c = v × S q̇ and forces pA = v ×* I v."""
        vel, bias, IA, pA = {root: sp.zeros(6, 1)}, {}, {}, {}
        for k, j in enumerate(self.joints):
            lk, X = j.child, self.X[j.child]
            v = X.motion(vel[j.parent])
            if j.dof:
                vJ = self.S[lk] * self.qdot[self.tree.columns[j.name]]
                v = self.bind(f"v{k}", v + vJ)
                bias[lk] = self.bind(f"c{k}", _cross_motion(v, vJ))
            else:
                v, bias[lk] = self.bind(f"v{k}", v), sp.zeros(6, 1)
            vel[lk] = v
            IA[lk] = _inertia6(*self.tree.link_inertia(lk))
            pA[lk] = _cross_force(v, _apply6(IA[lk], v))  # bound in pass 2, with the children's share
        return bias, IA, pA

    def _inward(self, root, bias, IA, pA):
        """Pass 2: per link, U = IA S, 1/d = 1/(Sᵀ U), u = τ − Sᵀ pA; the parent gets the
        articulated inertia Xᵀ (IA − U Uᵀ/d) X and force Xᵀ (pA + Ia c + U u/d)."""
        U, dinv, u = {}, {}, {}
        for k in reversed(range(len(self.joints))):
            j = self.joints[k]
            lk, X = j.child, self.X[j.child]
            IA[lk], pA[lk] = self.bind(f"IA{k}", IA[lk]), self.bind(f"pA{k}", pA[lk])
            if j.dof:
                s = self.S[lk]
                U[lk] = self.bind(f"U{k}", _apply6(IA[lk], s))
                dinv[lk] = self.bind(f"dinv{k}", sp.Matrix([1 / _dot(s, U[lk])]))[0]
                u[lk] = self.bind(f"u{k}", sp.Matrix([self.tau[self.tree.columns[j.name]] - _dot(s, pA[lk])]))[0]
                Ia = sp.Matrix(6, 6, lambda r, c: IA[lk][r, c] - _mul(_mul(U[lk][r], U[lk][c]), dinv[lk]))
                Ia = self.bind(f"Ia{k}", Ia)
                pa = self.bind(f"pa{k}", pA[lk] + _apply6(Ia, bias[lk]) + U[lk] * _mul(u[lk], dinv[lk]))
            else:
                Ia, pa = IA[lk], pA[lk]
            if j.parent != root:
                IA[j.parent] = IA[j.parent] + X.inertia_up(Ia)
                pA[j.parent] = pA[j.parent] + X.force_up(pa)
        return U, dinv, u

    def _accelerations(self, root, bias, U, dinv, u):
        """Pass 3: a = X a_parent + c, q̈ = (u − Uᵀ a)/d, a += S q̈; the root's a is g up."""
        acc = {root: sp.Matrix([0, 0, 0, 0, 0, self.g])}
        qdd = sp.zeros(self.tree.n, 1)
        for k, j in enumerate(self.joints):
            lk = j.child
            a = self.X[lk].motion(acc[j.parent]) + bias[lk]
            if j.dof:
                a = self.bind(f"a{k}", a)
                i = self.tree.columns[j.name]
                qdd[i] = self.bind(f"qdd{k}", sp.Matrix([_mul(u[lk] - _dot(U[lk], a), dinv[lk])]))[0]
                a = a + self.S[lk] * qdd[i]
            acc[lk] = self.bind(f"acc{k}", a)
        return qdd


def _bind(name, values, stages):
    """``values`` with each entry that is not a number or a symbol replaced by a new symbol
    ``name_i`` (row-major), their definitions appended to ``stages``; a symmetric 6×6 matrix binds
    its upper triangle once. Zeros stay exact, so the link frames' sparsity carries on."""
    values = sp.Matrix(values)
    out = sp.Matrix(values)
    symmetric = values.shape == (6, 6)
    syms, exprs = [], []
    for r in range(values.rows):
        for c in range(values.cols):
            if symmetric and c < r:
                out[r, c] = out[c, r]
                continue
            e = values[r, c]
            if e.is_Number or e.is_Symbol:
                continue
            s = sp.Symbol(f"{name}_{r * values.cols + c}", real=True)
            syms.append(s)
            exprs.append(e)
            out[r, c] = s
    if syms:
        stages.append((sp.Matrix(syms), sp.Matrix(exprs)))
    return out


def _motion_axis(j):
    """S (6×1, link frame): [a; 0] for a revolute joint, [0; a] for a prismatic one, none fixed."""
    a = _axis_vec(j.axis, f"{j.name}.axis")
    if j.type == "revolute":
        return sp.Matrix([*a, 0, 0, 0])
    if j.type == "prismatic":
        return sp.Matrix([0, 0, 0, *a])
    return sp.zeros(6, 1)


def _joint_transform(tree, j):
    """The transform from ``j``'s parent frame to its child's at the joint's coordinate: the child
    frame's rotation R = R_o R_joint(q) and origin r (parent coordinates, m), E = Rᵀ."""
    R_o, xyz = _rot_xyz(j.origin_rpy, f"{j.name}.origin_rpy"), _vec(j.origin_xyz, f"{j.name}.origin_xyz")
    if j.type == "revolute":
        R, r = _mm(R_o, _axis_rotation(j.axis, tree.q[tree.columns[j.name]], f"{j.name}.axis")), xyz
    elif j.type == "prismatic":
        R, r = R_o, xyz + _mm(R_o, _axis_vec(j.axis, f"{j.name}.axis")) * tree.q[tree.columns[j.name]]
    elif j.type == "fixed":
        R, r = R_o, xyz
    else:
        raise ValueError(f"joint '{j.name}': the articulated-body algorithm here takes revolute, prismatic "
                         f"and fixed joints, not {j.type}")
    return _Transform(sp.Matrix(R), sp.Matrix(r))


class _Transform:
    """Plücker transform parent → child: E = Rᵀ (parent coordinates into the child's), r the child's
    origin in parent coordinates."""

    def __init__(self, R, r):
        self.R, self.E, self.r = R, R.T, r
        self.Sr = sp.Matrix([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])

    def motion(self, m):
        """X m = [E ω; E (v − r × ω)]: a parent motion vector in child coordinates."""
        w, v = m[:3, 0], m[3:, 0]
        return sp.Matrix([*_rows(self.E, w), *_rows(self.E, v - _cross(self.r, w))])

    def force_up(self, f):
        """Xᵀ f = [R n + r × (R f); R f]: a child force in parent coordinates."""
        n, fl = _rows(self.R, f[:3, 0]), _rows(self.R, f[3:, 0])
        return sp.Matrix([*(n + _cross(self.r, fl)), *fl])

    def inertia_up(self, I):
        """Xᵀ I X for a symmetric 6×6 I = [[A, B], [Bᵀ, C]] (child coordinates): rotated blocks
        A' = R A Rᵀ, B' = R B Rᵀ, C' = R C Rᵀ, then the shift by r (S = S(r)):
        [[A' + S B'ᵀ − (B' + S C') S, B' + S C'], [·, C']]. Upper triangles only where symmetric."""
        A, B, C = I[:3, :3], I[:3, 3:], I[3:, 3:]
        R, S = self.R, self.Sr
        A, B, C = _product(R, _product(A, R.T), True), _product(R, _product(B, R.T)), \
            _product(R, _product(C, R.T), True)
        top = B + _product(S, C)
        TL = A + _product(S, B.T) - _product(top, S)
        TL = sp.Matrix(3, 3, lambda r, c: TL[min(r, c), max(r, c)])
        return sp.Matrix(sp.BlockMatrix([[TL, top], [top.T, C]]))


def _rows(M, x):
    """M x (3×3 by 3×1) as sums of nonzero products."""
    return sp.Matrix([_dot(M[r, :], x) for r in range(M.rows)])


def _product(P, Q, symmetric=False):
    """P Q entry by entry (zeros skipped); ``symmetric``: the result is known symmetric, so the
    lower triangle mirrors the upper one (one expression per pair)."""
    out = sp.zeros(P.rows, Q.cols)
    for r in range(P.rows):
        for c in range(Q.cols):
            if symmetric and c < r:
                out[r, c] = out[c, r]
            else:
                out[r, c] = _dot(P[r, :], Q[:, c])
    return out


def _inertia6(m, h, I):
    """The link's spatial inertia (link frame, about its origin) as a 6×6 matrix
    [[I_o, S(h)], [S(h)ᵀ, m 1]]: I_o kg m², h = m c kg m, m kg."""
    Sh = sp.Matrix([[0, -h[2], h[1]], [h[2], 0, -h[0]], [-h[1], h[0], 0]])
    return sp.Matrix(sp.BlockMatrix([[I, Sh], [Sh.T, m * sp.eye(3)]]))


def _apply6(M, x):
    """M x for a 6×6 M and a 6-vector x, zeros skipped."""
    return sp.Matrix([_dot(M[r, :], x) for r in range(6)])
