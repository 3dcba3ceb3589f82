"""Hydrogen's rigid body against the recursive algorithms Pinocchio implements, in CasADi instructions.

For the planar chain of ``bench_scaling.py`` (:func:`bench_scaling.chain_model`), n = 2 ... 16 (2 ... 4
with ``--quick``): hydrogen's ``forward_dynamics``, ``inverse_dynamics`` and ``mass_matrix`` (the
derivation's own path: ``rigid_body_functions``, then ``casadi_function`` with CSE) against
Featherstone's articulated-body algorithm (ABA), recursive Newton-Euler (RNEA) and composite rigid
bodies (CRBA), in local link frames, written here in Python over ``casadi.SX`` with the same inputs
(θ symbolic, the other inertial parameters numbers), so CasADi's instruction counts compare like for
like. ``pinocchio.casadi`` is not in the installed ``pin`` wheel, so this SX implementation is the
reference; it is checked in double precision against ``pinocchio``'s ``aba``, ``rnea`` and ``crba``
on the same chain at random states (every n).

Optionally (``--pinocchio-python PYTHON``: an interpreter of a separate environment with the
``cmeel-casadi-kin-dyn`` package, which traces Pinocchio itself on SX with its own CasADi), the
counts of Pinocchio's traced ABA, RNEA and CRBA are reported beside this reference's at the same
inputs (there the inertial parameters are all numbers: the package reads them from a URDF).

Both folded (the description's numbers constants) and with the numbers as inputs (the default
build): there hydrogen's functions take every number the derivation meets as one more input,
``numbers``, and the reference the same numbers as SX symbols (a joint axis's 0 and ±1 entries are
structure in both, as a Pinocchio joint's axis is its type); the two are checked to agree.

Per n: instruction counts, the ratio hydrogen / reference, and the seconds to derive and convert
hydrogen's rigid-body functions (``rigid_body_functions`` derives all of them: D, C, G, Y, y0, q̈, τ)
and to build the reference's; and the counts of D and D a + C q̇ + G as the rigid body's form
(closed or staged, the one ``form`` names) derives them for C, G, Y and the controllers.

Run: ``python benchmarks/bench_recursive.py [--quick] [--json FILE] [--pinocchio-python PYTHON]``
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

try:  # imported as benchmarks.bench_recursive
    from . import common
    from .bench_scaling import chain_model
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common
    from bench_scaling import chain_model

NS, QUICK_NS = tuple(range(2, 17)), (2, 3, 4)
#: hydrogen function -> the recursive algorithm it is compared with
PAIRS = (("forward_dynamics", "aba"), ("inverse_dynamics", "rnea"), ("mass_matrix", "crba"))
#: The functions also counted as the form derives them (its own D and D a + C q̇ + G: what C, G, Y and
#: the controllers are derived with, and what "auto" weighs the forms by).
FORM_OWN = ("mass_matrix", "inverse_dynamics")
#: Random states per n at which the reference is checked against pinocchio.
CHECK_STATES = 5


# ---------------------------------------------------------------------------------------------
# Featherstone's algorithms over casadi.SX, local link frames (motion vectors [ω; v], forces [n; f])
# ---------------------------------------------------------------------------------------------
def _skew(v):
    return ca.vertcat(ca.horzcat(0, -v[2], v[1]), ca.horzcat(v[2], 0, -v[0]), ca.horzcat(-v[1], v[0], 0))


def _symmetric(M):
    """M's upper triangle mirrored: the same SX node for (i, j) and (j, i), as Pinocchio's Symmetric3."""
    out = ca.SX(M.shape[0], M.shape[1])
    for i in range(M.shape[0]):
        for j in range(i, M.shape[1]):
            out[i, j] = out[j, i] = M[i, j]
    return out


def _axis_rotation(axis, angle):
    """Rotation by ``angle`` about the unit ``axis`` (numbers or SX entries): Rodrigues, zeros fold."""
    K = _skew(ca.vertcat(*axis))
    return ca.SX.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * ca.mtimes(K, K)


def _rpy(rpy):
    """Rz(yaw) Ry(pitch) Rx(roll) of numbers."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp_, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp_], [0, 1, 0], [-sp_, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _rpy_sx(rpy):
    """Rz(yaw) Ry(pitch) Rx(roll) of numbers or SX entries (an angle that is a number 0 folds)."""
    def cs(a):
        return (1.0, 0.0) if isinstance(a, float) and a == 0.0 else (ca.cos(a), ca.sin(a))
    (cr, sr), (cp, sp_), (cy, sy) = (cs(a) for a in rpy)
    Rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, cr, -sr), ca.horzcat(0, sr, cr))
    Ry = ca.vertcat(ca.horzcat(cp, 0, sp_), ca.horzcat(0, 1, 0), ca.horzcat(-sp_, 0, cp))
    Rz = ca.vertcat(ca.horzcat(cy, -sy, 0), ca.horzcat(sy, cy, 0), ca.horzcat(0, 0, 1))
    return ca.mtimes(Rz, ca.mtimes(Ry, Rx))


class Transform:
    """The Plücker transform from a parent's frame to a child's: E rotates parent coordinates into
    the child's, r is the child's origin in parent coordinates (m)."""

    def __init__(self, E, r):
        self.E, self.r = E, r

    def motion(self, m):
        """X m: a parent motion vector in child coordinates."""
        w, v = m[:3], m[3:]
        return ca.vertcat(ca.mtimes(self.E, w), ca.mtimes(self.E, v - ca.cross(self.r, w)))

    def force_up(self, f):
        """Xᵀ f: a child force in parent coordinates."""
        n, fl = ca.mtimes(self.E.T, f[:3]), ca.mtimes(self.E.T, f[3:])
        return ca.vertcat(n + ca.cross(self.r, fl), fl)

    def inertia_up(self, I):
        """Xᵀ I X: a child's (articulated) spatial inertia in parent coordinates, block-wise."""
        E = self.E
        A, B, C = I[:3, :3], I[:3, 3:], I[3:, 3:]
        A, B, C = (ca.mtimes(E.T, ca.mtimes(M, E)) for M in (A, B, C))
        A, C = _symmetric(A), _symmetric(C)
        S = _skew(self.r)
        top = B + ca.mtimes(S, C)
        TL = _symmetric(A + ca.mtimes(S, B.T) - ca.mtimes(top, S))
        return _blocks(TL, top, C)


def _blocks(A, B, C):
    return ca.vertcat(ca.horzcat(A, B), ca.horzcat(B.T, C))


def _crm(v, m):
    """v × m for motion vectors."""
    w, u, w2, u2 = v[:3], v[3:], m[:3], m[3:]
    return ca.vertcat(ca.cross(w, w2), ca.cross(w, u2) + ca.cross(u, w2))


def _crf(v, f):
    """v ×* f for a motion vector v and a force f."""
    w, u, n, fl = v[:3], v[3:], f[:3], f[3:]
    return ca.vertcat(ca.cross(w, n) + ca.cross(u, fl), ca.cross(w, fl))


class Chain:
    """A tree of revolute and prismatic joints (fixed joints merged into the parent's body as
    Pinocchio does) from a hydrogen model, inertial parameters θ (SX or numbers) in the model's
    ``theta_names`` order, the others the description's numbers (mass, first moment h = m c in the
    link frame, inertia I_o about the link origin: Pinocchio's). ``numbers``: description numbers
    by name (``model.numbers()``'s) given as SX symbols instead (the numbers as inputs); any other
    stays a number."""

    def __init__(self, model, theta, numbers=None):
        numbers = numbers or {}
        subst = {**numbers, **dict(zip(model.theta_names, [theta[k] for k in range(len(model.theta_names))]))}
        self.parent, self.kind, self.axis, self.origin, self.inertia = [], [], [], [], []
        self.gravity = numbers.get("gravity", model.gravity)

        def entries(joint, key, values):
            return [numbers.get(f"{joint}.{key}[{k}]", float(v)) for k, v in enumerate(values)]

        index = {model.root: -1}
        for j in model.joints:
            if j.type not in ("revolute", "prismatic"):
                raise ValueError(f"the reference chain takes revolute and prismatic joints, not {j.type}")
            index[j.child] = len(self.parent)
            self.parent.append(index[j.parent])
            self.kind.append(j.type)
            self.axis.append(entries(j.name, "axis", j.axis))
            self.origin.append((_rpy_sx(entries(j.name, "origin_rpy", j.origin_rpy)),
                                ca.vertcat(*entries(j.name, "origin_xyz", j.origin_xyz))))
            p = {k: subst.get(f"{j.child}.{k}", v) for k, v in model.link(j.child).parameters().items()}
            h = ca.vertcat(p["mcx"], p["mcy"], p["mcz"])
            Io = ca.vertcat(ca.horzcat(p["Ixx"], p["Ixy"], p["Ixz"]), ca.horzcat(p["Ixy"], p["Iyy"], p["Iyz"]),
                            ca.horzcat(p["Ixz"], p["Iyz"], p["Izz"]))
            self.inertia.append(_blocks(Io, _skew(h), p["mass"] * ca.DM.eye(3)))
        self.n = len(self.parent)

    def transform(self, i, qi):
        """X_i (parent → link i) at the joint's coordinate ``qi``: origin, then the joint's motion."""
        R_o, xyz = self.origin[i]
        if self.kind[i] == "revolute":
            R, p = ca.mtimes(R_o, _axis_rotation(self.axis[i], qi)), xyz
        else:
            R, p = R_o, xyz + ca.mtimes(R_o, ca.vertcat(*self.axis[i])) * qi
        return Transform(R.T, p)

    def motion_axis(self, i):
        """S_i (6×1, link frame)."""
        a = ca.vertcat(*self.axis[i])
        return ca.vertcat(a, ca.SX.zeros(3)) if self.kind[i] == "revolute" else ca.vertcat(ca.SX.zeros(3), a)

    def base_acceleration(self):
        """The base accelerating up at g: gravity along −z of the base frame."""
        return ca.vertcat(0, 0, 0, 0, 0, self.gravity)


def aba(chain, q, v, tau):
    """q̈ by the articulated-body algorithm (Featherstone 2008, Table 7.1)."""
    n = chain.n
    X = [chain.transform(i, q[i]) for i in range(n)]
    S = [chain.motion_axis(i) for i in range(n)]
    vel, c, IA, pA = [None] * n, [None] * n, [None] * n, [None] * n
    for i in range(n):
        vJ = S[i] * v[i]
        vel[i] = vJ if chain.parent[i] < 0 else X[i].motion(vel[chain.parent[i]]) + vJ
        c[i] = _crm(vel[i], vJ)
        IA[i] = chain.inertia[i]
        pA[i] = _crf(vel[i], ca.mtimes(chain.inertia[i], vel[i]))
    U, d, u = [None] * n, [None] * n, [None] * n
    for i in reversed(range(n)):
        U[i] = ca.mtimes(IA[i], S[i])
        d[i] = ca.dot(S[i], U[i])
        u[i] = tau[i] - ca.dot(S[i], pA[i])
        p = chain.parent[i]
        if p >= 0:
            Ia = IA[i] - ca.mtimes(U[i], U[i].T) / d[i]
            pa = pA[i] + ca.mtimes(Ia, c[i]) + U[i] * (u[i] / d[i])
            IA[p] = IA[p] + X[i].inertia_up(Ia)
            pA[p] = pA[p] + X[i].force_up(pa)
    acc, qdd = [None] * n, [None] * n
    for i in range(n):
        p = chain.parent[i]
        acc[i] = X[i].motion(chain.base_acceleration() if p < 0 else acc[p]) + c[i]
        qdd[i] = (u[i] - ca.dot(U[i], acc[i])) / d[i]
        acc[i] = acc[i] + S[i] * qdd[i]
    return ca.vertcat(*qdd)


def rnea(chain, q, v, a):
    """τ by recursive Newton-Euler (Featherstone 2008, Table 5.1)."""
    n = chain.n
    X = [chain.transform(i, q[i]) for i in range(n)]
    S = [chain.motion_axis(i) for i in range(n)]
    vel, acc, f = [None] * n, [None] * n, [None] * n
    for i in range(n):
        p = chain.parent[i]
        vJ = S[i] * v[i]
        vel[i] = vJ if p < 0 else X[i].motion(vel[p]) + vJ
        acc[i] = X[i].motion(chain.base_acceleration() if p < 0 else acc[p]) + S[i] * a[i] + _crm(vel[i], vJ)
        Iv = ca.mtimes(chain.inertia[i], vel[i])
        f[i] = ca.mtimes(chain.inertia[i], acc[i]) + _crf(vel[i], Iv)
    tau = [None] * n
    for i in reversed(range(n)):
        tau[i] = ca.dot(S[i], f[i])
        if chain.parent[i] >= 0:
            f[chain.parent[i]] = f[chain.parent[i]] + X[i].force_up(f[i])
    return ca.vertcat(*tau)


def crba(chain, q):
    """The mass matrix by composite rigid bodies (Featherstone 2008, Table 6.2)."""
    n = chain.n
    X = [chain.transform(i, q[i]) for i in range(n)]
    S = [chain.motion_axis(i) for i in range(n)]
    Ic = list(chain.inertia)
    H = ca.SX(n, n)
    for i in reversed(range(n)):
        if chain.parent[i] >= 0:
            Ic[chain.parent[i]] = Ic[chain.parent[i]] + X[i].inertia_up(Ic[i])
        F = ca.mtimes(Ic[i], S[i])
        H[i, i] = ca.dot(S[i], F)
        j = i
        while chain.parent[j] >= 0:
            F = X[j].force_up(F)
            j = chain.parent[j]
            H[i, j] = H[j, i] = ca.dot(S[j], F)
    return H


def reference_functions(model, theta_numeric: bool = False, numbers=()) -> dict:
    """ABA, RNEA and CRBA of ``model`` as CasADi Functions with CSE, inputs as hydrogen's
    (q, qdot, tau | qddot, theta); with ``theta_numeric`` θ is the description's values (no input).
    ``numbers``: names of description numbers (``model.numbers()``'s) taken as one more input,
    ``numbers``, in that order (hydrogen's numbers as inputs; θ's own entries are θ's)."""
    n, p = model.n, len(model.theta_names)
    q, v, tau, a = (ca.SX.sym(k, n) for k in ("q", "qdot", "tau", "qddot"))
    theta = ca.SX.sym("theta", p)
    nb = ca.SX.sym("numbers", len(numbers))
    chain = Chain(model, list(model.theta) if theta_numeric else theta,
                  {name: nb[k] for k, name in enumerate(numbers)})
    extra, names = ([], []) if theta_numeric else ([theta], ["theta"])
    if numbers:
        extra, names = [*extra, nb], [*names, "numbers"]
    opts = {"cse": True}
    return {
        "aba": ca.Function("aba", [q, v, tau, *extra], [aba(chain, q, v, tau)], ["q", "qdot", "tau", *names],
                           ["qddot"], opts),
        "rnea": ca.Function("rnea", [q, v, a, *extra], [rnea(chain, q, v, a)], ["q", "qdot", "qddot", *names],
                            ["tau"], opts),
        "crba": ca.Function("crba", [q, *extra], [ca.densify(crba(chain, q))], ["q", *names], ["D"], opts),
    }


# ---------------------------------------------------------------------------------------------
# pinocchio (double precision) for the check
# ---------------------------------------------------------------------------------------------
def pinocchio_model(model):
    """Pinocchio's model of a revolute/prismatic tree description, the description's parameters."""
    import pinocchio as pin

    from hydrogen.model import INERTIAL_PARAMETERS

    pm = pin.Model()
    index = {model.root: 0}
    for j in model.joints:
        placement = pin.SE3(_rpy(j.origin_rpy), np.asarray(j.origin_xyz, float))
        joint = {"revolute": pin.JointModelRevoluteUnaligned,
                 "prismatic": pin.JointModelPrismaticUnaligned}[j.type](np.asarray(j.axis, float))
        index[j.child] = pm.addJoint(index[j.parent], joint, placement, j.name)
        p = model.link(j.child).parameters()
        pm.appendBodyToJoint(index[j.child], pin.Inertia.FromDynamicParameters(
            np.array([p[k] for k in INERTIAL_PARAMETERS])), pin.SE3.Identity())
    pm.gravity.linear = np.array([0.0, 0.0, -model.gravity])
    return pm


def check_reference(model, funcs: dict, seed: int = 0, count: int = CHECK_STATES) -> dict:
    """The largest relative difference of the reference's ABA, RNEA, CRBA from pinocchio's at
    ``count`` random states around the neutral pose, θ the description's values."""
    import pinocchio as pin

    pm = pinocchio_model(model)
    data = pm.createData()
    rng = np.random.default_rng(seed)
    th = np.asarray(model.theta, float)
    worst = {k: 0.0 for k in ("aba", "rnea", "crba")}

    def rel(a, b):
        a, b = np.asarray(a, float).reshape(np.shape(b)), np.asarray(b, float)
        return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))

    for _ in range(count):
        q = np.asarray(model.neutral_pose, float) + rng.uniform(-1, 1, model.n)
        v, tau, a = rng.normal(size=model.n), rng.normal(size=model.n) * 100, rng.normal(size=model.n)
        worst["aba"] = max(worst["aba"], rel(funcs["aba"](q, v, tau, th), pin.aba(pm, data, q, v, tau)))
        worst["rnea"] = max(worst["rnea"], rel(funcs["rnea"](q, v, a, th), pin.rnea(pm, data, q, v, a)))
        M = pin.crba(pm, data, q)
        worst["crba"] = max(worst["crba"], rel(funcs["crba"](q, th), np.triu(M) + np.triu(M, 1).T))
    return worst


# ---------------------------------------------------------------------------------------------
# Pinocchio traced on SX (optional, another environment)
# ---------------------------------------------------------------------------------------------
_URDF_INERTIA = (("ixx", 0, 0), ("ixy", 0, 1), ("ixz", 0, 2), ("iyy", 1, 1), ("iyz", 1, 2), ("izz", 2, 2))


def urdf_text(model) -> str:
    """A URDF of a revolute/prismatic tree description (the centre of mass and the inertia about it
    from the description's parameters)."""
    lines = [f'<robot name="{model.name}">', f'  <link name="{model.root}"/>']
    for lk in model.links:
        p = lk.parameters()
        m = p["mass"]
        c = np.array([p["mcx"], p["mcy"], p["mcz"]]) / m
        Io = np.array([[p["Ixx"], p["Ixy"], p["Ixz"]], [p["Ixy"], p["Iyy"], p["Iyz"]], [p["Ixz"], p["Iyz"], p["Izz"]]])
        Ic = Io - m * (c @ c * np.eye(3) - np.outer(c, c))  # parallel axes: about the centre of mass
        num = lambda x: repr(float(x))  # noqa: E731 (a plain number: URDF parsers reject numpy's repr)
        lines += [f'  <link name="{lk.name}"><inertial>', f'    <origin xyz="{" ".join(num(x) for x in c)}"/>',
                  f'    <mass value="{num(m)}"/>',
                  '    <inertia ' + " ".join(f'{k}="{num(Ic[i, j])}"' for k, i, j in _URDF_INERTIA) + '/>',
                  '  </inertial></link>']
    for j in model.joints:
        xyz, rpy, ax = (" ".join(repr(float(x)) for x in v) for v in (j.origin_xyz, j.origin_rpy, j.axis))
        lines += [f'  <joint name="{j.name}" type="{j.type}"><parent link="{j.parent}"/><child link="{j.child}"/>',
                  f'    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{ax}"/>',
                  '    <limit lower="-10" upper="10" effort="1e9" velocity="1e9"/></joint>']
    return "\n".join(lines + ["</robot>"]) + "\n"


_TRACED = """
import json, sys
from casadi_kin_dyn import casadi_kin_dyn as ckd  # first: it loads the CasADi library its casadi module needs
import casadi as ca
k = ckd.CasadiKinDyn(open(sys.argv[1]).read())
out = {"casadi": ca.__version__, "nq": k.nq()}
for name in ("aba", "rnea", "crba"):
    f = getattr(k, name)()
    args = [ca.SX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    g = ca.Function(name, args, [ca.densify(x) for x in f.call(args)], {"cse": True})
    out[name] = int(g.n_instructions())
print("JSON", json.dumps(out))
"""


def pinocchio_traced(model, python: str) -> dict | None:
    """Instruction counts of Pinocchio's ABA, RNEA and CRBA traced on SX by ``cmeel-casadi-kin-dyn``
    in the interpreter ``python`` (its own CasADi), with CSE; None when it cannot run there."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{model.name}.urdf"
        path.write_text(urdf_text(model))
        try:
            env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # that environment's packages only
            proc = subprocess.run([python, "-c", _TRACED, str(path)], capture_output=True, text=True, timeout=600,
                                  env=env)
        except OSError:
            return None
    for line in proc.stdout.splitlines():
        if line.startswith("JSON "):
            out = json.loads(line[5:])
            return out if out["nq"] == model.n else None  # a URDF it could not read gives an empty model
    return None


# ---------------------------------------------------------------------------------------------
# hydrogen and the run
# ---------------------------------------------------------------------------------------------
def hydrogen_counts(model, inputs: bool = False) -> dict:
    """Hydrogen's counts of :data:`PAIRS`'s functions, its form, and the seconds to derive the rigid
    body (``rigid_body_functions``) and to convert those functions to CasADi; with ``inputs`` the
    description's numbers are symbols taken as one more input (the default build's functions), and
    ``numbers`` names them (those the derivation met, in its order)."""
    import sympy as sp

    from hydrogen.codegen.casadi_functions import casadi_function
    from hydrogen.symbolic.constants import folded, numbers_as_symbols
    from hydrogen.symbolic.forms import rigid_body_form
    from hydrogen.symbolic.functions import rigid_body_functions, with_numbers_input

    t0 = time.perf_counter()
    form = rigid_body_form(model)
    with (numbers_as_symbols("name") if inputs else folded()) as table:
        funcs = rigid_body_functions(model)
        own_funcs = rigid_body_functions(model, form_dynamics=True)
    if inputs:
        vector = sp.Matrix(table.symbols)
        funcs, own_funcs = ([with_numbers_input(f, vector) for f in fs] for fs in (funcs, own_funcs))
    t1 = time.perf_counter()
    cache, counts, converted = {}, {}, {}
    for sf in funcs:
        if sf.name in dict(PAIRS):
            converted[sf.name] = casadi_function(sf, cache=cache)
            counts[sf.name] = int(converted[sf.name].n_instructions())
    convert_s = time.perf_counter() - t1
    own = {sf.name: int(casadi_function(sf, cache={}).n_instructions()) for sf in own_funcs if sf.name in FORM_OWN}
    return {"form": form, "counts": counts, "form_own": own, "derive_s": t1 - t0, "convert_s": convert_s,
            "numbers": list(table.names) if inputs else [], "functions": converted}


def theta_numeric_count(f, theta) -> int:
    """Instructions of the CasADi Function ``f`` with its input ``theta`` the numbers ``theta`` (CSE):
    SX folds every operation on constants, so this is ``f`` with all its numbers constants, as
    Pinocchio traced from a URDF has them."""
    names = [f.name_in(i) for i in range(f.n_in())]
    args = {k: ca.SX.sym(k, f.sparsity_in(i)) for i, k in enumerate(names) if k != "theta"}
    out = f.call({**args, "theta": ca.DM(np.asarray(theta, float))})
    g = ca.Function("g", list(args.values()), [ca.densify(out[k]) for k in f.name_out()], {"cse": True})
    return int(g.n_instructions())


def agreement(model, hyd: dict, ref: dict, numbers: list, seed: int = 0, count: int = CHECK_STATES) -> float:
    """The largest relative difference of hydrogen's functions with the numbers as inputs from the
    reference's with the same inputs, at ``count`` random states, θ and the numbers the description's."""
    values = model.numbers()
    every = np.array([values[k] for k in hyd["numbers"]])
    mine = np.array([values[k] for k in numbers])
    th = np.asarray(model.theta, float)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(count):
        q = np.asarray(model.neutral_pose, float) + rng.uniform(-1, 1, model.n)
        v, tau, a = rng.normal(size=model.n), rng.normal(size=model.n) * 100, rng.normal(size=model.n)
        args = {"forward_dynamics": (q, v, tau), "inverse_dynamics": (q, v, a), "mass_matrix": (q,)}
        for h, r in PAIRS:
            x = np.asarray(hyd["functions"][h](*args[h], th, every), float)
            y = np.asarray(ref[r](*args[h], th, mine), float)
            if h == "mass_matrix":
                x = np.triu(x) + np.triu(x, 1).T
            worst = max(worst, float(np.abs(x - y).max() / max(1.0, np.abs(y).max())))
    return worst


def run_one(n: int, pinocchio_python: str | None = None) -> dict:
    model = chain_model(n)
    hyd = hydrogen_counts(model)
    t0 = time.perf_counter()
    ref = reference_functions(model)
    ref_counts = {k: int(f.n_instructions()) for k, f in ref.items()}
    build_s = time.perf_counter() - t0
    # the numbers as inputs, like for like: the reference takes the numbers hydrogen's functions take
    hyd_in = hydrogen_counts(model, inputs=True)
    numbers = [k for k in hyd_in["numbers"] if k not in model.theta_names]
    ref_in = reference_functions(model, numbers=numbers)
    ref_in_counts = {k: int(f.n_instructions()) for k, f in ref_in.items()}
    row = {"n": n, "form": hyd["form"], "hydrogen": hyd["counts"], "form_own": hyd["form_own"], "reference": ref_counts,
           "ratio": {h: hyd["counts"][h] / ref_counts[r] for h, r in PAIRS},
           "inputs": {"numbers": len(numbers), "hydrogen": hyd_in["counts"], "reference": ref_in_counts,
                      "ratio": {h: hyd_in["counts"][h] / ref_in_counts[r] for h, r in PAIRS},
                      "over_folded": {h: hyd_in["counts"][h] / hyd["counts"][h] for h, _ in PAIRS},
                      "agree": agreement(model, hyd_in, ref_in, numbers)},
           "hydrogen_derive_s": hyd["derive_s"], "hydrogen_convert_s": hyd["convert_s"], "reference_s": build_s,
           "check_max_rel": check_reference(model, ref) if _pin_version() != NO_PIN else None}
    if pinocchio_python:
        numeric = {k: int(f.n_instructions()) for k, f in reference_functions(model, theta_numeric=True).items()}
        row["reference_theta_numeric"] = numeric
        row["hydrogen_theta_numeric"] = {h: theta_numeric_count(hyd["functions"][h], model.theta) for h, _ in PAIRS}
        row["pinocchio_traced"] = pinocchio_traced(model, pinocchio_python)
    return row


def run(quick: bool = False, pinocchio_python: str | None = None) -> dict:
    pinocchio_python = pinocchio_python or os.environ.get("HYDROGEN_BENCH_PINOCCHIO_PYTHON") or None
    t0 = time.perf_counter()
    rows = [run_one(n, pinocchio_python) for n in (QUICK_NS if quick else NS)]
    return {"rows": rows, "quick": quick, "growth": growth(rows), "reference": "own SX Featherstone, checked "
            "against pinocchio " + _pin_version(), "machine": common.machine_info(), "cores": os.cpu_count(),
            "wall_s": time.perf_counter() - t0}


NO_PIN = "(not installed: the reference is not checked)"


def _pin_version() -> str:
    """pinocchio's version; the test extra installs it, a user's environment may not."""
    try:
        import pinocchio

        return pinocchio.__version__
    except ImportError:
        return NO_PIN


def growth(rows) -> dict:
    """The exponent k of a least-squares fit count ∝ n^k per function (log-log), hydrogen's and the
    reference's."""
    if len(rows) < 2:
        return {}
    ns = np.log([r["n"] for r in rows])
    out = {}
    for h, r in PAIRS:
        out[h] = float(np.polyfit(ns, np.log([x["hydrogen"][h] for x in rows]), 1)[0])
        out[r] = float(np.polyfit(ns, np.log([x["reference"][r] for x in rows]), 1)[0])
    return out


def _worst(row) -> str:
    check = row.get("check_max_rel")
    return "-" if not check else f"{max(check.values()):.1e}"


def print_table(res: dict) -> None:
    rows = res["rows"]
    print(f"planar chain of n links: hydrogen's rigid body against Featherstone's recursive algorithms "
          f"(CasADi instructions with CSE; reference: {res['reference']}):")
    head = (f"{'n':>2} {'form':>6} " + " ".join(f"{h[:7] + ' ' + r:>12} {'ratio':>5}" for h, r in PAIRS)
            + f" {'hyd s':>6} {'ref s':>6} {'max rel err vs pin':>18}")
    print(head)
    print("-" * len(head))
    for x in rows:
        cells = " ".join(f"{str(x['hydrogen'][h]) + '/' + str(x['reference'][r]):>12} {x['ratio'][h]:>5.2f}"
                         for h, r in PAIRS)
        print(f"{x['n']:>2} {x['form']:>6} {cells} {x['hydrogen_derive_s'] + x['hydrogen_convert_s']:>6.1f} "
              f"{x['reference_s']:>6.2f} {_worst(x):>18}")
    if res["growth"]:
        print("growth exponent k (count ~ n^k): " + ", ".join(f"{k} {v:.2f}" for k, v in res["growth"].items()))
    print("the form's own D and D a + C q̇ + G: " + ", ".join(
        f"n={x['n']} {x['form_own']['mass_matrix']}/{x['form_own']['inverse_dynamics']}" for x in rows))
    print("numbers as inputs, hydrogen/reference (ratio) and hydrogen's as inputs / folded:")
    for x in rows:
        i = x["inputs"]
        print(f"{x['n']:>2} " + " ".join(f"{i['hydrogen'][h]}/{i['reference'][r]} ({i['ratio'][h]:.2f})" for h, r in PAIRS)
              + "  " + " ".join(f"{i['over_folded'][h]:.2f}" for h, _ in PAIRS) + f"  agree {i['agree']:.0e}")
    traced = [x for x in rows if x.get("pinocchio_traced")]
    if traced:
        print(f"Pinocchio traced on SX (casadi {traced[0]['pinocchio_traced'].get('casadi')}) against this "
              "reference, θ numbers in both:")
        for x in traced:
            print(f"{x['n']:>2} " + " ".join(f"{r} {x['pinocchio_traced'][r]}/{x['reference_theta_numeric'][r]}"
                                             for _, r in PAIRS))


def main(argv=None) -> int:
    return common.script_main(__doc__, run, print_table, argv, {"--pinocchio-python": dict(
        metavar="PYTHON", help="an interpreter with cmeel-casadi-kin-dyn (another environment): Pinocchio traced on SX")})


if __name__ == "__main__":
    sys.exit(main())
