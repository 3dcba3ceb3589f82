"""Forward dynamics by the articulated-body algorithm, inverse dynamics by recursive Newton-Euler and
D by composite bodies (hydrogen.symbolic.articulated): the same q̈ as the symbolic solve of
D q̈ = τ − C q̇ − G it replaced and as Pinocchio's aba, the same τ as D a + C q̇ + G and Pinocchio's
rnea, the same D as the form's and Pinocchio's crba, on the planar chain of
benchmarks/bench_scaling.py (n = 2 ... 6, closed and staged forms) and on a branched tree of every
joint type they take; their CasADi instructions grow by a constant per link.

The functions are evaluated as CasADi Functions straight from the derivation (no C compile)."""
import sys
from pathlib import Path

import numpy as np
import pytest

from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.symbolic import kinematics as K
from hydrogen.symbolic import rigid_body as RB
from hydrogen.symbolic.articulated import articulated_body_stages, composite_body_stages, newton_euler_stages
from hydrogen.symbolic.functions import SymbolicFunction, rigid_body_functions
from hydrogen.symbolic.tree import SymbolicTree

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from bench_scaling import chain_model  # noqa: E402
from test_staged_rigid_body import _branching_tree, _christoffel, _close, _pinocchio  # noqa: E402

pin = pytest.importorskip("pinocchio")


def _solve_function(model):
    """q̈ by the symbolic solve of D q̈ = τ − C q̇ − G (what forward_dynamics was), in the model's form."""
    n = model.n
    q, qd, tau, th = K.pose_symbols(model), K.rate_symbols("qdot", n), K.rate_symbols("tau", n), RB.theta_symbols(model)
    qdd = K.rate_symbols("solve_qdd", n)
    stages = [*RB.rigid_body_stages(model, q),
              (qdd, ("solve", RB.mass_matrix(model, q, th), tau - RB.bias_forces(model, q, qd, th)))]
    return to_casadi_function(SymbolicFunction("solve", [("q", q), ("qdot", qd), ("tau", tau), ("theta", th)],
                                               [("qddot", qdd)], "", stages))


def _form_mass_matrix(model):
    """D as the model's form derives it (what C, G and the controllers are derived with)."""
    q, th = K.pose_symbols(model), RB.theta_symbols(model)
    return to_casadi_function(SymbolicFunction("D", [("q", q), ("theta", th)], [("D", RB.mass_matrix(model, q, th))],
                                               "", RB.rigid_body_stages(model, q)))


def _crba(pm, data, q):
    M = pin.crba(pm, data, q)
    return np.triu(M) + np.triu(M, 1).T


@pytest.mark.parametrize("n", range(2, 7))
def test_chain_forward_dynamics_equals_the_solve_pinocchio_and_D_C_G(n, rng):
    chain = chain_model(n)
    funcs = {sf.name: to_casadi_function(sf) for sf in rigid_body_functions(chain)}
    solve, form_D = _solve_function(chain), _form_mass_matrix(chain)
    pm = _pinocchio(chain)
    data = pm.createData()
    for _ in range(4):
        q = chain.neutral_pose + rng.uniform(-1, 1, n)
        v, tau = rng.normal(size=n), rng.normal(size=n) * 100
        _close(funcs["forward_dynamics"](q, v, tau, chain.theta), pin.aba(pm, data, q, v, tau))
        th = chain.theta * rng.uniform(0.5, 1.5, chain.n_theta)  # θ an input: any parameters
        qdd = np.asarray(funcs["forward_dynamics"](q, v, tau, th)).ravel()
        # the solve (CasADi's symbolic QR) loses digits with D's condition number: a looser bound
        # than against Pinocchio, whose aba the recursive q̈ meets to round-off
        np.testing.assert_allclose(qdd, np.asarray(solve(q, v, tau, th)).ravel(), rtol=1e-6)
        D, C, G = (np.asarray(f) for f in (funcs["mass_matrix"](q, th), funcs["coriolis"](q, v, th),
                                           funcs["gravity"](q, th)))
        _residual(D, C @ v + G.ravel(), qdd, tau)
        _close(D, form_D(q, th))
        _close(funcs["mass_matrix"](q, chain.theta), _crba(pm, data, q))
        a = rng.normal(size=n)
        _close(funcs["inverse_dynamics"](q, v, a, th), D @ a + C @ v + G.ravel())
        _close(funcs["inverse_dynamics"](q, v, a, chain.theta), pin.rnea(pm, data, q, v, a))


def _residual(D, bias, qdd, tau):
    """D q̈ + bias = τ to round-off of the largest term."""
    scale = max(np.abs(tau).max(), np.abs(D @ qdd).max(), np.abs(bias).max())
    np.testing.assert_allclose(D @ qdd + bias, tau, rtol=0, atol=1e-11 * scale)


def test_branched_tree_forward_dynamics_equals_pinocchio_and_D_C_G(rng):
    """Revolute, prismatic and fixed joints on two branches, adapted parameters of every kind."""
    model, theta = _branching_tree(rng)
    n = len(model.coordinate_names)
    q, qd, tau, th = K.rate_symbols("q", n), K.rate_symbols("v", n), K.rate_symbols("tau", n), RB.theta_symbols(model)
    tree = SymbolicTree(model, q, th)
    qdd, stages = articulated_body_stages(tree, qd, tau, model.gravity)
    D = tree.mass_matrix()
    inputs = [("q", q), ("v", qd), ("tau", tau), ("th", th)]
    fd = to_casadi_function(SymbolicFunction("fd", inputs, [("qdd", qdd)], "", stages))
    tau_id, id_stages = newton_euler_stages(tree, qd, tau, model.gravity)  # "tau" is the acceleration here
    rnea = to_casadi_function(SymbolicFunction("id", inputs, [("f", tau_id)], "", id_stages))
    D_crba, crba_stages = composite_body_stages(tree)
    crba = to_casadi_function(SymbolicFunction("crba", inputs, [("D", D_crba)], "", crba_stages))
    dcg = _christoffel(to_casadi_function(SymbolicFunction("dg", inputs, [("D", D), ("G", tree.gravity(model.gravity))],
                                                           "")))
    pm = _pinocchio(model)
    data = pm.createData()
    for _ in range(5):
        q0, v0, tau0 = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n) * 10
        got = np.asarray(fd(q0, v0, tau0, theta)).ravel()
        _close(got, pin.aba(pm, data, q0, v0, tau0))
        th0 = theta * rng.uniform(0.5, 1.5, len(theta))
        got = np.asarray(fd(q0, v0, tau0, th0)).ravel()
        D0, C0, G0 = (np.asarray(x) for x in dcg(q0, v0, tau0, th0))
        _residual(D0, C0 @ v0 + G0.ravel(), got, tau0)
        a0 = rng.normal(size=n)
        _close(rnea(q0, v0, a0, th0), D0 @ a0 + C0 @ v0 + G0.ravel())
        _close(rnea(q0, v0, a0, theta), pin.rnea(pm, data, q0, v0, a0))
        _close(crba(q0, v0, tau0, th0), D0)
        _close(crba(q0, v0, tau0, theta), _crba(pm, data, q0))


def _instructions(n, stages_of):
    chain = chain_model(n)
    q, qd, x, th = K.pose_symbols(chain), K.rate_symbols("qdot", n), K.rate_symbols("x", n), \
        RB.theta_symbols(chain)
    out, stages = stages_of(SymbolicTree(chain, q, th), qd, x, chain.gravity)
    inputs = [("q", q), ("qdot", qd), ("x", x), ("theta", th)]
    return to_casadi_function(SymbolicFunction("f", inputs, [("out", out)], "", stages)).n_instructions()


@pytest.mark.parametrize("stages_of", [articulated_body_stages, newton_euler_stages])
def test_instructions_grow_by_a_constant_per_link(stages_of):
    """Each link adds the same work (its stages refer to its neighbours' symbols only)."""
    counts = [_instructions(n, stages_of) for n in (4, 5, 6, 7)]
    steps = np.diff(counts)
    assert steps.min() > 0 and steps.max() - steps.min() <= 0.05 * steps.mean(), counts


def test_a_fixed_mount_on_the_root_and_two_branches_from_it(rng):
    """The branched tree hung from the base by a fixed, rotated mount (its body weighs on no joint),
    with a second branch from the mount: q̈, τ and D against Pinocchio."""
    from dataclasses import replace

    from hydrogen.model import Joint, Link

    model, _ = _branching_tree(rng)
    mount = Joint("mount", "fixed", "base", "m", np.array([0.1, 0.2, 0.3]), np.array([0.3, -0.2, 0.5]),
                  np.array([1.0, 0.0, 0.0]))
    side = Joint("side", "revolute", "m", "s", np.array([0.0, 0.2, 0.0]), np.array([0.0, 0.0, 0.4]),
                 np.array([0.0, 0.0, 1.0]))
    joints = (mount, *(replace(j, parent="m") if j.parent == "base" else j for j in model.joints), side)
    links = (*model.links, Link("m", 7.0, np.array([0.1, 0.0, 0.0]), np.eye(3)),
             Link("s", 2.0, np.array([0.0, 0.1, 0.0]), np.diag([0.1, 0.2, 0.3])))
    model = replace(model, joints=joints, links=links, coordinate_names=(*model.coordinate_names, "side"))
    theta = np.array([model.link(x.split(".")[0]).parameters()[x.split(".")[1]] for x in model.theta_names])
    n = len(model.coordinate_names)
    q, qd, x, th = K.rate_symbols("q", n), K.rate_symbols("v", n), K.rate_symbols("x", n), RB.theta_symbols(model)
    tree = SymbolicTree(model, q, th)
    inputs = [("q", q), ("v", qd), ("x", x), ("th", th)]
    fns = {}
    for name, (out, stages) in (("aba", articulated_body_stages(tree, qd, x, model.gravity)),
                                ("rnea", newton_euler_stages(tree, qd, x, model.gravity)),
                                ("crba", composite_body_stages(tree))):
        fns[name] = to_casadi_function(SymbolicFunction(name, inputs, [("out", out)], "", stages))
    pm = _pinocchio(model)
    data = pm.createData()
    assert pm.nv == n
    for _ in range(3):
        q0, v0, x0 = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        _close(fns["aba"](q0, v0, x0 * 10, theta), pin.aba(pm, data, q0, v0, x0 * 10))
        _close(fns["rnea"](q0, v0, x0, theta), pin.rnea(pm, data, q0, v0, x0))
        _close(fns["crba"](q0, v0, x0, theta), _crba(pm, data, q0))


def test_the_plants_accelerations_are_the_forward_dynamics_of_the_cylinder_forces(rng):
    """plant_rhs's q̈ rows (its own articulated-body pass) = forward_dynamics(q, q̇, JLᵀ f), f the
    cylinders' pressure forces (no friction), on the chain in the staged form."""
    from hydrogen.pressures import n_pressures
    from hydrogen.symbolic.functions import derive_functions

    chain = chain_model(4)
    n = chain.n
    f = {sf.name: to_casadi_function(sf) for sf in derive_functions(chain, controllers=False)
         if sf.name in ("plant_rhs", "forward_dynamics", "leg_jacobian", "leg_force")}
    for _ in range(3):
        q, qd = chain.neutral_pose + rng.uniform(-0.2, 0.2, n), rng.normal(size=n)
        pc = np.asarray(chain.supply_pressure, float) * rng.uniform(0.3, 0.7, n_pressures(chain))
        x = np.concatenate([q, qd, pc, np.zeros(2 * chain.n_cylinders)])
        xdot = np.asarray(f["plant_rhs"](x, np.zeros(chain.n_cylinders), chain.theta, *chain.gamma,
                                         np.tile([0.0, 0.0, 1e-3], chain.n_cylinders), np.zeros(5 * chain.n_cylinders))).ravel()
        tau = np.asarray(f["leg_jacobian"](q)).T @ np.asarray(f["leg_force"](pc)).ravel()
        _close(xdot[n:2 * n], f["forward_dynamics"](q, qd, tau, chain.theta))
