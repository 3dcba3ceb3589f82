import re

import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.symbolic import kinematics as K

from conftest import workspace_poses
from reference import T_matrix, leg_lengths, rotation, vee


def test_T_maps_euler_rates_to_base_frame_angular_velocity(rng):
    """S(ω) = Ṙ Rᵀ with ω = T η̇ (finite differences of R, numpy)."""
    for _ in range(20):
        eta = rng.uniform(-1.2, 1.2, 3)
        eta_dot = rng.normal(size=3)
        h = 1e-6
        Rd = (rotation(*(eta + h * eta_dot)) - rotation(*(eta - h * eta_dot))) / (2 * h)
        omega = vee(Rd @ rotation(*eta).T)
        np.testing.assert_allclose(T_matrix(eta[1], eta[2]) @ eta_dot, omega, atol=1e-8)


def test_symbolic_rotation_and_T_match_numpy(rng):
    q = K.pose_symbols(hydrogen.load_model())
    R, T, Tb = K.rotation(q), K.angular_velocity_map(q), K.body_angular_velocity_map(q)
    for _ in range(5):
        val = rng.uniform(-1, 1, 6)
        sub = dict(zip(q, val))
        Rn = np.array(R.subs(sub), dtype=float)
        np.testing.assert_allclose(Rn, rotation(*val[3:]), atol=1e-14)
        np.testing.assert_allclose(np.array(T.subs(sub), dtype=float), T_matrix(val[4], val[5]), atol=1e-14)
        np.testing.assert_allclose(np.array(Tb.subs(sub), dtype=float), Rn.T @ T_matrix(val[4], val[5]),
                                   atol=1e-14)


def test_leg_lengths_match_geometry(dyn, model, rng):
    for q in workspace_poses(model, 20, rng):
        np.testing.assert_allclose(dyn.leg_lengths(q), leg_lengths(model, q), rtol=1e-14)


def test_leg_lengths_many_is_leg_lengths_row_by_row(dyn, model, rng):
    qs = workspace_poses(model, 50, rng)
    np.testing.assert_array_equal(dyn.leg_lengths_many(qs), np.array([dyn.leg_lengths(q) for q in qs]))
    assert dyn.leg_lengths_many(np.zeros((0, 6))).shape == (0, 6)
    with pytest.raises(ValueError, match=r"\(k, 6\)"):
        dyn.leg_lengths_many(qs[:, :5])
    qs[3, 2], qs[7, 0] = np.nan, np.inf  # refused as leg_lengths refuses NaN, never NaN lengths back
    with pytest.raises(hydrogen.InputError, match=r"poses not finite in 2 of 50 rows: \[3, 7\]"):
        dyn.leg_lengths_many(qs)


def test_neutral_pose_is_mid_stroke(dyn, model):
    l = dyn.leg_lengths(model.neutral_pose)
    assert np.all(l > model.leg_min) and np.all(l < model.leg_max)


def test_leg_jacobian_matches_finite_differences(dyn, model, rng):
    h = 1e-6
    for q in workspace_poses(model, 20, rng):
        fd = np.column_stack([(leg_lengths(model, q + h * e) - leg_lengths(model, q - h * e)) / (2 * h)
                              for e in np.eye(6)])
        np.testing.assert_allclose(dyn.leg_jacobian(q), fd, atol=1e-8)


def test_forward_kinematics_inverts_leg_lengths_on_a_grid(dyn, model):
    axes = [np.linspace(-1, 1, 3)] * 6
    grid = np.stack(np.meshgrid(*axes), -1).reshape(-1, 6)
    poses = model.neutral_pose + grid * np.array([0.05, 0.05, 0.05, 0.12, 0.12, 0.12])
    for q in poses:
        np.testing.assert_allclose(dyn.forward_kinematics(dyn.leg_lengths(q)), q, atol=1e-10)


def test_forward_kinematics_reports_failure(dyn, model):
    impossible = np.full(6, 0.1)  # legs far shorter than the joint circles allow
    with pytest.raises(hydrogen.KinematicsError, match="forward kinematics"):
        dyn.forward_kinematics(impossible, max_iter=30)
    with pytest.raises(hydrogen.KinematicsError, match="not finite"):
        dyn.forward_kinematics(np.full(6, np.nan))


def _evaluate_stages(stages, values):
    """Numeric value of every stage symbol, evaluating the (symbols, expression) stages in order."""
    values = dict(values)
    for syms, expr in stages:
        free = sorted(expr.free_symbols, key=str)
        out = np.array(sp.lambdify(free, list(expr))(*[values[s] for s in free]), float)
        values.update(zip(list(syms), out))
    return values


def test_jl_dot_of_the_controllers_matches_finite_differences(dyn, model, rng):
    """The controllers' staged l, JL and d/dt JL (forward mode through q, R and l) against the
    compiled leg lengths and finite differences of the compiled JL."""
    q, qd = K.pose_symbols(model), K.rate_symbols("qd", 6)
    l, JL, JLdot, stages = K.leg_intermediates(model, q, qd)
    h = 1e-6
    for qv in workspace_poses(model, 10, rng):
        v = rng.normal(size=6) * 0.2
        val = _evaluate_stages(stages, {**dict(zip(q, qv)), **dict(zip(qd, v))})
        lv = np.array([val[s] for s in l])
        Jv = np.array([[val[JL[i, j]] for j in range(6)] for i in range(6)])
        Jd = np.array([[val[JLdot[i, j]] for j in range(6)] for i in range(6)])
        np.testing.assert_allclose(lv, dyn.leg_lengths(qv), rtol=1e-14)
        np.testing.assert_allclose(Jv, dyn.leg_jacobian(qv), atol=1e-12)
        fd = (dyn.leg_jacobian(qv + h * v) - dyn.leg_jacobian(qv - h * v)) / (2 * h)
        np.testing.assert_allclose(Jd, fd, atol=1e-7)


def test_staged_jl_is_the_jacobian_of_the_leg_lengths(model, rng):
    """JL as staged (unit leg vectors and moment arms through T) equals SymPy's own Jacobian of l(q)."""
    q = K.pose_symbols(model)
    _, JL, stages = K.leg_stages(model, q)
    R = K.rotation(q)
    lengths = sp.Matrix([(sp.Matrix(q[:3]) + R * sp.Matrix(c.point_to) - sp.Matrix(c.point_from)).norm()
                         for c in model.cylinders])
    direct = sp.lambdify([q], lengths.jacobian(q))
    for qv in workspace_poses(model, 5, rng, scale=3.0):
        val = _evaluate_stages(stages, dict(zip(q, qv)))
        Jv = np.array([[val[JL[i, j]] for j in range(6)] for i in range(6)])
        np.testing.assert_allclose(Jv, np.array(direct(qv), float), atol=1e-13)


def test_leg_kinematics_is_leg_lengths_and_jacobian_in_one_call(dyn, model, rng):
    fn = dyn.functions["leg_kinematics"]
    for qv in workspace_poses(model, 5, rng):
        lv, Jv = fn(qv)
        np.testing.assert_array_equal(lv, dyn.leg_lengths(qv))
        np.testing.assert_array_equal(Jv, dyn.leg_jacobian(qv))


def test_forward_kinematics_reports_a_singular_jacobian(dyn, model):
    """At θ = 90° (gimbal lock) T, and so JL, loses rank: Newton must stop with a clear error naming the
    condition number and the pose."""
    q0 = model.neutral_pose.copy()
    q0[4] = np.pi / 2
    with pytest.raises(hydrogen.KinematicsError, match=r"JL is singular \(condition number \S+, 1-norm; at most "
                       r"1e\+08\) at q = \[.*1\.57"):
        dyn.forward_kinematics(dyn.leg_lengths(model.neutral_pose + 0.01), q0=q0)


def test_forward_kinematics_refuses_exactly_where_the_condition_number_passes_its_bound(dyn, model, rng):
    """The Newton steps' check of JL's 1-norm condition number (a cheap upper bound first, the exact
    number where the bound does not settle it) decides as the exact number does: a bound just above
    it solves, one just below it refuses and reports it (numpy's np.linalg.cond, 1-norm)."""
    for qa in workspace_poses(model, 3, rng):
        target = dyn.leg_lengths(qa + 1e-6)  # a few Newton steps from qa, whose JL barely changes
        kappa = np.linalg.cond(np.asarray(dyn.leg_jacobian(qa)).reshape(model.n, model.n), 1)
        q = dyn.forward_kinematics(target, q0=qa, max_cond=kappa * 1.001)
        np.testing.assert_allclose(dyn.leg_lengths(q), target, atol=1e-9)
        with pytest.raises(hydrogen.KinematicsError, match=r"JL is singular \(condition number (\S+), 1-norm") as err:
            dyn.forward_kinematics(target, q0=qa, max_cond=kappa * 0.999)
        reported = float(re.search(r"condition number (\S+),", str(err.value)).group(1))
        assert reported == pytest.approx(kappa, rel=5e-3)  # 3 significant digits in the message


def _reference_newton(dyn, l, q, tol=1e-12, max_iter=50):
    """Newton's method in numpy on the compiled l(q) and JL (forward kinematics as it was written in
    Python before the C solver was the only one)."""
    for _ in range(max_iter + 1):
        r = dyn.leg_lengths(q) - l
        if np.max(np.abs(r)) < tol:
            return q
        q = q - np.linalg.solve(dyn.leg_jacobian(q), r)
    raise AssertionError("the reference Newton did not converge")


def test_forward_kinematics_many_is_the_single_sample_solver_warm_started(dyn, model, rng):
    """A batch gives, bit for bit, the single-sample solver run row by row from the previous row's pose,
    and both agree with a plain numpy Newton to the tolerance."""
    Q = model.neutral_pose + np.cumsum(rng.normal(size=(40, 6)) * 0.002, axis=0)  # a trajectory
    L = dyn.leg_lengths_many(Q)
    batch = dyn.forward_kinematics_many(L, q0=model.neutral_pose)
    q, rows = model.neutral_pose, []
    for l in L:
        q = dyn.forward_kinematics(l, q0=q)
        rows.append(q)
    np.testing.assert_array_equal(batch, rows)
    np.testing.assert_allclose(batch, Q, rtol=0, atol=1e-10)
    q, ref = model.neutral_pose, []
    for l in L:
        q = _reference_newton(dyn, l, q)
        ref.append(q)
    np.testing.assert_allclose(batch, ref, rtol=0, atol=1e-11)


def test_forward_kinematics_many_names_the_sample_that_fails(dyn, model):
    L = dyn.leg_lengths_many(np.tile(model.neutral_pose, (5, 1)))
    L[3] = 0.1  # legs far shorter than the joint circles allow
    with pytest.raises(hydrogen.KinematicsError, match=r"^sample 3: forward kinematics") as err:
        dyn.forward_kinematics_many(L, max_iter=30)
    assert err.value.sample == 3
    with pytest.raises(hydrogen.KinematicsError) as single:  # the single sample's words, from the same start
        dyn.forward_kinematics(L[3], q0=model.neutral_pose, max_iter=30)
    assert err.value.reason == str(single.value)
    L[1] = np.nan
    with pytest.raises(hydrogen.KinematicsError, match=r"^sample 1: forward kinematics: leg lengths are not finite"):
        dyn.forward_kinematics_many(L)
    with pytest.raises(hydrogen.KinematicsError, match=r"shape \(k, 6\); got shape \(6,\)"):
        dyn.forward_kinematics_many(L[0])


def test_forward_kinematics_needs_the_compiled_loop_driver(model, dyn):
    """No second solver for dynamics without a compiled library: a clear error, not a silent fallback."""
    from types import SimpleNamespace

    from hydrogen.dynamics import Dynamics
    bare = Dynamics(model, SimpleNamespace(functions=dyn.functions))
    with pytest.raises(hydrogen.KinematicsError, match="no compiled loop driver.*hydrogen.build"):
        bare.forward_kinematics(dyn.leg_lengths(model.neutral_pose))
