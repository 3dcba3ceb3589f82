"""hydrogen/controllers/sliding_mode.py: sliding mode with a bounded disturbance estimate, added as one
module; built here for the shipped robots (a cache build: their descriptions do not list it)."""
import dataclasses

import numpy as np
import pytest

import hydrogen
from hydrogen.controllers import CONTROLLERS, controller, spec
from hydrogen.pressures import bounds as pressure_bounds
from hydrogen.simulation.control import gain_scale, make_controller

NAME = "sliding-mode"
#: (robot, scenario) run here: the paper's Stewart platform run, one scenario each of the arm and crane
CASES = [("ubc_stewart", "paper-sim"), ("excavator_arm", "arm-sim"), ("loader_crane", "crane-sim")]
#: Its worst max error over the coordinates (% of each amplitude) may exceed backstepping's (Theorem 1,
#: the same known parameters and force loop) by this factor at most. Measured: 0.17 % against 0.72 % on
#: paper-sim; it is at or below backstepping's on every case here.
VS_BACKSTEPPING = 1.5
SEEDS = (0, 1, 2)


def _worst(res) -> float:
    return max(v for v in res.metrics["max_error_pct"].values() if v is not None)


@pytest.fixture(scope="module", params=[name for name, _ in CASES])
def built(request, cache):
    model = hydrogen.load_model(request.param)
    model = dataclasses.replace(model, controllers=(*model.controllers, NAME))  # listed for this test only
    return hydrogen.build(model, cache=cache, controllers=[NAME, "backstepping"])


def _scenario(dyn) -> str:
    return dict(CASES)[dyn.model.name]


def test_it_is_registered_after_the_shipped_controllers_and_shipped_robots_do_not_list_it():
    ranked = [c for c in CONTROLLERS if spec(c).rank != spec(NAME).rank]  # the shipped, ranked ones
    assert CONTROLLERS.index(NAME) > max(CONTROLLERS.index(c) for c in ranked)  # (another new one may follow)
    assert spec(NAME).knows_true_parameters
    assert all(NAME not in hydrogen.load_model(name).controllers for name, _ in CASES)


def test_it_tracks_like_backstepping_stable_over_noise_seeds(built):
    scen = _scenario(built)
    ref = _worst(hydrogen.simulate(scen, "backstepping", dyn=built))
    for seed in SEEDS if built.model.name == "ubc_stewart" else SEEDS[:1]:
        res = hydrogen.simulate(scen, NAME, dyn=built, seed=seed)
        assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.u))
        assert _worst(res) <= VS_BACKSTEPPING * ref + 0.05, (seed, res.metrics["max_error_pct"], ref)


def test_the_disturbance_estimate_stays_inside_its_bound(built):
    res = hydrogen.simulate(_scenario(built), NAME, dyn=built)
    d_hat = res.states["d_hat"]
    d_max = controller(NAME).default_gains(built.model, gain_scale(built))["d_max"]
    assert d_hat.shape == (len(res.t), built.model.n) and np.all(d_hat[0] == 0.0)  # its declared start
    assert np.all(np.abs(d_hat) <= d_max) and np.any(np.abs(d_hat[-1]) > 0)  # moved, inside the bound


def test_a_tight_bound_holds_the_estimate_at_it(built):
    d_max = 1e-3 * np.ones(built.model.n)
    res = hydrogen.simulate(_scenario(built), NAME, dyn=built, gains={"d_max": d_max}, duration=0.3)
    assert np.all(np.abs(res.states["d_hat"]) <= d_max) and np.any(np.isclose(np.abs(res.states["d_hat"]), d_max))


def test_it_cancels_a_constant_disturbance_in_its_own_model(built):
    """d̂̇ = Γ_d s has the sign that cancels a constant d: with the robot lagging (s < 0), d̂ goes down."""
    ctrl = make_controller(built, NAME)
    model = built.model
    q0 = model.neutral_pose
    ctrl.reset(q0, np.zeros(model.n))
    ref = [q0 + 0.01, np.zeros(model.n), np.zeros(model.n), np.zeros(model.n)]  # q below q_d: s = Λ e < 0
    l = np.asarray(built.leg_lengths(q0), float).ravel()
    lo, hi = pressure_bounds(model)
    pc = 0.5 * (lo + hi)
    ctrl.update(1e-3, q0, np.zeros(model.n), pc, l, ref, True)
    assert np.all(ctrl.part("d_hat") < 0)


def test_its_c_loop_and_python_loop_agree(built):
    scen = _scenario(built)
    c = hydrogen.simulate(scen, NAME, dyn=built, duration=0.3)
    py = hydrogen.simulate(scen, NAME, dyn=built, duration=0.3, engine="python")
    np.testing.assert_allclose(c.q, py.q, atol=1e-10)
    np.testing.assert_allclose(c.u, py.u, atol=1e-10)
    np.testing.assert_allclose(c.states["d_hat"], py.states["d_hat"], rtol=1e-8, atol=1e-8)


def test_its_fmu_exposes_the_disturbance_estimate(built, tmp_path):
    pytest.importorskip("fmpy")
    from fmpy import read_model_description

    from hydrogen.fmu import export_fmu

    if built.model.name != "ubc_stewart":
        pytest.skip("one robot's FMU is enough")
    path = export_fmu(tmp_path / "sm.fmu", "controller", _scenario(built), NAME, dyn=built, duration=0.05)
    by = {v.name: v for v in read_model_description(str(path)).modelVariables}
    model = built.model
    for c, unit in zip(model.coordinate_names, model.coordinate_units):
        v = by[f"d_hat.{c}"]
        assert v.causality == "output" and v.unit == ("N" if unit == "m" else "N.m")
