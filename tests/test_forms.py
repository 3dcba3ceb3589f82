"""The rigid body's two forms (``rigid_body_form``, :mod:`hydrogen.symbolic.forms`) on the spatial
3-DOF leg of benchmarks/bench_forms.py, where both apply: the same D, C, G, Y, τ and q̈ (and
Pinocchio's), "auto" takes the form of fewer instructions, the key forces a form, a bad value stops
at load time naming the file and the key. CasADi Functions straight from the derivation (no C)."""
import sys
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.errors import ModelError
from hydrogen.model import INERTIAL_PARAMETERS
from hydrogen.symbolic import kinematics as K
from hydrogen.symbolic import rigid_body as RB
from hydrogen.symbolic.forms import FORMS, form_costs, oblique_joints, rigid_body_form, with_form
from hydrogen.symbolic.functions import rigid_body_functions
from hydrogen.symbolic.tree import SymbolicTree

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from bench_forms import leg_model  # noqa: E402
from bench_scaling import chain_model  # noqa: E402

FUNCTIONS = ("mass_matrix", "coriolis", "gravity", "regressor", "inverse_dynamics", "forward_dynamics")


@pytest.fixture(scope="module")
def leg():
    return leg_model()


@pytest.fixture(scope="module")
def funcs(leg):
    """Per form, the leg's rigid-body functions as CasADi Functions, by name."""
    return {f: {sf.name: to_casadi_function(sf) for sf in rigid_body_functions(with_form(leg, f))} for f in FORMS}


def _close(a, b):
    b = np.asarray(b, float)
    a = np.asarray(a, float).reshape(b.shape)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(b).max()))


def test_both_forms_give_the_same_dynamics_as_pinocchio(leg, funcs, rng):
    pin = pytest.importorskip("pinocchio")
    from test_staged_rigid_body import _pinocchio

    pm = _pinocchio(leg)
    data = pm.createData()
    child = {j.name: j.child for j in leg.joints}
    cols = {f"{child[pm.names[jid]]}.{p}": 10 * (jid - 1) + k
            for jid in range(1, pm.njoints) for k, p in enumerate(INERTIAL_PARAMETERS)}
    sel = [cols[x] for x in leg.theta_names]
    closed, staged = funcs["closed"], funcs["staged"]
    assert set(closed) == set(staged)
    for _ in range(6):
        q = leg.neutral_pose + rng.uniform(-1, 1, leg.n)
        v, w, a = (rng.normal(size=leg.n) for _ in range(3))
        th = leg.theta * rng.uniform(0.5, 1.5, leg.n_theta)
        tau = rng.normal(size=leg.n) * 50
        args = {"mass_matrix": (q, th), "coriolis": (q, v, th), "gravity": (q, th), "regressor": (q, v, w, a),
                "regressor_offset": (q, v, w, a), "inverse_dynamics": (q, v, a, th),
                "forward_dynamics": (q, v, tau, th)}
        for name in closed:
            _close(staged[name](*args[name]), closed[name](*args[name]))
        Y = np.asarray(closed["regressor"](q, v, v, a))
        _close(Y, pin.computeJointTorqueRegressor(pm, data, q, v, a)[:, sel])
        _close(closed["inverse_dynamics"](q, v, a, leg.theta), pin.rnea(pm, data, q, v, a))
        _close(closed["forward_dynamics"](q, v, tau, leg.theta), pin.aba(pm, data, q, v, tau))
        # Y θ + y0 = D a + C(q, v) w + G with w ≠ v, in each form
        for f in FORMS:
            F = funcs[f]
            D, C, G = (np.asarray(x) for x in (F["mass_matrix"](q, th), F["coriolis"](q, v, th), F["gravity"](q, th)))
            y0 = np.asarray(F["regressor_offset"](q, v, w, a)).ravel() if "regressor_offset" in F else 0.0
            _close(np.asarray(F["regressor"](q, v, w, a)) @ th + y0, D @ a + C @ w + G.ravel())


def test_auto_takes_the_form_of_fewer_instructions(leg):
    totals = {f: sum(form_costs(leg, f).values()) for f in FORMS}
    assert totals["closed"] != totals["staged"]  # a real decision, not a tie
    assert rigid_body_form(leg) == min(totals, key=totals.get)
    q = K.pose_symbols(leg)
    assert SymbolicTree(leg, q, RB.theta_symbols(leg)).staged() == (rigid_body_form(leg) == "staged")


def test_auto_without_counting_a_floating_body_and_a_deep_chain():
    assert rigid_body_form(hydrogen.load_model("ubc_stewart")) == "closed"  # the staged form cannot take it
    assert rigid_body_form(chain_model(4)) == "staged"


URDF_LEG = Path(__file__).resolve().parent.parent / "benchmarks" / "data" / "urdf_leg.toml"


def test_auto_stages_a_tree_of_oblique_joints_without_counting(monkeypatch):
    # the URDF-born leg (rpy origins): its closed form is never derived, not even to be counted
    import hydrogen.symbolic.forms as forms

    model = hydrogen.load_model(URDF_LEG)
    assert forms.oblique_joints(model) == ["haa_joint", "hfe_joint"]
    monkeypatch.setattr(forms, "form_costs", lambda *a: pytest.fail("counted the forms"))
    assert rigid_body_form(model) == "staged"


def test_oblique_joints_are_rotated_origins_and_tilted_axes(leg):
    import dataclasses

    assert oblique_joints(leg) == []  # axis-aligned: counted as before
    j = leg.joints[1]
    for changed in (dataclasses.replace(j, origin_rpy=np.array([0.0, 0.0, 1e-3])),
                    dataclasses.replace(j, axis=np.array([0.0, 0.6, 0.8]))):
        assert oblique_joints(dataclasses.replace(leg, joints=(leg.joints[0], changed, *leg.joints[2:]))) == [j.name]
    flipped = dataclasses.replace(j, axis=np.array([0.0, -1.0, 0.0]))  # a flipped axis is still a coordinate axis
    assert oblique_joints(dataclasses.replace(leg, joints=(leg.joints[0], flipped, *leg.joints[2:]))) == []
    # a payload fixed at an angle below the last link is merged into it, no rotation of the chain;
    # the same mount with a moving joint below it turns the chain
    from hydrogen.model import Joint, Link

    payload = Link("payload", 5.0, np.array([0.1, 0.0, 0.0]), np.eye(3))
    mount = Joint("mount", "fixed", "shank", "payload", np.array([0.0, 0.0, -0.4]), np.array([0.0, 0.3, 0.0]),
                  np.array([1.0, 0.0, 0.0]))
    with_payload = dataclasses.replace(leg, links=(*leg.links, payload), joints=(*leg.joints, mount))
    assert oblique_joints(with_payload) == []
    wrist = Joint("wrist", "revolute", "payload", "tool", np.zeros(3), np.zeros(3), np.array([0.0, 1.0, 0.0]))
    tool = Link("tool", 1.0, np.zeros(3), np.eye(3))
    assert oblique_joints(dataclasses.replace(with_payload, links=(*with_payload.links, tool),
                                              joints=(*with_payload.joints, wrist))) == ["mount"]


@pytest.mark.parametrize("form", FORMS)
def test_the_key_forces_the_form(form):
    model = leg_model(form)
    assert model.rigid_body_form == form and rigid_body_form(model) == form
    q = K.pose_symbols(model)
    assert SymbolicTree(model, q, RB.theta_symbols(model)).staged() == (form == "staged")
    assert bool(RB.rigid_body_stages(model, q)) == (form == "staged")  # the functions evaluate the poses
    assert model.baked_hash() != leg_model().baked_hash()  # a forced form is another compiled library


def test_auto_keeps_the_hash_of_a_description_without_the_key():
    from bench_forms import leg_description
    from hydrogen.model import model_from_dict

    assert model_from_dict(leg_description()).baked_hash() == leg_model("auto").baked_hash()


def test_a_bad_value_names_the_file_and_the_key(tmp_path):
    from hydrogen.model import model_path

    text = model_path("ubc_stewart").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text('rigid_body_form = "fast"\n' + text)
    with pytest.raises(ModelError, match=r"bad\.toml: rigid_body_form: expected one of 'auto', 'closed', "
                                         r"'staged', got 'fast'"):
        hydrogen.load_model(bad)
    bad.write_text('rigid_body_form = "staged"\n' + text)  # the platform's joint is floating
    with pytest.raises(ModelError, match=r"bad\.toml: rigid_body_form: 'staged' takes revolute, .*floating"):
        hydrogen.load_model(bad)
    bad.write_text('rigid_body_form = "closed"\n' + text)
    assert hydrogen.load_model(bad).rigid_body_form == "closed"
