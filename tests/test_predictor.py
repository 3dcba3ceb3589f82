"""The delay predictor (a scenario's ``predictor``): the state the controller is given is the plant's at
t_k + delay, the C loop and the Python reference agree with it on, and it is inert without a delay."""
import numpy as np
import pytest

from hydrogen.errors import ScenarioError
from hydrogen.simulation.scenarios import scenario
from hydrogen.diagram import LOOP_BLOCKS
from hydrogen.simulation.simulator import PythonStages, prepare_run, simulate


def _ideal(model, **kw):
    """paper-sim with an exact plant-model match for the predictor: no valve dynamics, no friction,
    exact sensors (what the controller's own model assumes)."""
    sc = scenario("paper-sim", model)
    return sc.with_overrides(valve_lag=0.0, valve_bandwidth_hz=0.0, friction=(0.0, 0.0, 1e-3), noise_l=0.0,
                             noise_p=0.0, quantization_l=0.0, kalman=False, **kw)


@pytest.mark.parametrize("periods", [1, 2])
def test_prediction_is_the_plant_state_where_the_command_lands(dyn, periods):
    """With the controller's model equal to the plant (backstepping knows θ, γ), the predicted state
    at t_k is the plant's own state `periods` periods later, to the forward kinematics' tolerance: the
    same RK4 steps over the same commands in flight."""
    model = dyn.model
    h = 1.0 / scenario("paper-sim", model).control_rate
    sc = _ideal(model, delay=periods * h, predictor=True, predictor_substeps=scenario("paper-sim", model).substeps,
                duration=0.2)
    p = prepare_run(dyn, sc, "backstepping", None, None, True, {})
    loop = PythonStages(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    predicted, checked = {}, 0
    for k in range(p.n):
        loop.k = k
        s = loop.signals(p.noise[k])
        for block in LOOP_BLOCKS:  # the diagram's blocks, the prediction taken as the controller's
            if block.name == "controller":
                if k in predicted:
                    scale = np.maximum(np.abs(loop.x), 1.0)
                    err = np.abs(predicted.pop(k) - loop.x)[: 2 * model.n + loop.n_p] / scale[: 2 * model.n + loop.n_p]
                    assert err.max() < 1e-8, (k, err.max())
                    checked += 1
                if k % 17 == 5:
                    predicted[k + periods] = loop.predicted(s)
            loop.stages[block.name](s)
        loop.after_period()
    assert checked >= 5


@pytest.mark.parametrize("controller", ["backstepping", "adaptive-robust", "adaptive-observer", "p"])
@pytest.mark.parametrize("delay_periods", [1.0, 1.5, 0.01])
def test_c_loop_predicts_as_the_python_reference(dyn, controller, delay_periods):
    """The C loop's predictor (estimates read from the controller's state, the commands in flight from
    its ring, a fraction of a period split off) gives the Python stages' numbers on the noisy rig."""
    h = 1.0 / scenario("z-1hz", dyn.model).control_rate
    kw = dict(predictor=True, delay=delay_periods * h, duration=0.25, theta0_factor=(0.8,) * dyn.model.n_theta)
    c = simulate(dyn, "z-1hz", controller, **kw)
    py = simulate(dyn, "z-1hz", controller, engine="python", **kw)
    assert np.max(np.abs(c.q - py.q)) < 1e-12
    assert np.max(np.abs(c.u - py.u)) < 1e-12 * max(1.0, np.max(np.abs(py.u)))
    assert np.max(np.abs(c.theta_hat - py.theta_hat)) < 1e-9 * np.max(np.abs(py.theta_hat))
    off = simulate(dyn, "z-1hz", controller, **{**kw, "predictor": False})
    assert np.max(np.abs(off.u - c.u)) > 1e-9  # the predictor changed the commands


def test_predictor_is_inert_without_a_delay(dyn):
    """No delay, nothing in flight: predictor on runs the same loop bit for bit."""
    a = simulate(dyn, "paper-sim", "adaptive-robust", duration=0.2, delay=0.0)
    b = simulate(dyn, "paper-sim", "adaptive-robust", duration=0.2, delay=0.0, predictor=True)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.u, b.u)


def test_predictor_recovers_the_undelayed_tracking(dyn):
    """On the ideal plant a two-period delay makes backstepping's error five times the undelayed one;
    with the predictor (its model is then exact) the error is the undelayed one."""
    model = dyn.model
    h = 1.0 / scenario("paper-sim", model).control_rate

    def err(**kw):
        r = simulate(dyn, _ideal(model, duration=3.0, metric_start=1.0, **kw), "backstepping")
        return max(v for v in r.metrics["max_error_pct"].values() if v is not None)

    none, late, predicted = err(), err(delay=2 * h), err(delay=2 * h, predictor=True)
    assert late > 3 * none
    assert abs(predicted - none) < 0.02 * none


@pytest.mark.parametrize("field, value", [("predictor", "yes"), ("predictor", 1), ("predictor_substeps", 0),
                                          ("predictor_substeps", 2.5), ("predictor_substeps", True)])
def test_bad_predictor_settings_are_refused(model, field, value):
    with pytest.raises(ScenarioError, match=field):
        scenario("z-1hz", model).with_overrides(**{field: value})
