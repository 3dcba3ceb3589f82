"""D, C, G and the regressor of every URDF-described robot against Pinocchio built from the same URDF."""
import numpy as np
import pytest

import hydrogen
from hydrogen.model import INERTIAL_PARAMETERS

from conftest import MODELS, workspace_poses

pin = pytest.importorskip("pinocchio")
from pathlib import Path

# every shipped URDF-described robot, and the benchmarks' URDF-born leg (rpy origins, full inertias)
URDF_MODELS = [m for m in MODELS if hydrogen.load_model(m).urdf is not None] \
    + [str(Path(__file__).resolve().parent.parent / "benchmarks" / "data" / "urdf_leg.toml")]


@pytest.fixture(scope="module", params=URDF_MODELS)
def robot(request, cache):
    model = hydrogen.load_model(request.param)
    dyn = hydrogen.build(model, cache=cache, controllers=())  # the rigid body's functions: the core alone
    pm = pin.buildModelFromUrdf(str(model.urdf))
    assert pm.nq == model.n and pm.nv == model.n  # same coordinates: revolute/prismatic joints in tree order
    return model, dyn, pm, pm.createData()


def _states(model, rng, n=10):
    for q in workspace_poses(model, n, rng, scale=2.0):
        yield q, rng.normal(size=model.n), rng.normal(size=model.n)


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(b).max()))


def test_inverse_dynamics_equals_rnea(robot, rng):
    model, dyn, pm, data = robot
    th = model.theta
    for q, v, a in _states(model, rng):
        tau = pin.rnea(pm, data, q, v, a)
        _close(dyn.mass_matrix(q, th) @ a + dyn.coriolis(q, v, th) @ v + dyn.gravity(q, th), tau)


def test_generated_inverse_dynamics_equals_rnea(robot, rng):
    model, dyn, pm, data = robot
    for q, v, a in _states(model, rng):
        _close(dyn.inverse_dynamics(q, v, a, model.theta), pin.rnea(pm, data, q, v, a))


def test_mass_matrix_equals_crba(robot, rng):
    model, dyn, pm, data = robot
    for q, _, _ in _states(model, rng):
        M = pin.crba(pm, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        _close(dyn.mass_matrix(q, model.theta), M)


def test_coriolis_and_gravity_equal_pinocchios(robot, rng):
    model, dyn, pm, data = robot
    for q, v, _ in _states(model, rng):
        _close(dyn.gravity(q, model.theta), pin.computeGeneralizedGravity(pm, data, q))
        _close(dyn.coriolis(q, v, model.theta) @ v,
               pin.nonLinearEffects(pm, data, q, v) - pin.computeGeneralizedGravity(pm, data, q))
        _close(dyn.coriolis(q, v, model.theta), pin.computeCoriolisMatrix(pm, data, q, v))


def test_regressor_columns_equal_pinocchios_joint_torque_regressor(robot, rng):
    """Y's column for parameter 'link.p' is Pinocchio's column for that link's dynamic parameter p."""
    model, dyn, pm, data = robot
    child = {j.name: j.child for j in model.joints}
    cols = {}
    for jid in range(1, pm.njoints):
        link = child[pm.names[jid]]
        for k, p in enumerate(INERTIAL_PARAMETERS):
            cols[f"{link}.{p}"] = 10 * (jid - 1) + k
    # Pinocchio's parameters must be ours: same inertias from the same URDF (but for a link with a
    # fixed child, which Pinocchio merges into it and hydrogen keeps apart, as a non-adapted share)
    pi = np.concatenate([pm.inertias[j].toDynamicParameters() for j in range(1, pm.njoints)])
    merged = {j.parent for j in model.joints if j.type == "fixed"}
    own = [i for i, n in enumerate(model.theta_names) if n.split(".")[0] not in merged]
    assert own  # something is compared
    _close(np.asarray(model.theta)[own], pi[[cols[model.theta_names[i]] for i in own]])
    for q, v, a in _states(model, rng):
        R = pin.computeJointTorqueRegressor(pm, data, q, v, a)
        _close(dyn.regressor(q, v, v, a), R[:, [cols[n] for n in model.theta_names]])
        _close(dyn.regressor(q, v, v, a) @ model.theta + dyn.regressor_offset(q, v, v, a), R @ pi)


def test_generated_forward_dynamics_equals_aba(robot, rng):
    model, dyn, pm, data = robot
    for q, v, _ in _states(model, rng):
        tau = rng.normal(size=model.n) * 1e3
        _close(dyn.forward_dynamics(q, v, tau, model.theta), pin.aba(pm, data, q, v, tau))


@pytest.mark.parametrize("name", [m for m in MODELS if hydrogen.load_model(m).urdf is not None])
def test_a_payload_fixed_at_an_angle_is_merged_as_pinocchio_merges_it(name, tmp_path, rng):
    """A 20 kg payload (full inertia, on a fixed joint at an angle) added to the URDF of a shipped robot:
    hydrogen merges it into the link it is fixed to (the closed form's bodies) and Pinocchio, reading
    the same URDF, into that joint's body. D, C, G and Y (the adapted links' own columns) from the
    derivation, as CasADi Functions, equal Pinocchio's."""
    import sys

    from hydrogen.codegen.casadi_functions import to_casadi_function
    from hydrogen.symbolic.functions import rigid_body_functions

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    from bench_structural import with_fixed_link

    model = hydrogen.load_model(with_fixed_link(name, tmp_path))
    assert any(j.type == "fixed" for j in model.joints) and model.rigid_body_form_chosen() == "closed"
    f = {sf.name: to_casadi_function(sf) for sf in rigid_body_functions(model)}
    pm = pin.buildModelFromUrdf(str(model.urdf))
    data = pm.createData()
    child = {j.name: j.child for j in model.joints}
    cols = {f"{child[pm.names[jid]]}.{p}": 10 * (jid - 1) + k
            for jid in range(1, pm.njoints) for k, p in enumerate(INERTIAL_PARAMETERS)}
    th = model.theta
    for q, v, a in _states(model, rng, n=5):
        M = pin.crba(pm, data, q)
        _close(np.asarray(f["mass_matrix"](q, th)), np.triu(M) + np.triu(M, 1).T)
        _close(np.asarray(f["gravity"](q, th)).ravel(), pin.computeGeneralizedGravity(pm, data, q))
        _close(np.asarray(f["coriolis"](q, v, th)), pin.computeCoriolisMatrix(pm, data, q, v))
        R = pin.computeJointTorqueRegressor(pm, data, q, v, a)
        _close(np.asarray(f["regressor"](q, v, v, a)), R[:, [cols[n] for n in model.theta_names]])
