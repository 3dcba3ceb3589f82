"""hydrogen/estimators: the Kalman filter written once, its numpy update and its C statements."""
import numpy as np
import pytest

from hydrogen.estimators import kalman
from hydrogen.runtime.build import repo_generated_dir


def test_the_update_is_the_filters_predict_then_correct(rng):
    """[l, l̇] predicted with F = [1 h; 0 1], then corrected with the gain against the measurement:
    the matrix form of the filter, for each actuator."""
    h, gain = 1 / 512, kalman.kalman_gain(1 / 512, 2e-11, 50.0)
    kf = np.vstack([rng.uniform(0.5, 1.5, 4), rng.normal(size=4)])
    meas = kf[0] + 0.01 * rng.normal(size=4)
    F = np.array([[1.0, h], [0.0, 1.0]])
    pred = F @ kf
    expect = pred + np.outer(gain, meas - pred[0])
    np.testing.assert_allclose(kalman.update(kf, meas, gain, h), expect, rtol=1e-15, atol=1e-15)
    # a measurement on the prediction changes nothing but the prediction
    np.testing.assert_array_equal(kalman.update(kf, kf[0] + h * kf[1], gain, h), np.vstack([kf[0] + h * kf[1], kf[1]]))


def test_the_filter_starts_at_rest_at_the_lengths():
    np.testing.assert_array_equal(kalman.start([0.5, 0.7]), [[0.5, 0.7], [0.0, 0.0]])


@pytest.mark.parametrize("robot", ["ubc_stewart", "excavator_arm", "loader_crane"])
def test_the_loop_driver_runs_the_modules_c_statements(robot):
    """The committed loop driver of each robot holds C_UPDATE as the module writes it: one
    definition, rendered (generate --check keeps the committed drivers current)."""
    text = (repo_generated_dir() / robot / f"{robot}_loop.c").read_text()
    assert text.count(kalman.C_UPDATE) == 1


def test_the_gain_corrects_towards_the_measurement():
    """A steady-state gain filters: 0 < K_l < 1 and K_l̇ > 0 (a rate pulled towards the residual)."""
    K = kalman.kalman_gain(1 / 512, kalman.length_noise_variance(2e-6, 1e-5), 50.0)
    assert 0 < K[0] < 1 and K[1] > 0


def test_an_edit_of_the_filters_c_is_an_edit_of_the_loop_drivers(package_copy):
    """The filter's C reaches every loop driver: the drivers' hash covers its module, so an edit
    makes the committed and cached folders' drivers stale instead of running the old statements."""
    from hydrogen.codegen import generate as gen

    before = gen.drivers_hash()
    f = package_copy / "estimators" / "kalman.py"
    f.write_text(f.read_text().replace("st->kf[i] = lp + c->kf_gain[0] * r;", "st->kf[i] = lp + c->kf_gain[0] * r * 1.0;"))
    assert gen.drivers_hash() != before


def test_a_sweeps_designs_leave_out_a_scenario_that_cannot_be_designed_for():
    """A sweep's parent solves the designs of every entry it can; an entry whose scenario cannot be
    designed for (a setting of the wrong type) is left to its own run to report, not the sweep's."""
    import dataclasses

    import hydrogen
    from hydrogen.estimators import designs_for
    from hydrogen.simulation.scenarios import scenario

    model = hydrogen.load_model("excavator_arm")
    good = scenario("arm-dig", model)
    bad = dataclasses.replace(good, kalman_accel="x")
    got = designs_for([(bad, 1 / 512), (good, 1 / 512)])
    assert list(got) == ["kalman"] and len(got["kalman"]) == 1


def test_an_unknown_estimator_is_named_with_the_known_ones():
    from hydrogen.estimators import ESTIMATORS, estimator

    with pytest.raises(KeyError, match="no estimator 'nope'; the estimators are kalman"):
        estimator("nope")
    assert estimator("kalman") is kalman and "kalman" in ESTIMATORS


def test_an_explicit_ideal_sensor_beside_an_estimators_switch_is_refused():
    """By default the switch decides (a rig's kalman = true: the filter); "ideal" written beside a switch
    that is on asks for two things, and is refused naming both, never silently the switch's."""
    import hydrogen
    from hydrogen.errors import ScenarioError
    from hydrogen.estimators import AUTO, selected
    from hydrogen.simulation.scenarios import scenario

    rig = scenario("arm-dig", hydrogen.load_model("excavator_arm"))
    assert rig.estimator == AUTO and rig.kalman and selected(rig) == "kalman"
    with pytest.raises(ScenarioError, match=r'estimator = "ideal" and kalman = true .* the ideal rate sensor and an '
                                            r"estimator; .*write kalman = false"):
        rig.with_overrides(estimator="ideal")
    assert selected(rig.with_overrides(estimator="ideal", kalman=False)) is None
