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
from hydrogen.plant import supply

from controller_inputs import PAPER_LAWS, random_controller_inputs

KINDS = ["adaptive-robust", "adaptive-observer"]


def _args(fn, values):
    return [values[n] for n in fn.in_names]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("p0", [(1.0, 1.0), (0.37, 5.3)])
def test_lean_functions_equal_the_full_ones_at_composite_rates_zero(robot_dyn, kind, p0, rng):
    """At rates 0 (and P at P0 I, where it stays then; P0_gamma and P0_theta apart and not 1 too):
    the command, τ_d, τ̇_d, f_d and every non-composite rate of the lean controller, rates and
    step functions equal the full ones; the composite blocks' rates are 0 (their states hold)."""
    dyn, model = robot_dyn, robot_dyn.model
    ctrl = make_controller(dyn, kind, {"P0_gamma": p0[0], "P0_theta": p0[1], **PAPER_LAWS})
    assert ctrl.variant == LEAN
    comp = np.zeros(ctrl.xc.size, bool)
    for name, sl in ctrl.slices.items():
        comp[sl] = name in COMPOSITE_BLOCKS
    assert comp.any() and not comp.all()
    fns = {v: (dyn.functions[function_name(kind, v)], dyn.functions[rates_function_name(kind, v)],
               dyn.functions[step_function_name(kind, v)]) for v in (None, LEAN)}
    lo, hi = ctrl.bounds
    for _ in range(4):
        q, qdot, pc, ref, xc = random_controller_inputs(ctrl, model, rng)
        l = np.asarray(dyn.leg_lengths(q)).ravel()
        values = dict(ctrl.values, q=q, qdot=qdot, pc=pc, l=l, qd0=ref[0], qd1=ref[1], qd2=ref[2], qd3=ref[3],
                      xc=xc, adapt=np.array([1.0]), u_applied=rng.uniform(-1, 1, model.n_cylinders) * 1e-3,
                      h=np.array([1e-3]), xc_lo=lo, xc_hi=hi,
                      ps=np.array([supply.nominal(model) * rng.uniform(0.8, 1.0)]))  # read where the supply is a state
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
            assert np.abs(f_rate[~comp]).max() > 0  # and the estimates too: not a vacuous equality
        # the step: the non-composite state and the command equal; the composite states held
        x_full, x_lean = full["step"][1], lean["step"][1]
        np.testing.assert_array_equal(x_lean[~comp], x_full[~comp])
        np.testing.assert_array_equal(x_lean[comp], np.clip(xc, lo, hi)[comp])
        np.testing.assert_array_equal(lean["step"][0], full["step"][0])


def test_the_lean_variant_fixes_each_gain_block_at_its_own_p0(model):
    """The least-squares gain blocks are fixed at P0 I of their own family, upper triangles row by
    row, one per cylinder for γ (what the controller's reset writes)."""
    layout = controller("adaptive-robust").state_layout(model)
    spec = lean_variant(layout)
    start, i = {}, 0
    for name, size in layout:
        start[name] = (i, size)
        i += size
    fixed = {idx: v for k, idx, v in spec["fixed"] if k == "xc"}
    for block, p0, tri in (("gamma_gain", "P0_gamma", [1, 0, 1]), ("theta_gain", "P0_theta", None)):
        a, size = start[block]
        if tri is None:
            p = model.n_theta
            tri = [1 if r == c else 0 for r in range(p) for c in range(r, p)]
        want = [(p0, 0) if t else 0.0 for t in tri * (size // len(tri))]
        assert [fixed[a + j] for j in range(size)] == want
    assert {k for k, _, _ in spec["fixed"] if k != "xc"} == {"rate_ls_gamma", "rate_ls_theta"}
    assert lean_variant(controller("backstepping").state_layout(model)) is None


def test_lean_variant_is_smaller(robot_dyn):
    """Partial evaluation removed the composite terms: the lean functions have well under the full
    ones' instructions (read from the manifest of the generated code)."""
    counts = {f["name"]: f["instructions"] for f in robot_dyn.library.manifest["functions"]}
    for kind in KINDS:
        for name in (function_name, rates_function_name, step_function_name):
            assert counts[name(kind, LEAN)] < 0.85 * counts[name(kind)], name(kind)


def test_runtime_picks_the_lean_variant_exactly_when_the_composite_rates_are_zero(robot_dyn):
    for kind in KINDS:
        assert make_controller(robot_dyn, kind, PAPER_LAWS).fn.name == function_name(kind, LEAN)
        for gain in ("rate_ls_gamma", "rate_ls_theta"):
            c = make_controller(robot_dyn, kind, {gain: 5.0})
            assert c.variant is None
            assert (c.fn.name, c.rates_fn.name, c.step_fn.name) == (
                function_name(kind), rates_function_name(kind), step_function_name(kind))
    # controllers without composite blocks have no variant
    assert make_controller(robot_dyn, "backstepping").variant is None
    assert lean_variant(controller("backstepping").state_layout(robot_dyn.model)) is None


@pytest.mark.parametrize("kind,engine", [("adaptive-robust", "c"), ("adaptive-robust", "python"),
                                         ("adaptive-observer", "c")])
def test_a_run_with_the_lean_variant_equals_one_with_the_full_function(dyn, kind, engine, monkeypatch):
    """The whole closed loop (z-1hz, rig: semi-implicit update and delay) gives the same trajectory,
    command and estimates bit for bit."""
    lean = hydrogen.simulate("z-1hz", controller=kind, dyn=dyn, duration=0.5, engine=engine, gains=PAPER_LAWS)
    monkeypatch.setattr(control, "runs_lean", lambda gains: False)
    full = hydrogen.simulate("z-1hz", controller=kind, dyn=dyn, duration=0.5, engine=engine, gains=PAPER_LAWS)
    np.testing.assert_array_equal(lean.q, full.q)
    np.testing.assert_array_equal(lean.u, full.u)
    np.testing.assert_array_equal(lean.theta_hat, full.theta_hat)
    np.testing.assert_array_equal(lean.gamma1_hat, full.gamma1_hat)
    np.testing.assert_array_equal(lean.gamma2_hat, full.gamma2_hat)
    assert np.abs(lean.theta_hat[-1] - lean.theta_hat[0]).max() > 0  # the estimates moved


def test_the_manifest_names_the_inputs_a_lean_function_does_not_read(robot_dyn):
    """Code generation records the inputs no output depends on: for the lean variant, every
    composite gain; for the full function, none of them."""
    composite = {"rate_ls_gamma", "rate_ls_theta", "P0_gamma", "P0_theta", "lambda_f_gamma", "lambda_f_theta"}
    for kind in KINDS:
        lean = set(robot_dyn.functions[function_name(kind, LEAN)].unread_inputs)
        full = set(robot_dyn.functions[function_name(kind)].unread_inputs)
        assert composite <= lean and not composite & full
        assert "Lambda" not in lean and "xc" not in lean
