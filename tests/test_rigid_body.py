"""Rigid-body dynamics against properties (3), Newton-Euler (one body) and Pinocchio (any tree)."""
import numpy as np
import sympy as sp

from hydrogen.symbolic import kinematics as K
from hydrogen.symbolic import rigid_body as RB

from conftest import random_theta, workspace_poses
from reference import newton_euler


def test_D_symmetric_positive_definite_over_workspace(robot_dyn, robot_model, rng):
    # ±10 %: θ may hold first moments and inertias about a joint, which must stay physically
    # consistent (I_o ≥ m c²) for D to be positive definite
    for q in workspace_poses(robot_model, 50, rng, scale=3.0):
        D = robot_dyn.mass_matrix(q, random_theta(robot_model, rng, spread=0.1))
        np.testing.assert_allclose(D, D.T, atol=1e-12 * np.abs(D).max())
        assert np.linalg.eigvalsh(D).min() > 0


def test_Ddot_minus_2C_is_skew(robot_dyn, robot_model, rng):
    h, n = 1e-6, robot_model.n
    for q in workspace_poses(robot_model, 20, rng, scale=3.0):
        th, qd = random_theta(robot_model, rng), rng.normal(size=n)
        Ddot = (robot_dyn.mass_matrix(q + h * qd, th) - robot_dyn.mass_matrix(q - h * qd, th)) / (2 * h)
        N = Ddot - 2 * robot_dyn.coriolis(q, qd, th)
        np.testing.assert_allclose(N + N.T, 0, atol=1e-6 * np.abs(N).max())
        assert np.abs(N).max() > 1e-3  # the test has teeth: N itself is not zero


def test_C_is_symmetric_in_its_two_velocity_slots(robot_dyn, robot_model, rng):
    n = robot_model.n
    for q in workspace_poses(robot_model, 20, rng, scale=3.0):
        th, x, y = random_theta(robot_model, rng), rng.normal(size=n), rng.normal(size=n)
        lhs, rhs = robot_dyn.coriolis(q, x, th) @ y, robot_dyn.coriolis(q, y, th) @ x
        np.testing.assert_allclose(lhs, rhs, atol=1e-10 * max(1.0, np.abs(lhs).max()))


def test_paper_c22_gives_the_same_C_qdot(model):
    q, qd, th = K.pose_symbols(model), K.rate_symbols("qd", 6), RB.theta_symbols(model)
    D = RB.mass_matrix(model, q, th)
    diff = RB.coriolis(D, q, qd) * qd - RB.coriolis_paper(q, qd, th) * qd
    f = sp.lambdify([q, qd, th], diff, "numpy")
    rng = np.random.default_rng(7)
    for _ in range(20):
        val = f(rng.uniform(-1, 1, 6), rng.normal(size=6), rng.uniform(20, 300, 4))
        np.testing.assert_allclose(np.asarray(val, float), 0, atol=1e-9)


def test_regressor_matches_newton_euler(dyn, model, rng):
    for q in workspace_poses(model, 20, rng, scale=3.0):
        qd, qdd, th = rng.normal(size=6), rng.normal(size=6), random_theta(model, rng)
        Y = dyn.regressor(q, qd, qd, qdd)
        np.testing.assert_allclose(Y @ th, newton_euler(model, th, q, qd, qdd), rtol=1e-6, atol=1e-5)


def test_regressor_slots_match_D_C_G(robot_dyn, robot_model, rng):
    n = robot_model.n
    for q in workspace_poses(robot_model, 10, rng):
        v, w, a, th = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n), random_theta(robot_model, rng)
        expected = robot_dyn.mass_matrix(q, th) @ a + robot_dyn.coriolis(q, v, th) @ w + robot_dyn.gravity(q, th)
        got = robot_dyn.regressor(q, v, w, a) @ th + robot_dyn.regressor_offset(q, v, w, a)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_inverse_dynamics_matches_newton_euler(dyn, model, rng):
    # the platform against the independent Newton-Euler of tests/reference (the URDF robots: Pinocchio's RNEA)
    for q in workspace_poses(model, 10, rng, scale=3.0):
        qd, qdd, th = rng.normal(size=6), rng.normal(size=6), random_theta(model, rng)
        np.testing.assert_allclose(dyn.inverse_dynamics(q, qd, qdd, th), newton_euler(model, th, q, qd, qdd),
                                   rtol=1e-6, atol=1e-5)
    Q = workspace_poses(model, 4, rng)  # a batch: one call
    V, A = rng.normal(size=(4, 6)), rng.normal(size=(4, 6))
    batch = dyn.inverse_dynamics(Q, V, A, model.theta)
    assert batch.shape == (4, 6)
    np.testing.assert_allclose(batch[2], dyn.inverse_dynamics(Q[2], V[2], A[2], model.theta), rtol=1e-14)


def test_a_floating_body_with_frames_fixed_to_it_keeps_its_closed_form_inverse(model, rng):
    """The Stewart platform with a massless sensor frame and a payload fixed to it (a link at an angle,
    the payload below it): the frame merges into the platform, which stays at its centre of mass, so
    D⁻¹ keeps its closed form, D⁻¹ D = 1 at random poses (D from the merged bodies); with the payload
    off the centre the inverse is left to a solve."""
    from dataclasses import replace

    from hydrogen.model import Joint, Link
    from hydrogen.symbolic.tree import SymbolicTree

    frame = Link("imu", 0.0, np.zeros(3), np.zeros((3, 3)))
    mount = Joint("imu_mount", "fixed", "platform", "imu", np.array([0.1, 0.0, 0.2]), np.array([0.3, 0.0, 0.0]),
                  np.array([1.0, 0.0, 0.0]))
    sensed = replace(model, links=(*model.links, frame), joints=(*model.joints, mount))
    payload = Link("payload", 20.0, np.array([1.0, 0.0, 0.4]), np.diag([0.4, 0.5, 0.3]))
    carried = replace(sensed, links=(*sensed.links, payload),
                      joints=(*sensed.joints, replace(mount, name="payload_mount", parent="imu", child="payload")))
    q = K.pose_symbols(model)
    for m, closed in ((sensed, True), (carried, False)):
        tree = SymbolicTree(m, q, RB.theta_symbols(m))
        assert tree.single_floating_body() is closed
        Dinv = tree.mass_matrix_inverse()
        assert (Dinv is not None) is closed
        if closed:
            f = sp.lambdify(list(q) + list(RB.theta_symbols(m)), [tree.mass_matrix(), Dinv], "numpy")
            for pose in workspace_poses(m, 4, rng):
                D, Di = (np.asarray(x, float) for x in f(*pose, *m.theta))
                np.testing.assert_allclose(Di @ D, np.eye(m.n), atol=1e-12)
