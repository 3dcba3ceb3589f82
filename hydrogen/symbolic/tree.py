"""The kinematic tree of a description, symbolically: link poses, Jacobians, D, G, cylinder lengths.

Any tree of revolute, prismatic, fixed and floating joints. Two forms of the same kinematics:

* closed form (:meth:`SymbolicTree.mass_matrix`, :meth:`SymbolicTree.potential`): every link's
  world rotation R, origin p and Jacobians as expressions of q, for D(q) and G(q), which are
  differentiated symbolically (Christoffel symbols, ∂V/∂q);
* staged (:meth:`SymbolicTree.cylinder_stages`): each link's R and p are intermediate symbols
  defined from its parent's, so the cylinders' lengths, JL and J̇L refer to a few symbols instead of
  expanded products of sines and cosines (CasADi evaluates the stages in order);
* the staged rigid body (:meth:`SymbolicTree.staged_mass_matrix`, ``staged_coriolis``,
  ``staged_gravity``, ``staged_inverse_dynamics``, ``staged_regressor``), on trees of revolute,
  prismatic and fixed joints, where it is the cheaper or the asked-for form (:meth:`SymbolicTree.staged`): spatial
  algebra (Featherstone's, base frame, Plücker coordinates about the base origin) over the same
  pose symbols, so its expressions grow polynomially with the depth where the closed form's grow
  about 3.5× per link. D by composite bodies, G from the composite first moments, and
  D a + C(q, v) w + G, C and Y by one Newton-Euler pass with a body Coriolis factor that gives the
  Christoffel C (see :meth:`SymbolicTree.staged_inverse_dynamics`).

Inertial parameters are Pinocchio's: mass m, first moment h = m c (link frame) and the inertia
I_o about the link origin (link axes). The adapted ones are the symbols θ; the others are baked
numbers. The kinetic energy of a link is ½ m |v_o|² + v_oᵀ R (ω_b × h) + ½ ω_bᵀ I_o ω_b, with v_o
the origin's velocity (base frame) and ω_b the angular velocity in link axes, so
D = Σ m J_vᵀ J_v − (X + Xᵀ) + J_ωᵀ I_o J_ω with X = J_vᵀ R S(h) J_ω, linear in the parameters.
"""
from __future__ import annotations

import sympy as sp

from ..tree import fixed_path
from .calculus import diff_matrix, jacobian, matmul
from .constants import baked
from .coordinates import angular_velocity_map, body_angular_velocity_map, matrix_symbols, rotation

__all__ = ["SymbolicTree", "skew"]


def skew(v) -> sp.Matrix:
    """S(v) with S(v) x = v × x."""
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _rot_xyz(rpy, name: str | None = None) -> sp.Matrix:
    """Origin rotation Rz(yaw) Ry(pitch) Rx(roll) of numbers (identity stays exact); ``name``: the
    numbers' place in the description (:func:`~hydrogen.symbolic.constants.baked`)."""
    if all(float(v) == 0.0 for v in rpy):
        return sp.eye(3)
    return rotation([0, 0, 0, *(baked(v, name and f"{name}[{k}]") for k, v in enumerate(rpy))])


def _axis_vec(axis, name: str | None = None) -> sp.Matrix:
    """A joint's unit axis (numbers): its entries 0, 1 and -1 exact in either mode, as the
    description's structure holds them (:meth:`hydrogen.model.Model.structure`): a coordinate axis is
    the joint's kind, as Pinocchio's RX/RY/RZ joints; any other entry a number."""
    return sp.Matrix([baked(a, name and f"{name}[{i}]") if float(a) not in (0.0, 1.0, -1.0) else sp.Integer(int(a))
                      for i, a in enumerate(axis)])


def _axis_rotation(axis, angle, name: str | None = None) -> sp.Matrix:
    """Rotation by ``angle`` about the unit ``axis`` (numbers); exact for coordinate axes."""
    K = skew(_axis_vec(axis, name))
    return sp.eye(3) + sp.sin(angle) * K + (1 - sp.cos(angle)) * K * K


_EYE = sp.eye(3)


def _mm(*factors):
    """The product of matrices, skipping exact identities (the root's rotation, an origin without
    rotation): multiplying large expressions by 1 and 0 costs SymPy seconds for nothing."""
    out = None
    for f in factors:
        if isinstance(f, sp.MatrixBase) and f.shape == (3, 3) and f == _EYE:
            continue
        out = f if out is None else matmul(out, f)
    return _EYE if out is None else out


def _vec(values, name: str | None = None) -> sp.Matrix:
    """A vector of numbers (zeros exact); ``name``: their place in the description."""
    return sp.Matrix([baked(v, name and f"{name}[{k}]") if float(v) != 0.0 else sp.S.Zero
                      for k, v in enumerate(values)])


class SymbolicTree:
    """Symbolic kinematics and rigid-body dynamics of ``model``'s tree at coordinates ``q``.

    ``theta`` are the symbols of the adapted parameters (``model.theta_names`` order).
    """

    def __init__(self, model, q, theta, baked_parameters: bool = True):
        self.model = model
        self._form = None  # "closed" or "staged", resolved on first use (:meth:`form`)
        self.q = sp.Matrix(q)
        self.n = len(self.q)
        subst = dict(zip(model.theta_names, list(theta)))
        self.params = {}
        for lk in model.links:
            values = lk.parameters()
            # baked_parameters=False zeroes every parameter that is not adapted: the share of θ alone
            p = {k: subst.get(f"{lk.name}.{k}",
                              baked(v, f"{lk.name}.{k}") if v != 0.0 and baked_parameters else sp.S.Zero)
                 for k, v in values.items()}
            self.params[lk.name] = p
        self.columns = {}  # joint name -> first coordinate index
        i = 0
        for j in model.joints:
            self.columns[j.name] = i
            i += j.dof
        self.parent_joint = {j.child: j for j in model.joints}
        self._closed = None

    # --- paths ----------------------------------------------------------------------------
    def path(self, link: str) -> list:
        """Joints from the root down to ``link``."""
        out = []
        while link in self.parent_joint:
            j = self.parent_joint[link]
            out.append(j)
            link = j.parent
        return out[::-1]

    def single_floating_body(self) -> bool:
        """True for one floating body on the root with its frame at its centre of mass, whose mass
        matrix has a closed-form inverse (the Stewart platform's structure): the only moving joint,
        every other link fixed to that body (merged into it, :meth:`bodies`: a massless sensor frame
        leaves it at its centre of mass) or to the root (it never moves)."""
        moving = [j for j in self.model.joints if j.type != "fixed"]
        if len(moving) != 1 or moving[0].type != "floating" or moving[0].parent != self.model.root:
            return False
        _, h, I = self.bodies()[moving[0].child]
        return all(x is sp.S.Zero for x in (*h, I[0, 1], I[0, 2], I[1, 2])) \
            and all(float(v) == 0.0 for v in (*moving[0].origin_rpy,))

    # --- closed form ----------------------------------------------------------------------
    def closed_form(self) -> dict:
        """Per link: world rotation R, origin p, J_v (3×n, base frame) and J_ω (3×n, link axes)."""
        if self._closed is not None:
            return self._closed
        n, q = self.n, self.q
        root = self.model.root
        out = {root: (sp.eye(3), sp.zeros(3, 1), sp.zeros(3, n), sp.zeros(3, n), sp.zeros(3, n))}
        for j in self.model.joints:
            R_p, p_p, Jv_p, Jw_p, Jww_p = out[j.parent]  # Jww: angular velocity Jacobian, base frame
            R_o, xyz = _rot_xyz(j.origin_rpy, f"{j.name}.origin_rpy"), _vec(j.origin_xyz, f"{j.name}.origin_xyz")
            i = self.columns[j.name]
            lever = _mm(R_p, xyz)
            # the child origin's offset from the parent's: a prismatic or floating joint's own
            # displacement moves it too (the lever of the ancestors' angular velocity)
            arm = lever
            if j.type == "prismatic":
                arm = lever + _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis")) * q[i]
            elif j.type == "floating":
                arm = lever + _mm(R_p, q[i:i + 3, 0])
            Jv = Jv_p - skew(arm) * Jww_p if any(x != 0 for x in arm) and any(x != 0 for x in Jww_p) else Jv_p
            Jv, Jww = sp.Matrix(Jv), sp.Matrix(Jww_p)
            if j.type == "revolute":
                R_rel = _mm(R_o, _axis_rotation(j.axis, q[i], f"{j.name}.axis"))
                R, p = _mm(R_p, R_rel), p_p + lever
                a_w = _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis"))
                Jww[:, i] = Jww[:, i] + a_w
                Jw = _mm(R_rel.T, Jw_p)
                Jw[:, i] = Jw[:, i] + _axis_vec(j.axis, f"{j.name}.axis")
            elif j.type == "prismatic":
                R, p = _mm(R_p, R_o), p_p + lever + _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis")) * q[i]
                Jv[:, i] = Jv[:, i] + _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis"))
                Jw = _mm(R_o.T, Jw_p)
            elif j.type == "floating":
                eta = q[i + 3:i + 6, 0]
                R_rel = _mm(R_o, rotation([0, 0, 0, *eta]))
                R, p = _mm(R_p, R_rel), p_p + lever + _mm(R_p, q[i:i + 3, 0])
                Jv[:, i:i + 3] = Jv[:, i:i + 3] + R_p
                Jww[:, i + 3:i + 6] = Jww[:, i + 3:i + 6] + _mm(R_p, R_o, angular_velocity_map([0, 0, 0, *eta]))
                Jw = _mm(R_rel.T, Jw_p)
                Jw[:, i + 3:i + 6] = Jw[:, i + 3:i + 6] + body_angular_velocity_map([0, 0, 0, *eta])
            else:  # fixed
                R, p, Jw = _mm(R_p, R_o), p_p + lever, _mm(R_o.T, Jw_p)
            out[j.child] = (R, p, Jv, Jw, Jww)
        self._closed = out
        return out

    def _inertia(self, link, unit=None):
        p = self.params[link] if unit is None else {k: unit.get(k, sp.S.Zero) for k in self.params[link]}
        h = sp.Matrix([p["mcx"], p["mcy"], p["mcz"]])
        I = sp.Matrix([[p["Ixx"], p["Ixy"], p["Ixz"]], [p["Ixy"], p["Iyy"], p["Iyz"]],
                       [p["Ixz"], p["Iyz"], p["Izz"]]])
        return p["mass"], h, I

    def mass_matrix(self) -> sp.Matrix:
        """D(q) (n×n), linear in the inertial parameters (made once; a copy each call)."""
        if getattr(self, "_closed_D", None) is None:
            self._closed_D = self._mass_matrix()
        return self._closed_D.copy()

    def mass_matrix_partials(self) -> list:
        """∂D/∂q_k (n×n each) for every coordinate k, made once: the Christoffel C of every pair of
        velocities (C(q, q̇), C(q, v) for v ≠ q̇) differentiates the same D."""
        if getattr(self, "_closed_dD", None) is None:
            D = self.mass_matrix()
            self._closed_dD = [diff_matrix(D, self.q[k]) for k in range(self.n)]
        return [d.copy() for d in self._closed_dD]

    def carriers(self) -> dict:
        """Per link, ``(body, R, r)``: the link whose frame it is fixed in through fixed joints (itself
        when its own joint moves, or when it is fixed to the root: it never moves), and its pose
        there, rotation R and origin r (m, the body's frame)."""
        if getattr(self, "_carriers", None) is not None:
            return self._carriers
        root = self.model.root

        def carrier(link):
            R, r = sp.eye(3), sp.zeros(3, 1)
            path = fixed_path(self.parent_joint, link)
            for j in path[:-1] if path and path[-1].parent == root else path:  # a link fixed to the root stays
                R_o, xyz = _rot_xyz(j.origin_rpy, f"{j.name}.origin_rpy"), _vec(j.origin_xyz, f"{j.name}.origin_xyz")
                R, r = _mm(R_o, R), xyz + _mm(R_o, r)
                link = j.parent
            return link, R, r

        self._carriers = {lk.name: carrier(lk.name) for lk in self.model.links}
        return self._carriers

    def bodies(self) -> dict:
        """The rigid bodies of the closed form: ``{link: (m, h, I_o)}``, Pinocchio's parameters of each
        link (kg, kg m, kg m²; its frame, I_o about its origin) with every link fixed to it below
        (through fixed joints, a payload, a bracket, a sensor housing) merged in, as Pinocchio's URDF
        reader does; those links are no body of their own. A link fixed to the root stays as it is
        (it never moves). One body of the merged parameters has the same D and G as its parts, and
        expressions the size of one link's: the payload's own Jacobians are never formed."""
        if getattr(self, "_bodies", None) is not None:
            return self._bodies
        placed = self.carriers()
        out = {name: list(self._inertia(name)) for name, (body, _, _) in placed.items() if body == name}
        for name, (body, R, r) in placed.items():
            if body == name:
                continue
            # the child's parameters in the body's frame: m; h + m r + R h_c; about the body's origin
            # I_o = R I_c Rᵀ − S(r) S(R h_c) − S(R h_c) S(r) − m_c S(r)²
            m_c, h_c, I_c = self._inertia(name)
            m, h, I = out[body]
            h_r = _mm(R, h_c)
            Sr, Sh = skew(r), skew(h_r)
            out[body] = [m + m_c, h + m_c * r + h_r,
                         I + _mm(R, I_c, R.T) - matmul(Sr, Sh) - matmul(Sh, Sr) - m_c * matmul(Sr, Sr)]
        self._bodies = {k: (sp.sympify(m), sp.Matrix(h), sp.Matrix(I)) for k, (m, h, I) in out.items()}
        return self._bodies

    def link_inertia(self, link: str):
        """``(m, h, I_o)`` of ``link`` in its own frame for the recursive algorithms: a body's with the
        links fixed to it merged in (:meth:`bodies`), zero for a link merged into another (its motion
        is its body's; its inertia is counted there)."""
        bodies = self.bodies()
        return bodies[link] if link in bodies else (sp.S.Zero, sp.zeros(3, 1), sp.zeros(3, 3))

    def _mass_matrix(self) -> sp.Matrix:
        cf = self.closed_form()
        D = sp.zeros(self.n, self.n)
        for link, (m, h, I) in self.bodies().items():
            R, _, Jv, Jw, _ = cf[link]
            D += m * matmul(Jv.T, Jv) + matmul(Jw.T, I, Jw)
            if any(x != 0 for x in h):
                X = matmul(Jv.T, R, skew(h), Jw)
                D -= X + X.T
        return D

    def potential(self, g) -> sp.Expr:
        """V(q) = g Σ (m p_z + (R h)_z): potential energy with gravity ``g`` along −z, J."""
        cf = self.closed_form()
        V = sp.S.Zero
        for link, (m, h, _) in self.bodies().items():
            R, p, _, _, _ = cf[link]
            V += m * p[2] + (R[2, :] * h)[0, 0]
        return g * V

    def gravity(self, g) -> sp.Matrix:
        """G(q) = ∂V/∂q (n), N or N m."""
        return jacobian([self.potential(g)], self.q).T

    def mass_matrix_inverse(self):
        """D⁻¹ in closed form for a single floating body at its centre of mass (block structure:
        m⁻¹ I and T_b⁻¹ I_o⁻¹ T_b⁻ᵀ, det T_b = cos θ), else None (solve numerically)."""
        if not self.single_floating_body():
            return None
        j = next(j for j in self.model.joints if j.type != "fixed")
        i = self.columns[j.name]
        m, _, I = self.bodies()[j.child]
        psi, th = self.q[i + 3], self.q[i + 4]
        c, s, ct, tt = sp.cos(psi), sp.sin(psi), sp.cos(th), sp.tan(th)
        Tb_inv = sp.Matrix([[1, s * tt, c * tt], [0, c, -s], [0, s / ct, c / ct]])
        Dinv = sp.zeros(self.n, self.n)
        Dinv[i:i + 3, i:i + 3] = sp.eye(3) / m
        Dinv[i + 3:i + 6, i + 3:i + 6] = Tb_inv * sp.diag(1 / I[0, 0], 1 / I[1, 1], 1 / I[2, 2]) * Tb_inv.T
        return Dinv

    # --- staged cylinder kinematics -------------------------------------------------------
    def cylinder_stages(self, prefix: str = "", qdot=None):
        """Cylinder lengths and JL as intermediate symbols: ``(l, JL, stages, link_stages)``.

        ``stages`` lists ``(symbols, expression)`` pairs to evaluate in order: the rotation R (and,
        below the first level, the origin p) of every link a cylinder hangs on or hangs below,
        then l_i = ‖v_i‖, v_i the vector between the pins, then row i of JL: n_iᵀ (J_B − J_A) with
        n_i = v_i / l_i and J the velocity Jacobian of each pin (a cylinder on a four-bar linkage: the
        linkage's l(q) of its joint's angle and dl/dq, :mod:`hydrogen.symbolic.linkage`). A revolute joint contributes
        a·(r × n) (a its axis, r from the joint to the pin), a prismatic one a·n, a floating one
        [R_pᵀ n, Tᵀ R_pᵀ (r × n)]; joints on both pins' paths cancel and are skipped.
        ``link_stages`` maps each staged link to (R symbols, p symbols or expression, ω expression,
        parent), for the time derivative.
        """
        model = self.model
        self._qdot = None if qdot is None else sp.Matrix(qdot)
        m_cyl = len(model.cylinders)
        needed = set()
        for c in model.cylinders:
            for link in (c.link_from, c.link_to):
                needed |= {j.child for j in self.path(link)}
        if self.staged():
            # the staged rigid body refers to every link's pose: one set of pose symbols for both
            needed |= {j.child for j in model.joints}
        poses, stages, link_stages = self._pose_stages(needed, prefix)
        l = sp.Matrix([sp.Symbol(f"{prefix}legl_{i}", real=True) for i in range(m_cyl)])
        JL = matrix_symbols(f"{prefix}JL", m_cyl, self.n)
        l_value, rows = [], []
        for ci, c in enumerate(model.cylinders):
            if c.joint is not None:  # a joint actuator: its coordinate is the joint's, its row a unit vector
                col = self.columns[c.joint]
                l_value.append(self.q[col])
                rows.append(sp.Matrix([[sp.S.One if k == col else sp.S.Zero for k in range(self.n)]]))
                continue
            if c.linkage is not None:  # a four-bar linkage: l(q) and dl/dq of its joint's angle alone
                from .linkage import four_bar_length
                col = self.columns[c.linkage_joint]
                l_link, dl_link, _ = four_bar_length(c.linkage, self.q[col], c.name)
                l_value.append(l_link)
                rows.append(sp.Matrix([[dl_link if k == col else sp.S.Zero for k in range(self.n)]]))
                continue
            R_a, p_a, _ = poses[c.link_from]
            R_b, p_b, _ = poses[c.link_to]
            r_b = _mm(R_b, _vec(c.point_to, f"{c.name}.to"))
            r_a = _mm(R_a, _vec(c.point_from, f"{c.name}.from"))
            v = p_b + r_b - (p_a + r_a)
            l_value.append(sp.sqrt(v.dot(v)))
            nvec = v / l[ci]
            row = sp.zeros(1, self.n)
            path_a, path_b = self.path(c.link_from), self.path(c.link_to)
            common = {j.name for j in path_a} & {j.name for j in path_b}
            for sign, path, link, r_local in ((1, path_b, c.link_to, r_b), (-1, path_a, c.link_from, r_a)):
                for j in path:
                    if j.name in common:
                        continue
                    row += sign * self._row_part(j, link, r_local, nvec, poses)
            rows.append(row)
        stages += [(l, sp.Matrix(l_value)), (JL, sp.Matrix.vstack(*rows))]
        return l, JL, stages, link_stages

    def _pose_stages(self, needed, prefix: str):
        """Poses of the links in ``needed`` as stages: ``(poses, stages, link_stages)``; ``poses`` maps
        each link (and the root) to (R, p, ω): R and p symbols (p an expression of q on the root's
        children), ω the angular velocity (base frame) as an expression of q̇."""
        model, q = self.model, self.q
        poses = {model.root: (sp.eye(3), sp.zeros(3, 1), sp.zeros(3, 1))}  # R, p, ω (base frame)
        stages, link_stages = [], {}
        for k, j in enumerate(model.joints):
            if j.child not in needed:
                continue
            R_p, p_p, w_p = poses[j.parent]
            R_o, xyz = _rot_xyz(j.origin_rpy, f"{j.name}.origin_rpy"), _vec(j.origin_xyz, f"{j.name}.origin_xyz")
            i = self.columns[j.name]
            lever = _mm(R_p, xyz)
            if j.type == "revolute":
                R_val = _mm(R_p, R_o, _axis_rotation(j.axis, q[i], f"{j.name}.axis"))
                p_val = p_p + lever
                w = w_p + _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis")) * self._rate(i)
            elif j.type == "prismatic":
                R_val = _mm(R_p, R_o)
                p_val = p_p + lever + _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis")) * q[i]
                w = w_p
            elif j.type == "floating":
                eta = q[i + 3:i + 6, 0]
                R_val = _mm(R_p, R_o, rotation([0, 0, 0, *eta]))
                p_val = p_p + lever + _mm(R_p, q[i:i + 3, 0])
                w = w_p + _mm(R_p, R_o, angular_velocity_map([0, 0, 0, *eta])) * self._rates(i + 3, 3)
            else:
                R_val, p_val, w = _mm(R_p, R_o), p_p + lever, w_p
            tag = f"{prefix}{k}" if len(model.joints) > 1 else prefix
            R = matrix_symbols(f"R{tag}", 3, 3)
            stages.append((R, R_val))
            if j.parent == model.root:
                p = p_val  # an expression of q: nothing to stage
            else:
                p = matrix_symbols(f"p{tag}", 3, 1)
                stages.append((p, p_val))
            poses[j.child] = (R, p, w)
            link_stages[j.child] = (R, p, w, j)
        return poses, stages, link_stages

    def _rate(self, i):
        qdot = getattr(self, "_qdot", None)
        return sp.Symbol(f"qdot_{i}", real=True) if qdot is None else qdot[i]

    def _rates(self, i, k):
        return sp.Matrix([self._rate(i + t) for t in range(k)])

    def _row_part(self, j, link, r_local, nvec, poses):
        """Contribution of joint ``j`` to n · (velocity of a pin on ``link``), a 1×n row."""
        R_c, p_c, _ = poses[j.child]
        R_p, _, _ = poses[j.parent]
        p_l = poses[link][1]
        r = r_local if j.child == link else r_local + (p_l - p_c)
        i = self.columns[j.name]
        part = sp.zeros(1, self.n)
        R_o = _rot_xyz(j.origin_rpy, f"{j.name}.origin_rpy")
        if j.type == "revolute":
            a = _mm(R_c, _axis_vec(j.axis, f"{j.name}.axis"))  # the axis is fixed by the rotation about it
            part[0, i] = a.dot(r.cross(nvec))
        elif j.type == "prismatic":
            part[0, i] = _mm(R_p, R_o, _axis_vec(j.axis, f"{j.name}.axis")).dot(nvec)
        elif j.type == "floating":
            eta = self.q[i + 3:i + 6, 0]
            T = angular_velocity_map([0, 0, 0, *eta])
            part[0, i:i + 3] = _mm(R_p.T, nvec).T
            part[0, i + 3:i + 6] = _mm(T.T, _mm(R_p, R_o).T, r.cross(nvec)).T
        return part

    # --- staged rigid body ----------------------------------------------------------------
    def depth(self) -> int:
        """The most moving joints on one path from the root (the chain's length)."""
        return max((sum(1 for j in self.path(lk.name) if j.dof) for lk in self.model.links), default=0)

    def staged_applies(self) -> bool:
        """Whether the staged form can represent this tree: revolute, prismatic and fixed joints only
        (its motion axes S have no floating joint's six columns)."""
        return all(j.type in ("revolute", "prismatic", "fixed") for j in self.model.joints)

    def form(self) -> str:
        """The rigid body's form, "closed" or "staged": the description's ``rigid_body_form``, or
        for "auto" the cheaper one (:func:`hydrogen.symbolic.forms.rigid_body_form`), as the model
        gives it (:meth:`hydrogen.model.Model.rigid_body_form_chosen`): choosing derives trees of
        both forms, so the choice is made above the tree and handed down with the model."""
        if self._form is None:
            self._form = self.model.rigid_body_form_chosen()
        return self._form

    def staged(self) -> bool:
        """Whether D, C, G and Y are computed from staged link poses (spatial algebra over the tree)
        rather than from the closed form (:meth:`form`). The closed form's expressions grow about 3.5×
        per link of depth (products of every ancestor's sines and cosines, then differentiated for C);
        the staged ones grow polynomially, but can cost more instructions on short chains."""
        return self.form() == "staged"

    def _staged_poses(self):
        """Every link's (R, p) as the symbols of :meth:`cylinder_stages` (prefix ""), and their stages."""
        if getattr(self, "_staged_cache", None) is None:
            poses, stages, _ = self._pose_stages({j.child for j in self.model.joints}, "")
            self._staged_cache = ({k: v[:2] for k, v in poses.items()}, stages)
        return self._staged_cache

    def pose_stages(self) -> list:
        """The ``(symbols, expression)`` stages the staged rigid body refers to (every link's R, p)."""
        return list(self._staged_poses()[1])

    def motion_axes(self) -> dict:
        """Per moving joint, its motion axis S (6×1, base frame, Plücker coordinates about the base
        origin: [ω; velocity of the body point at the origin] per unit rate): [a; p × a] for a revolute
        joint (a the world axis, p the child's origin, on the axis), [0; a] for a prismatic one."""
        if getattr(self, "_axes", None) is not None:
            return self._axes
        poses = self._staged_poses()[0]
        out = {}
        for j in self.model.joints:
            if not j.dof:
                continue
            R, p = poses[j.child]
            a = _mm(R, _axis_vec(j.axis, f"{j.name}.axis"))  # the child's rotation about its axis leaves the axis fixed
            out[j.name] = sp.Matrix([*a, *p.cross(a)]) if j.type == "revolute" else sp.Matrix([0, 0, 0, *a])
        self._axes = out
        return out

    def spatial_inertia(self, link: str, unit=None):
        """The link's inertia about the base origin, base axes: (m, c, Ī) with c = m p + R h the first
        moment (kg m) and Ī = R I_o Rᵀ − m S(p)² − S(p) S(R h) − S(R h) S(p) (kg m²); linear in the
        parameters. As a 6×6 matrix: [[Ī, S(c)], [S(c)ᵀ, m 1]]. ``unit`` ({name: 1}) replaces the
        link's parameters by that one alone (a regressor column)."""
        cache = self.__dict__.setdefault("_spatial", {})
        key = (link, None if unit is None else tuple(unit))
        if key in cache:
            return cache[key]
        R, p = self._staged_poses()[0][link]
        m, h, I = self._inertia(link, unit)
        Rh = _mm(R, h) if any(x != 0 for x in h) else sp.zeros(3, 1)
        Sp, SRh = skew(p), skew(Rh)
        Ibar = _mm(R, I, R.T) - m * Sp * Sp - Sp * SRh - SRh * Sp
        cache[key] = (m, sp.Matrix([_scale(m, x) for x in p]) + Rh, Ibar)
        return cache[key]

    def _is_body(self, link: str) -> bool:
        """Whether ``link`` carries the forces of the links fixed to it (:meth:`carriers`)."""
        return self.carriers()[link][0] == link

    def body_inertia(self, link: str):
        """The spatial inertia (:meth:`spatial_inertia`) of body ``link`` and every link fixed to it
        (:meth:`carriers`), summed in the base frame: they share its motion, so one force of the sum
        is theirs (the Newton-Euler pass forms one force per body, as Pinocchio's merged bodies)."""
        cache = self.__dict__.setdefault("_body_spatial", {})
        if link not in cache:
            members = [lk for lk, (body, _, _) in self.carriers().items() if body == link]
            m, c, I = self.spatial_inertia(members[0])
            for lk in members[1:]:
                mk, ck, Ik = self.spatial_inertia(lk)
                m, c, I = m + mk, c + ck, I + Ik
            cache[link] = (m, c, I)
        return cache[link]

    def staged_mass_matrix(self) -> sp.Matrix:
        """D(q) by composite rigid bodies: D_ij = S_iᵀ I^c_k S_j, k the deeper of joints i and j on one
        path, I^c_k the inertia of the subtree below joint k (base frame)."""
        S, comp = self.motion_axes(), self._composites()
        D = sp.zeros(self.n, self.n)
        for j in self.model.joints:
            if not j.dof:
                continue
            F = _apply_inertia(comp[j.child], S[j.name])
            c = self.columns[j.name]
            for i in self.path(j.child):
                if i.dof:
                    D[self.columns[i.name], c] = D[c, self.columns[i.name]] = _dot(S[i.name], F)
        return D

    def staged_gravity(self, g) -> sp.Matrix:
        """G(q) = ∂V/∂q: G_i = S_iᵀ I^c_i [0, 0, 0, 0, 0, g] (the base accelerating up at g), N or N m."""
        S, comp = self.motion_axes(), self._composites()
        G = sp.zeros(self.n, 1)
        for j in self.model.joints:
            if j.dof:
                m, c, _ = comp[j.child]
                s = S[j.name]
                G[self.columns[j.name]] = _scale(g, s[0] * c[1] - s[1] * c[0] + m * s[5])
        return G

    def staged_coriolis(self, v) -> sp.Matrix:
        """Christoffel C(q, v): column j is :meth:`staged_inverse_dynamics` at w = e_j, a = 0, g = 0,
        summed per link as f_L = I_L (v_j × S_j) + B_L(v_L) S_j on the links below joint j; see there."""
        S, vel = self.motion_axes(), self._velocities(v)
        C = sp.zeros(self.n, self.n)
        below = self._subtrees()
        for j in self.model.joints:
            if not j.dof:
                continue
            s, c = S[j.name], self.columns[j.name]
            dS = _cross_motion(vel[j.child], s)  # Ṡ_j at rate v
            f = {lk: _apply_inertia(self.body_inertia(lk), dS) + _b_term(self.body_inertia(lk), vel[lk], s)
                 for lk in below[j.child] if self._is_body(lk)}
            # rows: the joints above j (and j) see every link below j; joints below j their own subtree
            total = _sum6(f.values())
            for i in self.path(j.child):
                if i.dof:
                    C[self.columns[i.name], c] = _dot(S[i.name], total)
            for i in self.model.joints:
                if i.dof and i.child in below[j.child] and i.child != j.child:
                    C[self.columns[i.name], c] = _dot(S[i.name], _sum6(f[lk] for lk in below[i.child] if lk in f))
        return C

    def staged_inverse_dynamics(self, v, w, a, g) -> sp.Matrix:
        """τ = D(q) a + C(q, v) w + G(q) with the Christoffel C, by one Newton-Euler pass (n).

        Forward, per link L (base frame, Plücker about the base origin): the velocities v_L, w_L of
        the rates v and w, the acceleration α_L = Σ S_j a_j + [0, 0, 0, 0, 0, g] and the bias
        ζ_L = Σ (v_j × S_j) w_j (v_j the velocity of joint j's child, so v_j × S_j = Ṡ_j at rate v);
        the force f_L = I_L (α_L + ζ_L) + B_L(v_L) w_L with the body Coriolis factor
        B(v) x = ½ [v ×* (I x) − I (v × x) + x ×* (I v)]. Backward: τ_i = S_iᵀ Σ_{L below i} f_L.
        At w = v this is Newton-Euler (B(v) v = v ×* I v); the f's difference under v ↔ w is
        I (v × w) − I (v × w) = 0, so C(q, v) w = C(q, w) v: the unique C with that symmetry and
        the right C(q, q̇) q̇, the Christoffel one (Echeandia & Wensing 2021 give this factorisation).
        İ − 2B(v) = −(I v) ×̄* is skew, so Ḋ − 2C is skew."""
        motion = self._link_motion(v, w, a, g)
        force = {lk: _apply_inertia(self.body_inertia(lk), acc) + _b_term(self.body_inertia(lk), vv, ww)
                 for lk, (acc, vv, ww) in motion.items() if self._is_body(lk)}
        S, root = self.motion_axes(), self.model.root
        tau = sp.zeros(self.n, 1)
        total = {lk: force[lk] if lk in force else _zero6() for lk in motion}
        for j in reversed(self.model.joints):
            if j.parent != root:
                total[j.parent] = total[j.parent] + total[j.child]
            if j.dof:
                tau[self.columns[j.name]] = _dot(S[j.name], total[j.child])
        return tau

    def staged_regressor(self, v, w, a, g, names) -> sp.Matrix:
        """Y (n×p): column k is :meth:`staged_inverse_dynamics` of a robot whose only parameter is the
        one named ``names[k]`` ("link.parameter"), set to 1: that link's force f = I (α + ζ) + B(v) w
        with its unit inertia, on the joints above it. The links' motion is computed once."""
        motion, S = self._link_motion(v, w, a, g), self.motion_axes()
        Y = sp.zeros(self.n, len(names))
        for k, name in enumerate(names):
            link, par = name.rsplit(".", 1)
            inertia = self.spatial_inertia(link, {par: sp.S.One})
            acc, vv, ww = motion[link]
            f = _apply_inertia(inertia, acc) + _b_term(inertia, vv, ww)
            for j in self.path(link):
                if j.dof:
                    Y[self.columns[j.name], k] = _dot(S[j.name], f)
        return Y

    def _link_motion(self, v, w, a, g) -> dict:
        """Per link: (α + ζ, v_L, w_L) of :meth:`staged_inverse_dynamics` (base frame)."""
        S, vv, ww = self.motion_axes(), self._velocities(v), self._velocities(w)
        root = self.model.root
        acc = {root: sp.Matrix([0, 0, 0, 0, 0, g])}
        bias = {root: _zero6()}
        out = {}
        for j in self.model.joints:
            acc[j.child], bias[j.child] = acc[j.parent], bias[j.parent]
            if j.dof:
                i, s = self.columns[j.name], S[j.name]
                acc[j.child] = acc[j.child] + s * a[i]
                bias[j.child] = bias[j.child] + _cross_motion(vv[j.parent], s) * w[i]
            out[j.child] = (acc[j.child] + bias[j.child], vv[j.child], ww[j.child])
        return out

    def _velocities(self, rates) -> dict:
        """Per link, its spatial velocity (6×1, base frame) for joint rates ``rates``."""
        S = self.motion_axes()
        out = {self.model.root: _zero6()}
        for j in self.model.joints:
            out[j.child] = out[j.parent] + S[j.name] * rates[self.columns[j.name]] if j.dof else out[j.parent]
        return out

    def _subtrees(self) -> dict:
        """Per link, the links at or below it (tree order)."""
        out = {}
        for lk in [self.model.root] + [j.child for j in self.model.joints]:
            for above in [lk] + [j.parent for j in self.path(lk)]:
                out.setdefault(above, []).append(lk)
        return out

    def _composites(self) -> dict:
        """Per link, the inertia (m, c, Ī) of the subtree at or below it (base frame)."""
        out = {}
        for j in reversed(self.model.joints):
            m, c, I = self.spatial_inertia(j.child)
            for k in (x.child for x in self.model.joints if x.parent == j.child):
                mk, ck, Ik = out[k]
                m, c, I = m + mk, c + ck, I + Ik
            out[j.child] = (m, c, I)
        return out


def _zero6():
    return sp.zeros(6, 1)


def _sum6(vectors):
    out = _zero6()
    for x in vectors:
        out = out + x
    return out


# The products below skip exact zeros themselves: SymPy's 0 · x asks whether x is finite, which on a
# long expression walks it through the assumptions system (seconds per controller on a deep chain).
def _mul(a, b):
    return sp.S.Zero if a is sp.S.Zero or b is sp.S.Zero else a * b


def _cross(a, b):
    return sp.Matrix([sp.Add(_mul(a[1], b[2]), -_mul(a[2], b[1])), sp.Add(_mul(a[2], b[0]), -_mul(a[0], b[2])),
                      sp.Add(_mul(a[0], b[1]), -_mul(a[1], b[0]))])


def _cross_motion(v, m):
    """v × m for motion vectors [ω; u] (6×1)."""
    w, u, w2, u2 = v[:3, 0], v[3:, 0], m[:3, 0], m[3:, 0]
    return sp.Matrix([*_cross(w, w2), *(_cross(w, u2) + _cross(u, w2))])


def _cross_force(v, f):
    """v ×* f for a motion vector v = [ω; u] and a force f = [n; f_l] (6×1)."""
    w, u, n, fl = v[:3, 0], v[3:, 0], f[:3, 0], f[3:, 0]
    return sp.Matrix([*(_cross(w, n) + _cross(u, fl)), *_cross(w, fl)])


def _apply_inertia(inertia, x):
    """I x for the spatial inertia (m, c, Ī) and a motion vector x = [ω; u]: [Ī ω + c × u; m u − c × ω]."""
    m, c, I = inertia
    w, u = x[:3, 0], x[3:, 0]
    Iw = [_dot(I[r, :], w) for r in range(3)]  # not Matrix * Matrix: its zero tests query SymPy's assumptions
    return sp.Matrix([*(sp.Matrix(Iw) + _cross(c, u)), *(sp.Matrix([_scale(m, x) for x in u]) - _cross(c, w))])


def _b_term(inertia, v, x):
    """B(v) x = ½ [v ×* (I x) − I (v × x) + x ×* (I v)], the body's Coriolis factor (Christoffel)."""
    v = v / 2  # B is linear in v: halving v's short entries, not the long sum
    return (_cross_force(v, _apply_inertia(inertia, x)) - _apply_inertia(inertia, _cross_motion(v, x))
            + _cross_force(x, _apply_inertia(inertia, v)))


def _scale(k, e):
    """k e without SymPy distributing a number k over a long sum e (one product, not one per term)."""
    k = sp.sympify(k)
    if k is sp.S.Zero or e is sp.S.Zero:
        return sp.S.Zero
    if k.is_Number and isinstance(e, sp.Add):
        return sp.Mul(k, e, evaluate=False)
    return k * e


def _dot(a, b):
    """aᵀ b of two columns, as one sum."""
    return sp.Add(*[x * y for x, y in zip(a, b) if x is not sp.S.Zero and y is not sp.S.Zero])
