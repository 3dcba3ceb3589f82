"""Rigid-body dynamics against properties (3) and an independent Newton-Euler computation."""
import numpy as np
import sympy as sp

from hydrogen.symbolic import kinematics as K
from hydrogen.symbolic import rigid_body as RB

from conftest import workspace_poses
from reference import newton_euler


def _theta(rng):
    return np.array([250.0, 45.0, 45.0, 43.0]) * rng.uniform(0.5, 1.5, 4)


def test_D_symmetric_positive_definite_over_workspace(dyn, model, rng):
    for q in workspace_poses(model, 50, rng, scale=3.0):
        D = dyn.mass_matrix(q, _theta(rng))
        np.testing.assert_allclose(D, D.T, atol=1e-12)
        assert np.linalg.eigvalsh(D).min() > 0


def test_Ddot_minus_2C_is_skew(dyn, model, rng):
    h = 1e-6
    for q in workspace_poses(model, 20, rng, scale=3.0):
        th, qd = _theta(rng), rng.normal(size=6)
        Ddot = (dyn.mass_matrix(q + h * qd, th) - dyn.mass_matrix(q - h * qd, th)) / (2 * h)
        N = Ddot - 2 * dyn.coriolis(q, qd, th)
        np.testing.assert_allclose(N + N.T, 0, atol=1e-6 * np.abs(N).max())
        assert np.abs(N).max() > 1e-3  # the test has teeth: N itself is not zero


def test_C_is_symmetric_in_its_two_velocity_slots(dyn, model, rng):
    for q in workspace_poses(model, 20, rng, scale=3.0):
        th, x, y = _theta(rng), rng.normal(size=6), rng.normal(size=6)
        np.testing.assert_allclose(dyn.coriolis(q, x, th) @ y, dyn.coriolis(q, y, th) @ x, atol=1e-10)


def test_paper_c22_gives_the_same_C_qdot():
    q, qd, th = K.pose_symbols(), K.rate_symbols("qd"), RB.theta_symbols()
    D = RB.mass_matrix(q, th)
    diff = RB.coriolis(D, q, qd) * qd - RB.coriolis_paper(q, qd, th) * qd
    f = sp.lambdify([q, qd, th], diff, "numpy")
    rng = np.random.default_rng(7)
    for _ in range(20):
        val = f(rng.uniform(-1, 1, 6), rng.normal(size=6), rng.uniform(20, 300, 4))
        np.testing.assert_allclose(np.asarray(val, float), 0, atol=1e-9)


def test_regressor_matches_newton_euler(dyn, model, rng):
    for q in workspace_poses(model, 20, rng, scale=3.0):
        qd, qdd, th = rng.normal(size=6), rng.normal(size=6), _theta(rng)
        Y = dyn.regressor(q, qd, qd, qdd)
        np.testing.assert_allclose(Y @ th, newton_euler(model, th, q, qd, qdd), rtol=1e-6, atol=1e-5)


def test_regressor_slots_match_D_C_G(dyn, model, rng):
    for q in workspace_poses(model, 10, rng):
        v, w, a, th = rng.normal(size=6), rng.normal(size=6), rng.normal(size=6), _theta(rng)
        expected = dyn.mass_matrix(q, th) @ a + dyn.coriolis(q, v, th) @ w + dyn.gravity(q, th)
        np.testing.assert_allclose(dyn.regressor(q, v, w, a) @ th, expected, rtol=1e-12, atol=1e-9)
