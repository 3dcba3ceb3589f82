"""The staged rigid body (link poses as intermediate symbols, spatial algebra over the tree) on the
synthetic planar chain of benchmarks/bench_scaling.py, against Pinocchio built from the same
description, and the properties (3) of the paper's controllers: Ḋ − 2C skew, C symmetric in its
two velocity slots; τ̇_d of the controllers against CasADi's AD through the pose stages.

The functions are evaluated as CasADi Functions straight from the derivation (no C compile)."""
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.codegen.sympy_to_casadi import SympyToCasadi
from hydrogen.model import INERTIAL_PARAMETERS
from hydrogen.symbolic import kinematics as K
from hydrogen.symbolic import rigid_body as RB
from hydrogen.symbolic.functions import SymbolicFunction, rigid_body_functions
from hydrogen.symbolic.tree import SymbolicTree

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from bench_scaling import chain_model  # noqa: E402
from reference import controller_rate_map  # noqa: E402

pin = pytest.importorskip("pinocchio")
N = 4


@pytest.fixture(scope="module")
def chain():
    return chain_model(N)


@pytest.fixture(scope="module")
def funcs(chain):
    """The rigid-body functions of the chain as CasADi Functions, by name."""
    return {sf.name: to_casadi_function(sf) for sf in rigid_body_functions(chain)}


def _pinocchio(model):
    """Pinocchio's model of a revolute/prismatic/fixed tree description, parameters included (a
    link on a fixed joint is merged into its parent joint's body at its placement)."""
    pm = pin.Model()
    frame = {model.root: (0, pin.SE3.Identity())}  # link -> (Pinocchio joint, placement in that joint)
    for j in model.joints:
        parent, above = frame[j.parent]
        placement = above * pin.SE3(pin.rpy.rpyToMatrix(*np.asarray(j.origin_rpy, float)),
                                    np.asarray(j.origin_xyz, float))
        axis = np.asarray(j.axis, float)
        if j.type == "fixed":
            frame[j.child] = (parent, placement)
        else:
            joint = {"revolute": pin.JointModelRevoluteUnaligned,
                     "prismatic": pin.JointModelPrismaticUnaligned}[j.type](axis)
            frame[j.child] = (pm.addJoint(parent, joint, placement, j.name), pin.SE3.Identity())
        p = model.link(j.child).parameters()
        pid, at = frame[j.child]
        pm.appendBodyToJoint(pid, pin.Inertia.FromDynamicParameters(np.array([p[k] for k in INERTIAL_PARAMETERS])), at)
    pm.gravity.linear = np.array([0.0, 0.0, -model.gravity])
    return pm


def _states(model, rng, count=6):
    for _ in range(count):
        yield (model.neutral_pose + rng.uniform(-1, 1, model.n), rng.normal(size=model.n),
               rng.normal(size=model.n), rng.normal(size=model.n))


def _close(a, b):
    b = np.asarray(b, float)
    a = np.asarray(a, float).reshape(b.shape)  # CasADi returns columns as n×1
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(b).max()))


def test_the_chain_is_staged_and_the_shipped_arm_is_not(chain):
    import hydrogen

    q = K.pose_symbols(chain)
    assert SymbolicTree(chain, q, RB.theta_symbols(chain)).staged()
    assert RB.rigid_body_stages(chain, q)  # the functions evaluate the pose stages first
    for name in hydrogen.models():  # the closed form where it is smaller (short chains, a floating body)
        m = hydrogen.load_model(name)
        assert not SymbolicTree(m, K.pose_symbols(m), RB.theta_symbols(m)).staged()


def test_staged_rigid_body_equals_pinocchio(chain, funcs, rng):
    pm = _pinocchio(chain)
    data = pm.createData()
    th = chain.theta
    child = {j.name: j.child for j in chain.joints}
    cols = {f"{child[pm.names[jid]]}.{p}": 10 * (jid - 1) + k
            for jid in range(1, pm.njoints) for k, p in enumerate(INERTIAL_PARAMETERS)}
    pi = np.concatenate([pm.inertias[j].toDynamicParameters() for j in range(1, pm.njoints)])
    sel = [cols[n] for n in chain.theta_names]
    _close(th, pi[sel])
    for q, v, w, a in _states(chain, rng):
        M = pin.crba(pm, data, q)
        _close(funcs["mass_matrix"](q, th), np.triu(M) + np.triu(M, 1).T)
        _close(funcs["coriolis"](q, v, th), pin.computeCoriolisMatrix(pm, data, q, v))
        _close(funcs["gravity"](q, th), pin.computeGeneralizedGravity(pm, data, q))
        R = pin.computeJointTorqueRegressor(pm, data, q, v, a)
        _close(funcs["regressor"](q, v, v, a), R[:, sel])
        _close(np.asarray(funcs["regressor"](q, v, v, a)) @ th + np.asarray(funcs["regressor_offset"](q, v, v, a)).ravel(),
               pin.rnea(pm, data, q, v, a))
        tau = rng.normal(size=chain.n) * 100
        _close(funcs["forward_dynamics"](q, v, tau, th), pin.aba(pm, data, q, v, tau))


def test_staged_regressor_slots_are_D_C_G(chain, funcs, rng):
    """Y(q, v, w, a) θ + y0 = D a + C(q, v) w + G with w ≠ v: the slots, not only Newton-Euler."""
    th = chain.theta * rng.uniform(0.5, 1.5, chain.n_theta)
    for q, v, w, a in _states(chain, rng):
        D, C, G = (np.asarray(x) for x in (funcs["mass_matrix"](q, th), funcs["coriolis"](q, v, th),
                                           funcs["gravity"](q, th)))
        got = np.asarray(funcs["regressor"](q, v, w, a)) @ th + np.asarray(funcs["regressor_offset"](q, v, w, a)).ravel()
        _close(got, D @ a + C @ w + G.ravel())


def test_staged_Ddot_minus_2C_is_skew_and_C_symmetric_in_its_slots(chain, funcs, rng):
    h = 1e-6
    for q, v, w, _ in _states(chain, rng):
        th = chain.theta * rng.uniform(0.5, 1.5, chain.n_theta)
        Ddot = (np.asarray(funcs["mass_matrix"](q + h * v, th)) - np.asarray(funcs["mass_matrix"](q - h * v, th))) / (2 * h)
        N = Ddot - 2 * np.asarray(funcs["coriolis"](q, v, th))
        np.testing.assert_allclose(N + N.T, 0, atol=1e-6 * np.abs(N).max())
        assert np.abs(N).max() > 1e-3  # N itself is not zero: the test has teeth
        _close(np.asarray(funcs["coriolis"](q, v, th)) @ w, np.asarray(funcs["coriolis"](q, w, th)) @ v)


def test_staged_matches_the_closed_form(chain, rng):
    """The same D, C, G from both forms of one tree (the closed form differentiates D for C)."""
    q, th = K.pose_symbols(chain), RB.theta_symbols(chain)
    v = K.rate_symbols("v", chain.n)
    tree = SymbolicTree(chain, q, th)
    g = chain.gravity
    inputs = [("q", q), ("v", v), ("th", th)]
    staged = to_casadi_function(SymbolicFunction("s", inputs, [
        ("D", tree.staged_mass_matrix()), ("C", tree.staged_coriolis(v)), ("G", tree.staged_gravity(g))], "",
        tree.pose_stages()))
    D = tree.mass_matrix()
    closed = to_casadi_function(SymbolicFunction("c", inputs, [
        ("D", D), ("C", RB.coriolis(D, q, v)), ("G", tree.gravity(g))], ""))
    for q0, v0, _, _ in _states(chain, rng, 3):
        th0 = chain.theta * rng.uniform(0.5, 1.5, chain.n_theta)
        for a, b in zip(staged(q0, v0, th0), closed(q0, v0, th0)):
            _close(a, b)


@pytest.mark.parametrize("kind", ["backstepping", "adaptive-robust", "adaptive-observer"])
def test_staged_tau_d_dot_matches_casadi_ad_through_the_pose_stages(kind, chain, rng):
    """τ̇_d, derived by forward mode with the pose rates (Ṙ = S(ω) R, ṗ), equals CasADi's forward AD
    of τ_d when the poses are evaluated from q (their stages), not held fixed."""
    from hydrogen.controllers import controller
    from hydrogen.symbolic.control_laws import Common

    parts = controller(kind).derive(chain)
    stage = {str(s[0]): (s, v) for s, v in parts.intermediates}
    _, taud = stage["taud_0"]
    _, taud_dot = stage["taud_dot_0"]
    kin = Common(chain).kin
    defined = {s for syms, _ in kin for s in syms}
    free = set().union(*(v.free_symbols for _, v in kin if not isinstance(v, tuple)))
    syms = sorted((taud.free_symbols | taud_dot.free_symbols | free) - defined, key=str)
    X = ca.SX.sym("X", len(syms))
    conv = SympyToCasadi({s: X[i] for i, s in enumerate(syms)})
    for symbols, value in kin:
        conv.define(symbols, conv(value))
    assert taud.free_symbols & defined  # τ_d holds pose symbols: the stages matter
    idx = {str(s): i for i, s in enumerate(syms)}
    tau_sx, tau_dot_sx = conv(taud), conv(taud_dot)
    f = ca.Function("f", [X], [ca.jtimes(tau_sx, X, controller_rate_map(chain, syms, X, idx)), tau_dot_sx])
    for _ in range(3):
        x = rng.normal(size=X.numel())
        for s, i in idx.items():
            if s.startswith("theta_hat"):
                x[i] = 40 + abs(x[i])
        a, b = (np.array(v).ravel() for v in f(x))
        np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9 * max(1, np.abs(a).max()))


def _branching_tree(rng):
    """A tree with every joint type the staged form takes: revolute (about coordinate and skew axes),
    prismatic, fixed, a branch and rotated origins; 4 moving joints deep (staged). Random inertias."""
    from dataclasses import replace

    from hydrogen.model import Joint, Link

    def link(name):
        A = rng.normal(size=(3, 3))
        return Link(name, float(rng.uniform(1, 5)), rng.normal(size=3) * 0.3, A @ A.T + np.eye(3))

    spec = [("j1", "revolute", "base", "a", [0, 0, 0.3], [0.2, 0, 0], [0, 0, 1]),
            ("j2", "prismatic", "a", "b", [0.5, 0, 0], [0.1, -0.2, 0.3], [1, 0, 0]),
            ("j3", "revolute", "b", "c", [0, 0.4, 0], [0, 0, 0], [0, 1, 0]),
            ("j4", "fixed", "c", "d", [0.3, 0, 0.1], [0.4, 0.1, -0.2], [1, 0, 0]),
            ("j5", "revolute", "d", "e", [0, 0, 0.5], [0, 0, 0], [2 ** -0.5, 2 ** -0.5, 0]),
            ("j6", "revolute", "b", "f", [0, -0.4, 0], [0, 0.3, 0], [1, 0, 0])]
    joints = tuple(Joint(n, t, p, c, np.array(x, float), np.array(r, float), np.array(ax, float))
                   for n, t, p, c, x, r, ax in spec)
    links = (Link("base", 0.0, np.zeros(3), np.zeros((3, 3))),) + tuple(link(x) for x in "abcdef")
    names = ("a.Izz", "b.mass", "c.mcx", "c.Ixy", "e.mcz", "e.Iyy", "f.mass", "f.Ixx")
    m = replace(chain_model(4), name="tree", links=links, joints=joints, cylinders=(),
                coordinate_names=("j1", "j2", "j3", "j5", "j6"), theta_names=names)
    return m, np.array([m.link(x.split(".")[0]).parameters()[x.split(".")[1]] for x in names])


def test_the_closed_form_merges_a_fixed_link_into_its_body(rng):
    """The closed form has one body per moving link, each fixed link below merged in (its
    parameters in the body's frame): D and G equal the staged form's, which keeps the fixed link a
    body of its own, at random θ that include the merged link's mass, first moment and a product of
    inertia (so the merge is linear in them, as Y needs)."""
    from dataclasses import replace

    model, _ = _branching_tree(rng)
    names = ("d.mass", "d.mcy", "d.Ixz", "c.mcx", "e.Iyy")
    model = replace(model, theta_names=names)
    theta = np.array([model.link(x.split(".")[0]).parameters()[x.split(".")[1]] for x in names])
    n = len(model.coordinate_names)
    q, th = K.rate_symbols("q", n), RB.theta_symbols(model)
    v = K.rate_symbols("v", n)
    tree = SymbolicTree(model, q, th)
    assert set(tree.bodies()) == {"base"} | {j.child for j in model.joints if j.type != "fixed"}
    inputs = [("q", q), ("v", v), ("th", th)]
    closed = to_casadi_function(SymbolicFunction("c", inputs, [("D", tree.mass_matrix()),
                                                               ("G", tree.gravity(model.gravity))], ""))
    staged = to_casadi_function(SymbolicFunction("s", inputs, [("D", tree.staged_mass_matrix()),
                                                               ("G", tree.staged_gravity(model.gravity))],
                                                 "", tree.pose_stages()))
    for scale in (1.0, *rng.uniform(0.3, 3.0, size=(3, len(names)))):
        q0, v0 = rng.normal(size=n), rng.normal(size=n)
        for x, y in zip(closed(q0, v0, theta * scale), staged(q0, v0, theta * scale)):
            _close(x, y)


def _christoffel(dg, q_at: int = 0, v_at: int = 1):
    """``dg`` (its inputs) -> (D, G) as (D, C, G): C(q, v) of the Christoffel form by CasADi's own
    differentiation of D, q and v its inputs ``q_at`` and ``v_at`` (SymPy's of the closed-form D of a
    branched tree took most of a test)."""
    import casadi as ca

    args = [ca.SX.sym(dg.name_in(i), *dg.size_in(i)) for i in range(dg.n_in())]
    D, G = dg(*args)
    q, v = args[q_at], args[v_at]
    n = D.shape[0]
    dD = [ca.reshape(ca.jacobian(ca.vec(D), q[k]), n, n) for k in range(n)]  # dD[k][i, j] = ∂D_ij/∂q_k
    C = ca.SX(n, n)
    for i in range(n):
        for j in range(n):
            C[i, j] = sum(0.5 * (dD[k][i, j] + dD[j][i, k] - dD[i][j, k]) * v[k] for k in range(n))
    return ca.Function("dcg", args, [D, C, G])


def test_staged_tree_with_every_joint_type_equals_pinocchio_and_the_closed_form(rng):
    model, theta = _branching_tree(rng)
    n = len(model.coordinate_names)
    q, th = K.rate_symbols("q", n), RB.theta_symbols(model)
    v, w, a = (K.rate_symbols(k, n) for k in "vwa")
    tree = SymbolicTree(model, q, th)
    assert tree.staged() and tree.depth() == 4
    g = model.gravity
    inputs = [("q", q), ("v", v), ("w", w), ("a", a), ("th", th)]
    D = tree.mass_matrix()
    closed = _christoffel(to_casadi_function(SymbolicFunction("c", inputs, [("D", D), ("G", tree.gravity(g))], "")))
    zero = SymbolicTree(model, q, [0] * len(th))
    staged = to_casadi_function(SymbolicFunction("s", inputs, [
        ("D", tree.staged_mass_matrix()), ("C", tree.staged_coriolis(v)), ("G", tree.staged_gravity(g)),
        ("tau", tree.staged_inverse_dynamics(v, w, a, g)),
        ("Y", tree.staged_regressor(v, w, a, g, model.theta_names)),
        ("y0", zero.staged_inverse_dynamics(v, w, a, g))], "", tree.pose_stages()))
    pm = _pinocchio(model)
    data = pm.createData()
    moving = [j.child for j in model.joints if j.type != "fixed"]
    cols = [10 * moving.index(x.split(".")[0]) + INERTIAL_PARAMETERS.index(x.split(".")[1])
            for x in model.theta_names]
    for _ in range(5):
        q0, v0, w0, a0 = (rng.normal(size=n) for _ in range(4))
        Ds, Cs, Gs, tau, Y, y0 = staged(q0, v0, w0, a0, theta)
        for x, y in zip((Ds, Cs, Gs), closed(q0, v0, w0, a0, theta)):
            _close(x, y)
        M = pin.crba(pm, data, q0)
        _close(Ds, np.triu(M) + np.triu(M, 1).T)
        _close(Cs, pin.computeCoriolisMatrix(pm, data, q0, v0))
        _close(Gs, pin.computeGeneralizedGravity(pm, data, q0))
        _close(tau, np.asarray(Ds) @ a0 + np.asarray(Cs) @ w0 + np.asarray(Gs).ravel())
        _close(np.asarray(Y) @ theta + np.asarray(y0).ravel(), np.asarray(tau).ravel())
        # at w = v, Y's columns are Pinocchio's for those parameters
        _close(staged(q0, v0, v0, a0, theta)[4], pin.computeJointTorqueRegressor(pm, data, q0, v0, a0)[:, cols])
