"""Direct calls through the compiled CPython extension, the ctypes fallback, batches and out=.

Shapes and names come from the manifest: nothing here knows the robot's sizes.
"""
import subprocess
import threading

import numpy as np
import pytest

import hydrogen
from hydrogen.layout import NUMBERS
from hydrogen.runtime import extension as ext
from hydrogen.runtime.compiler import Toolchain

NEEDS_EXTENSION = pytest.mark.skipif(ext.unavailable_reason() is not None,
                                     reason=f"extension cannot be built here: {ext.unavailable_reason()}")


@pytest.fixture(scope="module")
def dyn_ctypes(model, cache):
    return hydrogen.build(model, cache=cache, backend="ctypes")


@pytest.fixture(scope="module", params=["extension", "ctypes"])
def either(request, dyn, dyn_ctypes):
    """Each backend in turn: the same semantics and messages are required of both."""
    if request.param == "extension" and dyn.backend != "extension":
        pytest.skip("extension not built here")
    return dyn if request.param == "extension" else dyn_ctypes


def _entries(dyn):
    """The manifest's functions with the inputs a caller passes (the description's numbers are filled
    by the runtime)."""
    return [{**e, "inputs": [i for i in e["inputs"] if i[0] != NUMBERS]} for e in dyn.library.manifest["functions"]]


def _user_shape(rows, cols):
    return (rows,) if cols == 1 else (rows, cols)


def _inputs(entry, model, rng, n=None):
    """Random inputs (stacked when n is given), near the neutral pose for pose-like inputs."""
    out = []
    lead = () if n is None else (n,)
    for name, r, c in entry["inputs"]:
        x = rng.uniform(-1.0, 1.0, lead + _user_shape(r, c))
        if name in ("q", "qd0", "q_hat") and r == model.neutral_pose.size and c == 1:
            x = model.neutral_pose + 0.02 * x
        elif name == "theta" and r == model.theta.size:
            x = model.theta * (1.0 + 0.1 * x)
        elif name == "pc":
            x = 5e6 + 1e5 * x
        out.append(x)
    return out


def _as_tuple(r):
    return r if isinstance(r, tuple) else (r,)


def _bits(a):
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _same_bits(a, b):
    a, b = _as_tuple(a), _as_tuple(b)
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.shape == y.shape and x.dtype == y.dtype == np.float64
        np.testing.assert_array_equal(_bits(x), _bits(y))


@NEEDS_EXTENSION
def test_extension_is_the_default_backend(dyn):
    assert dyn.backend == "extension" and dyn.library.backend == "extension"
    fn = dyn.functions["regressor"]
    assert fn.backend == "extension" and fn.name == "regressor"
    assert fn.in_names == [n for n, _, _ in next(e for e in _entries(dyn) if e["name"] == "regressor")["inputs"]]


def test_ctypes_backend_on_request(dyn_ctypes):
    assert dyn_ctypes.backend == "ctypes"
    assert all(f.backend == "ctypes" for f in dyn_ctypes.functions.values())


@NEEDS_EXTENSION
def test_backends_agree_to_the_bit_for_every_function(dyn, dyn_ctypes, model, rng):
    for entry in _entries(dyn):
        fast, slow = dyn.functions[entry["name"]], dyn_ctypes.functions[entry["name"]]
        for _ in range(3):
            args = _inputs(entry, model, rng)
            _same_bits(fast(*args), slow(*args))
        # and a batch through each (one C loop vs a Python loop)
        args = _inputs(entry, model, rng, n=4)
        _same_bits(fast(*args), slow(*args))


def test_outputs_keep_the_user_visible_layout(either, model, rng):
    """Column vectors come back 1-D, matrices as C-order arrays of the recorded shape."""
    for entry in _entries(either):
        res = _as_tuple(either.functions[entry["name"]](*_inputs(entry, model, rng)))
        for r, (_, rows, cols) in zip(res, entry["outputs"]):
            assert r.shape == _user_shape(rows, cols) and r.flags.c_contiguous and r.dtype == np.float64


def test_batch_equals_the_loop_over_states(either, model, rng):
    n = 5
    for entry in _entries(either):
        fn = either.functions[entry["name"]]
        args = _inputs(entry, model, rng, n=n)
        batch = _as_tuple(fn(*args))
        for k in range(n):
            _same_bits(tuple(b[k] for b in batch), _as_tuple(fn(*[a[k] for a in args])))


def test_one_unstacked_input_broadcasts(either, model, rng):
    n = 7
    entry = next(e for e in _entries(either) if e["name"] == "mass_matrix")
    q = _inputs(entry, model, rng, n=n)[0]
    D = either.mass_matrix(q, model.theta)
    assert D.shape[0] == n
    for k in range(n):
        _same_bits(D[k], either.mass_matrix(q[k], model.theta))
    # a stacked theta gives the same as the shared one repeated
    _same_bits(either.mass_matrix(q, np.tile(model.theta, (n, 1))), D)


def test_zero_states_give_empty_outputs(either, model):
    q = np.empty((0, model.neutral_pose.size))
    D = either.mass_matrix(q, model.theta)
    assert D.shape[0] == 0 and D.ndim == 3


def test_out_writes_in_place_and_returns_it(either, model, rng):
    entry = next(e for e in _entries(either) if e["name"] == "regressor")
    args = _inputs(entry, model, rng)
    want = either.regressor(*args)
    out = np.full_like(want, np.nan)
    assert either.regressor(*args, out=out) is out
    _same_bits(out, want)
    # a batch into a preallocated (n, ...) array
    n = 3
    bargs = _inputs(entry, model, rng, n=n)
    bout = np.empty((n,) + want.shape)
    assert either.regressor(*bargs, out=bout) is bout
    _same_bits(bout, either.regressor(*bargs))
    # several outputs: a tuple of arrays
    kin = next(e for e in _entries(either) if e["name"] == "leg_kinematics")
    q = _inputs(kin, model, rng)[0]
    outs = tuple(np.empty(_user_shape(r, c)) for _, r, c in kin["outputs"])
    assert either.functions["leg_kinematics"](q, out=outs) is outs
    _same_bits(outs, either.functions["leg_kinematics"](q))


def test_lists_and_other_dtypes_are_converted(either, model):
    q = model.neutral_pose + 0.01
    want = either.leg_lengths(q)
    _same_bits(either.leg_lengths(list(q)), want)
    np.testing.assert_allclose(either.leg_lengths(q.astype(np.float32)), want, rtol=1e-6)
    _same_bits(either.leg_lengths(np.asfortranarray(np.vstack([q, q]))), np.vstack([want, want]))
    _same_bits(either.leg_lengths(np.vstack([q, q, q])[::2]), np.vstack([want, want]))  # strided
    with pytest.raises(TypeError, match="leg_lengths: input 'q' cannot be converted to a float64 array"):
        either.leg_lengths(["x"] * q.size)


def test_bad_batches_name_the_argument(either, model, rng):
    entry = next(e for e in _entries(either) if e["name"] == "regressor")
    q, v, w, a = _inputs(entry, model, rng, n=4)
    with pytest.raises(ValueError, match=r"regressor: input 'v' holds 3 states .* input 'q' holds 4"):
        either.regressor(q, v[:3], w, a)
    with pytest.raises(ValueError, match=r"regressor: input 'w' needs shape \(\d+,\), or \(n, \d+\) for a batch"):
        either.regressor(q, v, w[:, :-1], a)
    with pytest.raises(ValueError, match=r"mass_matrix: input 'theta' needs shape"):
        either.mass_matrix(q, np.ones((4, 2, model.theta.size)))
    with pytest.raises(TypeError, match=r"regressor takes 4 inputs \(q, v, w, a\), got 3"):
        either.functions["regressor"](q, v, w)


def test_nan_rows_are_listed(either, model, rng):
    entry = next(e for e in _entries(either) if e["name"] == "regressor")
    q, v, w, a = _inputs(entry, model, rng, n=20)
    q[3, 0] = np.nan
    q[11, -1] = np.nan
    a[7, 2] = np.nan
    with pytest.raises(ValueError) as err:
        either.regressor(q, v, w, a)
    msg = str(err.value)
    assert "regressor: NaN states in a batch" in msg
    assert "input 'q' has NaN in 2 of 20 rows: [3, 11]" in msg and "input 'a' has NaN in 1 of 20 rows: [7]" in msg
    with pytest.raises(ValueError, match=r"input 'theta' \(one value shared by all 20 states\) contains NaN"):
        either.mass_matrix(np.nan_to_num(q), np.full(model.theta.size, np.nan))
    with pytest.raises(ValueError) as err:  # a NaN in a shared input is reported alone
        either.mass_matrix(q, np.full(model.theta.size, np.nan))
    assert "shared by all 20 states" in str(err.value) and "rows" not in str(err.value)
    many = np.full_like(q, np.nan)
    with pytest.raises(ValueError, match=r"has NaN in 20 of 20 rows: \[0, 1, .*, 9\] \.\.\."):
        either.leg_lengths(many)


def test_bad_out_is_rejected(either, model, rng):
    entry = next(e for e in _entries(either) if e["name"] == "regressor")
    args = _inputs(entry, model, rng)
    good = either.regressor(*args)
    # a hydrogen error from either backend (and a ValueError, as numpy's would be)
    assert issubclass(hydrogen.InputError, hydrogen.HydrogenError) and issubclass(hydrogen.InputError, ValueError)
    with pytest.raises(hydrogen.InputError, match=r"regressor: out for output 'Y' needs a writeable C-contiguous "
                       r"float64 array of shape \(\d+, \d+\), got \(2, 3\)$"):
        either.regressor(*args, out=np.empty((2, 3)))
    # the shape is right: the message names the one thing that is wrong, not the shape
    fortran = np.empty(good.shape[::-1]).T
    strided = np.empty((good.shape[0], 2 * good.shape[1]))[:, ::2]
    read_only = np.empty(good.shape)
    read_only.flags.writeable = False
    unaligned = np.frombuffer(bytearray(good.nbytes + 1), np.float64, good.size, offset=1).reshape(good.shape)
    faults = [(np.empty(good.shape, dtype=np.float32), "must be float64, got float32"),
              (np.empty(good.shape, dtype=np.int64), "must be float64, got int64"),
              (np.empty(good.shape, dtype=np.float64).astype(">f8"), "must be float64 in native byte order, got >f8"),
              (fortran, r"must be C-contiguous \(row-major, as np.empty gives\), got a Fortran-order \(column-major\) array"),
              (strided, "must be C-contiguous .*non-contiguous array"),
              (unaligned, "must be aligned, got an unaligned array"),
              (read_only, "must be writeable, got a read-only array")]
    for bad, fault in faults:
        with pytest.raises(ValueError, match=rf"^regressor: out for output 'Y' {fault}$"):
            either.regressor(*args, out=bad)
    with pytest.raises(ValueError, match=r"with n = 2"):
        either.regressor(*_inputs(entry, model, rng, n=2), out=good)
    with pytest.raises(TypeError, match="regressor: out must be an array or a tuple of 1 array"):
        either.regressor(*args, out=[good])
    q = model.neutral_pose + 0.0
    with pytest.raises(ValueError, match="leg_lengths: out for output 'l' shares memory with input 'q'"):
        either.leg_lengths(q, out=q)
    m = len(either.leg_lengths(q))
    both = np.zeros(m * m)  # the lengths written over the Jacobian's first row: refused, as over an input
    with pytest.raises(hydrogen.InputError, match="leg_kinematics: out for output 'l' shares memory with output"):
        either.functions["leg_kinematics"](q, out=(both[:m], both.reshape(m, m)))


def test_forward_dynamics_solves_the_equations_of_motion(either, model, rng):
    entry = next(e for e in _entries(either) if e["name"] == "forward_dynamics")
    q, qdot, tau, _ = _inputs(entry, model, rng, n=8)
    tau = tau * 1e3
    qdd = either.forward_dynamics(q, qdot, tau, model.theta)
    for k in range(len(q)):
        D = either.mass_matrix(q[k], model.theta)
        C = either.coriolis(q[k], qdot[k], model.theta)
        G = either.gravity(q[k], model.theta)
        want = np.linalg.solve(D, tau[k] - C @ qdot[k] - G)
        np.testing.assert_allclose(qdd[k], want, rtol=1e-10, atol=1e-10 * np.abs(want).max())
        _same_bits(either.forward_dynamics(q[k], qdot[k], tau[k], model.theta), qdd[k])
    # and D q̈ + C q̇ + G gives τ back through the regressor: Y(q, q̇, q̇, q̈) θ = τ
    Y = either.regressor(q, qdot, qdot, qdd)
    np.testing.assert_allclose(Y @ model.theta, tau, rtol=1e-9, atol=1e-9 * np.abs(tau).max())


def test_threads_share_a_function_safely(either, model, rng):
    entry = next(e for e in _entries(either) if e["name"] == "regressor")
    states = [_inputs(entry, model, rng) for _ in range(40)]
    want = [either.regressor(*s) for s in states]
    batch = _inputs(entry, model, rng, n=200)
    want_batch = either.regressor(*batch)
    errors = []

    def work():
        try:
            for _ in range(50):
                for s, w in zip(states, want):
                    if not np.array_equal(either.regressor(*s), w):
                        errors.append("single")
                if not np.array_equal(either.regressor(*batch), want_batch):
                    errors.append("batch")
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(repr(exc))

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors


def test_missing_python_headers_fall_back_to_ctypes(model, cache, tmp_path, monkeypatch):
    monkeypatch.setattr(ext, "python_include_dir", lambda: tmp_path / "no-include")
    with pytest.warns(RuntimeWarning, match=r"using ctypes calls .*no Python headers"):
        d = hydrogen.build(model, cache=cache)
    assert d.backend == "ctypes" and d.library.extension_functions is None
    q = model.neutral_pose + 0.01
    assert d.leg_lengths(np.vstack([q, q])).shape[0] == 2
    with pytest.raises(hydrogen.BuildCacheError, match="no Python headers"):
        hydrogen.build(model, cache=cache, backend="extension")


@NEEDS_EXTENSION
def test_failed_extension_build_falls_back_to_ctypes(model, cache, monkeypatch):
    key = ext.abi_key()
    monkeypatch.setattr(ext, "abi_key", lambda: {**key, "test": "broken-render"})  # a key of its own
    monkeypatch.setattr(ext, "render", lambda context: "#error this extension does not compile\n")
    with pytest.warns(RuntimeWarning, match="using ctypes calls .*CompilerError"):
        d = hydrogen.build(model, cache=cache)
    assert d.backend == "ctypes"


@NEEDS_EXTENSION
def test_any_extension_failure_falls_back_but_not_when_the_extension_is_required(model, cache, monkeypatch):
    def broken_render(context):
        raise KeyError("a template variable")

    key = ext.abi_key()
    monkeypatch.setattr(ext, "abi_key", lambda: {**key, "test": "render-raises"})
    monkeypatch.setattr(ext, "render", broken_render)
    with pytest.warns(RuntimeWarning, match="using ctypes calls .*KeyError"):
        assert hydrogen.build(model, cache=cache).backend == "ctypes"
    with pytest.raises(hydrogen.BuildCacheError, match="cannot be used: KeyError"):
        hydrogen.build(model, cache=cache, backend="extension")


@NEEDS_EXTENSION
def test_extension_is_rebuilt_when_the_python_abi_changes(model, cache, dyn, monkeypatch):
    first = dyn.library.extension_path
    assert hydrogen.build(model, cache=cache).library.extension_path == first  # cached
    key = ext.abi_key()
    monkeypatch.setattr(ext, "abi_key", lambda: {**key, "cache_tag": key["cache_tag"] + "-other"})
    other = hydrogen.build(model, cache=cache)
    assert other.backend == "extension"
    assert other.library.extension_path != first and other.library.extension_path.parent != first.parent
    assert first.exists()
    q = model.neutral_pose + 0.01
    _same_bits(other.leg_lengths(q), dyn.leg_lengths(q))


@NEEDS_EXTENSION
def test_rendered_extension_compiles_cleanly_with_werror(dyn, tmp_path):
    """The toolchain's warnings without -Werror build the extension; keep the template clean under it."""
    src = tmp_path / "ext.c"
    src.write_text(ext.render(ext.render_context(dyn.library.manifest)))
    tc = Toolchain()
    argv = [*tc.argv(), "-isystem", str(ext.python_include_dir()), "-isystem", str(ext.numpy_include_dir()),
            "-c", str(src), "-o", str(tmp_path / "ext.o")]
    proc = subprocess.run(argv, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_forward_dynamics_matches_pinocchio_aba(dyn, model, rng):
    """The platform as one free-flying rigid body in Pinocchio (origin at the centre of mass, the
    model's mass and principal inertia): ABA gives the same motion once coordinates are mapped.

    hydrogen: q = [p, ψ, θ, φ] (world position, Euler angles), ω_body = T_b q̇_ang, generalised
    forces τ = [f_world, T_bᵀ n_body]. Pinocchio: v = [Rᵀ ṗ, ω_body], τ = [Rᵀ f_world, n_body], and
    ABA returns dv/dt = [Rᵀ p̈ − ω × Rᵀ ṗ, T_b q̈_ang + Ṫ_b q̇_ang].
    """
    pin = pytest.importorskip("pinocchio")
    import sympy as sp

    from hydrogen.symbolic.kinematics import body_angular_velocity_map, pose_symbols, rate_symbols, rotation

    q_s = pose_symbols(model)
    if q_s.shape[0] != model.neutral_pose.size or model.theta.size != 4:
        pytest.skip("not a single free-flying body with [M, Ix, Iy, Iz] parameters")
    qd_s = rate_symbols("qd", q_s.shape[0])
    ang = slice(3, None)
    Tb_s = body_angular_velocity_map(q_s)
    Tb_dot_s = sum((Tb_s.diff(q_s[k]) * qd_s[k] for k in range(q_s.shape[0])), sp.zeros(*Tb_s.shape))
    R_f = sp.lambdify([q_s], rotation(q_s), "numpy")
    Tb_f = sp.lambdify([q_s], Tb_s, "numpy")
    Tb_dot_f = sp.lambdify([q_s, qd_s], Tb_dot_s, "numpy")

    M, Ixyz = model.theta[0], model.theta[1:]
    pmodel = pin.Model()
    joint = pmodel.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "platform")
    pmodel.appendBodyToJoint(joint, pin.Inertia(M, np.zeros(3), np.diag(Ixyz)), pin.SE3.Identity())
    pmodel.gravity.linear = np.array([0.0, 0.0, -model.gravity])
    pdata = pmodel.createData()

    entry = next(e for e in _entries(dyn) if e["name"] == "forward_dynamics")
    qs, qds, taus, _ = _inputs(entry, model, rng, n=5)
    qdds = dyn.forward_dynamics(qs, qds, 300.0 * taus, model.theta)
    for q, qd, tau, qdd in zip(qs, qds, 300.0 * taus, qdds):
        R, Tb, Tb_dot = (np.array(x, float) for x in (R_f(q), Tb_f(q), Tb_dot_f(q, qd)))
        v_lin, omega = R.T @ qd[:3], Tb @ qd[ang]
        q_pin = np.concatenate([q[:3], pin.Quaternion(R).coeffs()])
        v_pin = np.concatenate([v_lin, omega])
        tau_pin = np.concatenate([R.T @ tau[:3], np.linalg.solve(Tb.T, tau[ang])])
        dv = pin.aba(pmodel, pdata, q_pin, v_pin, tau_pin)
        want = np.concatenate([R.T @ qdd[:3] - np.cross(omega, v_lin), Tb @ qdd[ang] + Tb_dot @ qd[ang]])
        np.testing.assert_allclose(dv, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


def test_forward_dynamics_of_urdf_robots_matches_pinocchio_aba(cache, rng):
    """Every robot read from a URDF: q̈ against Pinocchio's ABA on the same URDF (same coordinates)."""
    pin = pytest.importorskip("pinocchio")
    for name in hydrogen.models():
        model = hydrogen.load_model(name)
        if model.urdf is None:
            continue
        d = hydrogen.build(model, cache=cache)
        pm = pin.buildModelFromUrdf(str(model.urdf))
        data = pm.createData()
        qs = model.neutral_pose + rng.uniform(-0.3, 0.3, (5, model.n))
        qds, taus = rng.normal(size=(5, model.n)), 1e4 * rng.normal(size=(5, model.n))
        got = d.forward_dynamics(qs, qds, taus, model.theta)
        for q, qd, tau, qdd in zip(qs, qds, taus, got):
            want = pin.aba(pm, data, q, qd, tau)
            np.testing.assert_allclose(qdd, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


@NEEDS_EXTENSION
def test_two_extensions_of_one_robot_stay_apart_when_loaded_again(tmp_path):
    """Two builds of one robot (the numbers as inputs, the numbers folded) have extensions of the same
    module name with different tables; loading each again (another build of the same robot) must
    neither give one build the other's functions nor change a module loaded before."""
    def manifest(numbers: bool):
        inputs = [["q", 2, 1]] + ([[NUMBERS, 3, 1]] if numbers else [])
        return {"model_name": "twin", "functions": [
            {"name": "f", "c_name": "twin_f", "inputs": inputs, "outputs": [["y", 2, 1]]}]}

    want = {k: ext.render_context(manifest(k))["functions"][0]["numbers"] for k in (True, False)}
    assert want == {True: True, False: False}
    paths = {k: ext.build_extension(manifest(k), cache=tmp_path) for k in (True, False)}
    assert paths[True] != paths[False]
    loaded = []
    for k in (True, False, True, False, True):
        module = ext.load_extension(paths[k], ext.module_name(manifest(k)))
        loaded.append((k, module))
        for kk, m in loaded:  # each module, the new one and those before it, keeps its own table
            assert m.specs()[0][-1] == int(want[kk]), (kk, m)
