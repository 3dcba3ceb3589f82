"""The plant's integration (hydrogen.plant.integrator): RK4's order, the pressures held within their
bounds, the sub-steps shared out around a command switch, and its C against its numpy to the bit."""
import ctypes
import math
import subprocess

import numpy as np
import pytest

from hydrogen.plant import integrator

# A toy plant x = [q, q', p1, p2]: two chambers driving a damped mass, fed through a valve opening u;
# written in the same operations in C and in Python, so the two integrations may be compared bit for bit.
_RHS_C = """\
static int plant_rhs(const rhs_params* m, const double* x, const double* u, double* xdot) {
    (void)m;
    xdot[0] = x[1];
    xdot[1] = 3.0 * (x[2] - x[3]) - 0.4 * x[1];
    xdot[2] = 500.0 * (u[0] - 0.2 * x[1]) - 2.0 * x[2];
    xdot[3] = -500.0 * (u[0] - 0.2 * x[1]) - 2.0 * x[3];
    return 0;
}
"""
_PC = slice(2, 4)  # a slice, as the engine passes: the clip writes into x
_LO, _HI = np.zeros(2), np.ones(2)


def _rhs(x, u):
    return np.array([x[1], 3.0 * (x[2] - x[3]) - 0.4 * x[1], 500.0 * (u - 0.2 * x[1]) - 2.0 * x[2],
                     -500.0 * (u - 0.2 * x[1]) - 2.0 * x[3]])


def _period(x, u_held, u_app, n, h, frac, stages):
    """The Python engine's plant over one period, as :meth:`PythonStages.integrate` composes it."""
    pieces = integrator.period_pieces(n, frac, h)
    for (steps, hs), u in zip(pieces, (u_held, u_app) if len(pieces) == 2 else (u_app,)):
        x = integrator.bounded_steps(lambda y: _rhs(y, u), x, steps, hs, _PC, _LO, _HI, stages)
    return x


@pytest.fixture(scope="module")
def c_integrator(tmp_path_factory):
    """The module's C text compiled with the toy plant, warnings as errors: ``period(...)`` and
    ``predictor_steps(...)`` through ctypes."""
    from hydrogen.runtime.compiler import Toolchain

    source = "\n".join([
        "#include <math.h>", "#define NX 4", "#define NPC 2",
        "typedef struct { const double *p_low, *p_high; int bound_stages; } rhs_params;",
        "typedef struct { double h, delay_frac; long long pred_substeps; } config;",
        _RHS_C, integrator.c_functions("2 + "),
        "int period(const config* c, double* x, const double* u_held, const double* u_app, long long n,",
        "           int stages, const double* lo, const double* hi) {",
        "    rhs_params m;", "    m.p_low = lo; m.p_high = hi; m.bound_stages = stages;",
        integrator.C_PERIOD.substitute(failed="1").rstrip("\n"), "    return 0;", "}",
        "long long predictor_steps(const config* c, double dt) {",
        integrator.C_PREDICTOR_STEPS.rstrip("\n"), "    return n;", "}", ""])
    folder = tmp_path_factory.mktemp("integrator")
    (folder / "integrator.c").write_text(source)
    lib = folder / "libintegrator.so"
    proc = subprocess.run([Toolchain().executable(), *Toolchain().flags(), "-shared", "-Wall", "-Wextra",
                           "-Werror", "-o", str(lib), str(folder / "integrator.c"), "-lm"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    c = ctypes.CDLL(str(lib))
    c.period.restype = ctypes.c_int
    c.predictor_steps.restype = ctypes.c_longlong
    return c


class _Config(ctypes.Structure):
    _fields_ = [("h", ctypes.c_double), ("delay_frac", ctypes.c_double), ("pred_substeps", ctypes.c_longlong)]


def _dptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


@pytest.mark.parametrize("stages", [True, False])
@pytest.mark.parametrize("frac", [0.0, 0.00256, 0.37, 0.999])
def test_the_c_integration_is_the_numpy_one_to_the_bit(c_integrator, stages, frac):
    """Ten periods of three sub-steps, the valve opened hard enough that both chambers reach their
    bounds: the C's state equals numpy's exactly after each period, with and without a command switch
    inside it."""
    h, n = 1.0 / 512, 3
    cfg = _Config(h, frac, 4)
    x_c = np.array([0.0, 0.0, 0.5, 0.5])
    x_py = x_c.copy()
    held = 0.0
    hit_bound = False
    for k in range(10):
        u = 0.8 if k < 6 else -0.8
        assert c_integrator.period(ctypes.byref(cfg), _dptr(x_c), _dptr(np.array([held])), _dptr(np.array([u])),
                                   n, int(stages), _dptr(_LO), _dptr(_HI)) == 0
        x_py = _period(x_py, held, u, n, h, frac, stages)
        assert np.array_equal(x_c, x_py), (k, x_c, x_py)
        hit_bound |= bool(np.any((x_py[_PC] == 0.0) | (x_py[_PC] == 1.0)))
        held = u
    assert hit_bound  # the bounds were exercised


def test_the_c_predictor_step_count_is_the_numpy_one(c_integrator):
    h = 1.0 / 512
    for pred in (1, 3, 4, 100):
        cfg = _Config(h, 0.0, pred)
        for periods in (1e-6, 0.00256, 0.25, 1.0 / 3, 0.5, 0.07, 0.7, 1.0, 2.0):
            assert c_integrator.predictor_steps(ctypes.byref(cfg), ctypes.c_double(periods * h)) == \
                integrator.predictor_steps(periods, pred), (pred, periods)
    assert integrator.predictor_steps(1.0, 4) == 4  # a whole period: exactly predictor_substeps
    assert 0.07 * 100 > 7 and integrator.predictor_steps(0.07, 100) == 7  # 7.000000000000001: not 8 steps


def test_rk4_is_fourth_order():
    """On a damped oscillator, halving the step divides the error at a fixed time by about 2^4."""
    a = np.array([[0.0, 1.0], [-400.0, -4.0]])
    w, v = np.linalg.eig(a)
    x0 = np.array([1.0, 0.0])
    exact = (v @ np.diag(np.exp(w * 0.1)) @ np.linalg.solve(v, x0)).real
    errors = []
    for steps in (20, 40, 80):
        x = x0.copy()
        for _ in range(steps):
            x = integrator.rk4(lambda y: a @ y, x, 0.1 / steps)
        errors.append(np.linalg.norm(x - exact))
    assert 14 < errors[0] / errors[1] < 18 and 14 < errors[1] / errors[2] < 18, errors


def test_a_pressure_at_its_bound_stays_there_and_the_rest_moves():
    """A chamber pushed past its upper bound by the valve stays at the bound exactly, the other at its
    lower one, with either way of holding them; the mass still moves; without stages the stages saw
    pressures past the bounds, so the two ways differ in the other states."""
    x0 = np.array([0.0, 0.0, 1.0, 0.0])
    out = {}
    for stages in (True, False):
        x = integrator.bounded_steps(lambda y: _rhs(y, 1.0), x0, 5, 1e-3, _PC, _LO, _HI, stages)
        assert x[2] == 1.0 and x[3] == 0.0
        assert x[0] > 0 and x[1] > 0
        out[stages] = x
    assert not np.array_equal(out[True], out[False])


@pytest.mark.parametrize("n", [1, 2, 3, 4, 8])
@pytest.mark.parametrize("frac", [0.0, 1e-9, 0.00256, 0.3, 0.5, 0.999999])
def test_a_period_is_shared_out_with_no_piece_longer_than_a_sub_step(n, frac):
    h = 1.0 / 512
    pieces = integrator.period_pieces(n, frac, h)
    assert len(pieces) == (2 if frac > 0 else 1)
    assert math.isclose(sum(steps * length for steps, length in pieces), h, rel_tol=1e-12)
    for steps, length in pieces:
        assert steps >= 1 and length <= h / n * (1 + 1e-12)
    if frac == 0:
        assert pieces == ((n, h / n),)
