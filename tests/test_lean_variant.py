"""The lean variant of the adaptive controllers (composite adaptation left out): the same numbers as
the full function whenever the composite rates are 0, fewer instructions, and picked by the
runtime exactly then."""
import numpy as np
import pytest

import hydrogen
import hydrogen.simulation.control as control
from hydrogen.controllers import LEAN, controller, function_name, rates_function_name, step_function_name
from hydrogen.controllers.common import COMPOSITE_BLOCKS, lean_variant
from hydrogen.simulation.control import make_controller

from test_composite import _random_inputs

KINDS = ["adaptive-robust", "adaptive-observer"]


def _args(fn, values):
    return [values[n] for n in fn.in_names]


@pytest.mark.parametrize("kind", KINDS)
def test_lean_functions_equal_the_full_ones_at_composite_rates_zero(robot_dyn, kind, rng):
    """At rates 0 (and P at P0 I, where it stays then): the command, τ_d, τ̇_d, f_d and every
    non-composite rate of the lean controller, rates and step functions equal the full ones; the
    composite blocks' rates are 0 (their states hold)."""
    dyn, model = robot_dyn, robot_dyn.model
    ctrl = make_controller(dyn, kind)
    assert ctrl.variant == LEAN
    layout = controller(kind).state_layout(model)
    comp = np.zeros(ctrl.xc.size, bool)
    for name, sl in ctrl.slices.items():
        comp[sl] = name in COMPOSITE_BLOCKS
    assert comp.any() and not comp.all()
    fns = {v: (dyn.functions[function_name(kind, v)], dyn.functions[rates_function_name(kind, v)],
               dyn.functions[step_function_name(kind, v)]) for v in (None, LEAN)}
    lo, hi = ctrl.bounds
    for _ in range(4):
        q, qdot, pc, ref, xc = _random_inputs(ctrl, model, rng)
        l = np.asarray(dyn.leg_lengths(q)).ravel()
        values = dict(ctrl.values, q=q, qdot=qdot, pc=pc, l=l, qd0=ref[0], qd1=ref[1], qd2=ref[2], qd3=ref[3],
                      xc=xc, adapt=np.array([1.0]), u_applied=rng.uniform(-1, 1, model.n_cylinders) * 1e-3,
                      h=np.array([1e-3]), xc_lo=lo, xc_hi=hi)
        full, lean = ({}, {})
        for v, out in ((None, full), (LEAN, lean)):
            c, r, s = fns[v]
            out["ctrl"] = [np.array(o, copy=True) for o in c(*_args(c, values))]
            out["rates"] = np.array(r(*_args(r, values)), copy=True)
            out["step"] = [np.array(o, copy=True) for o in s(*_args(s, values))]
        for a, b in zip(full["ctrl"][:1] + full["ctrl"][2:], lean["ctrl"][:1] + lean["ctrl"][2:]):
            np.testing.assert_array_equal(b, a)  # u, τ_d, τ̇_d, f_d
        for f_rate, l_rate in ((full["ctrl"][1], lean["ctrl"][1]), (full["rates"], lean["rates"])):
            np.testing.assert_array_equal(l_rate[~comp], f_rate[~comp])
            np.testing.assert_array_equal(l_rate[comp], 0.0)
            assert np.abs(f_rate[comp]).max() > 0  # the full function's filters do move
        # the step: the non-composite state and the command equal; the composite states held
        x_full, x_lean = full["step"][1], lean["step"][1]
        np.testing.assert_array_equal(x_lean[~comp], x_full[~comp])
        np.testing.assert_array_equal(x_lean[comp], np.clip(xc, lo, hi)[comp])
    assert lean_variant(layout) is not None


def test_lean_variant_is_smaller(robot_dyn):
    """Partial evaluation removed the composite terms: the lean functions have well under the full
    ones' instructions (read from the manifest of the generated code)."""
    counts = {f["name"]: f["instructions"] for f in robot_dyn.library.manifest["functions"]}
    for kind in KINDS:
        for name in (function_name, rates_function_name, step_function_name):
            assert counts[name(kind, LEAN)] < 0.85 * counts[name(kind)], name(kind)


def test_runtime_picks_the_lean_variant_exactly_when_the_composite_rates_are_zero(robot_dyn):
    for kind in KINDS:
        assert make_controller(robot_dyn, kind).fn.name == function_name(kind, LEAN)
        for gain in ("rate_ls_gamma", "rate_ls_theta"):
            c = make_controller(robot_dyn, kind, {gain: 5.0})
            assert c.variant is None
            assert (c.fn.name, c.rates_fn.name, c.step_fn.name) == (
                function_name(kind), rates_function_name(kind), step_function_name(kind))
    # controllers without composite blocks have no variant
    assert make_controller(robot_dyn, "backstepping").variant is None
    assert lean_variant(controller("backstepping").state_layout(robot_dyn.model)) is None


@pytest.mark.parametrize("engine", ["c", "python"])
def test_a_run_with_the_lean_variant_equals_one_with_the_full_function(dyn, engine, monkeypatch):
    """The whole closed loop (z-1hz, rig: semi-implicit update and delay) gives the same trajectory,
    command and estimates bit for bit."""
    lean = hydrogen.simulate("z-1hz", controller="adaptive-robust", dyn=dyn, duration=0.5, engine=engine)
    monkeypatch.setattr(control, "runs_lean", lambda gains: False)
    full = hydrogen.simulate("z-1hz", controller="adaptive-robust", dyn=dyn, duration=0.5, engine=engine)
    np.testing.assert_array_equal(lean.q, full.q)
    np.testing.assert_array_equal(lean.u, full.u)
    np.testing.assert_array_equal(lean.theta_hat, full.theta_hat)
    np.testing.assert_array_equal(lean.gamma1_hat, full.gamma1_hat)
    np.testing.assert_array_equal(lean.gamma2_hat, full.gamma2_hat)
