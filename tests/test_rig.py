"""The experiment-like rig: computation delay, second-order servo-valve, quantised
cylinder-length encoders, the Kalman filter from the Riccati equation, the gain searches and margins."""
from __future__ import annotations

import numpy as np
import pytest

import hydrogen
from hydrogen.simulation.scenarios import Scenario, scenario
from hydrogen.plant.integrator import rk4 as _rk4
from hydrogen.simulation.simulator import equilibrium_pressures, kalman_gain, length_noise_variance, simulate

from conftest import plant_inputs

MODELS = hydrogen.models()


@pytest.fixture(scope="module", params=MODELS)
def robot(request):
    """(dyn, its first rig scenario)"""
    from hydrogen.simulation.tuning import rig_scenarios
    model = hydrogen.load_model(request.param)
    return hydrogen.build(model), next(iter(rig_scenarios(model)))


@pytest.mark.parametrize("delay", [0, 1, 3])
def test_delay_applies_each_command_delay_periods_later(robot, delay):
    dyn, name = robot
    h = 1.0 / scenario(name, dyn.model).control_rate
    res = simulate(dyn, name, "p", duration=0.3, delay=delay * h)
    assert res.scenario.delay_split() == (delay, 0.0)
    np.testing.assert_array_equal(res.u_applied[:delay], 0.0)  # the valves start centred
    np.testing.assert_array_equal(res.u_applied[delay:], res.u[:len(res.u) - delay])


def test_a_step_in_the_command_reaches_the_valve_one_period_later(dyn):
    """P on a reference step: the command jumps in the period of the step, the valve one period later."""
    res = simulate(dyn, "z-step", "p", duration=1.2, noise_l=0.0, noise_p=0.0, quantization_l=0.0)
    assert res.scenario.delay_split() == (1, 0.0)
    k = int(np.argmax(res.t >= res.scenario.reference.t_step))
    jump = np.abs(np.diff(res.u, axis=0)).max(axis=1)
    jump_applied = np.abs(np.diff(res.u_applied, axis=0)).max(axis=1)
    assert jump[k - 1] > 10 * jump[: k - 1].max()
    assert jump_applied[k] > 10 * jump_applied[: k].max()


@pytest.mark.parametrize("zeta", [0.4, 0.7])
def test_second_order_valve_step_response_is_the_analytic_one(dyn, model, zeta):
    f_n = 80.0
    w = 2 * np.pi * f_n
    m = model.n_cylinders
    q0 = model.neutral_pose
    x0 = np.concatenate([q0, np.zeros(model.n), equilibrium_pressures(dyn, q0, model.theta), np.zeros(2 * m)])
    u = np.full(m, 1e-5)
    fric, valve = plant_inputs(model, valve=(0.0, w, zeta))
    rhs = lambda x: dyn.functions["plant_rhs"](x, u, model.theta, *model.gamma, fric, valve)  # noqa: E731
    h, x, t, spool = 2e-5, x0.copy(), [], []
    for k in range(1, 751):  # 15 ms
        x = _rk4(rhs, x, h)
        t.append(k * h)
        spool.append(x[2 * model.n + m: 2 * model.n + 2 * m].copy())
    t, spool = np.array(t), np.array(spool)
    wd = w * np.sqrt(1 - zeta ** 2)
    exact = 1 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    np.testing.assert_allclose(spool / u, np.tile(exact[:, None], (1, m)), atol=1e-7)
    # the 90-degree point: the spool rate at its largest near t = pi/(2 wd)-ish; the natural frequency
    # is where a sine command lags 90 deg: check the overshoot instead (second order, damping zeta)
    assert spool[:, 0].max() / u[0] == pytest.approx(1 + np.exp(-zeta * np.pi / np.sqrt(1 - zeta ** 2)), rel=1e-4)


def _doubling_dare(A, B, Q, R, tol=1e-13, max_iter=100):
    """The toolkit's former hand-written solver (structure-preserving doubling), kept here as an
    independent reference for scipy's: X = AᵀXA − AᵀXB (R + BᵀXB)⁻¹ BᵀXA + Q."""
    G = B @ np.linalg.solve(R, B.T)
    H, I = Q.copy(), np.eye(A.shape[0])
    for _ in range(max_iter):
        W = np.linalg.inv(I + G @ H)
        A_next, G_next, H_next = A @ W @ A, G + A @ W @ G @ A.T, H + A.T @ H @ W @ A
        done = np.abs(H_next - H).max() <= tol * max(np.abs(H_next).max(), 1e-300)
        A, G, H = A_next, G_next, H_next
        if done:
            break
    return 0.5 * (H + H.T)


def _kalman_settings():
    """(h, r, accel) of every shipped scenario with a Kalman filter, and a few off the shipped range."""
    from hydrogen.simulation.scenarios import scenario_names
    out = [(1 / 512, length_noise_variance(2e-6, 1e-5), 0.02), (1e-3, 1e-10, 1e-3),
           (1 / 512, length_noise_variance(5e-6, 1e-5), 1e-3)]
    for name in MODELS:
        model = hydrogen.load_model(name)
        for sc_name in scenario_names(model):
            sc = scenario(sc_name, model)
            if sc.kalman:
                out.append((1 / sc.control_rate, length_noise_variance(sc.noise_l, sc.quantization_l),
                            sc.kalman_accel))
    return out


def test_kalman_gain_is_the_dare_solution():
    settings = _kalman_settings()
    assert len(settings) > 3  # the shipped models do have rig scenarios with a filter
    for h, r, q in settings:
        F = np.array([[1.0, h], [0.0, 1.0]])
        Q = q * np.array([[h ** 3 / 3, h ** 2 / 2], [h ** 2 / 2, h]])
        H = np.array([[1.0, 0.0]])
        R = np.array([[r]])
        K = kalman_gain(h, r, q)
        # the same gain as the former doubling loop ...
        P_ref = _doubling_dare(F.T, H.T, Q, R)
        K_ref = (P_ref @ H.T / (H @ P_ref @ H.T + r)).ravel()
        np.testing.assert_allclose(K, K_ref, rtol=1e-10, atol=0)
        # ... whose covariance is a fixed point of the filter's Riccati recursion (predicted form):
        # an independent check that the reference is the DARE's solution, not just agreement
        P = P_ref
        resid = F @ P @ F.T - F @ P @ H.T @ H @ P @ F.T / (P[0, 0] + r) + Q - P
        assert np.abs(resid).max() <= 1e-9 * np.abs(P).max()
        assert 0 < K[0] < 1 and K[1] > 0
    assert length_noise_variance(0.0, 1e-5) == pytest.approx(1e-10 / 12)  # Δ²/12


def test_rig_kalman_filter_no_longer_differentiates_the_measurement(model):
    sc = scenario("z-1hz", model)
    K = kalman_gain(1 / sc.control_rate, length_noise_variance(sc.noise_l, sc.quantization_l), sc.kalman_accel)
    assert K[0] < 0.95


def test_measured_lengths_are_on_the_encoder_grid(robot):
    dyn, name = robot
    quiet = scenario(name, dyn.model).noise_free()  # every actuator's own length noise off too
    res = simulate(dyn, name, "p", duration=0.2, noise_l=0.0, actuators=quiet["actuators"])
    delta = res.scenario.quantization_l
    assert delta > 0
    cells = res.leg_lengths_measured / delta
    np.testing.assert_allclose(cells, np.round(cells), atol=1e-6)
    assert np.abs(res.leg_lengths_measured - res.leg_lengths).max() <= delta / 2 * (1 + 1e-9)


#: The C loop and the Python loop run the same noise samples and differ only in rounding (~1e-16).
#: Where nothing amplifies that, they agree over the whole run (P and backstepping on the rig, every
#: controller on the ideal scenarios: tests/test_simulation.py). On the rig the adaptive loops are
#: chaotic: a rounding difference grows by about a decade every 0.1-0.3 s once the adaptation is on,
#: and once two runs differ by enough for a measured length to fall in the next 10 um encoder cell
#: they part for good. Measured (C vs Python, first difference in q above 1e-8): 2.1 s on the
#: platform's z-1hz with adaptive-robust, 1.3 s with adaptive-observer, 1.6 s on z-2hz, 2.4 s on
#: psi-1hz. On the excavator arm (four-way cylinders) the differences are still growing when arm-dig
#: ends: with adaptive-robust 7e-8 (C vs Python) and 9e-6 (C vs C nudged) at most in q.
#: Two C runs whose noise differs by one part in 1e15 part the same way: the loop's sensitivity, not
#: a difference of the engines; one seed's result is one draw of a distribution (hydrogen.simulation.seeds).
AGREE_S = 1.0


def _c_run_with_noise_scaled(dyn, name, kind, factor):
    """q of the C loop on ``name`` with the noise table multiplied by ``factor``."""
    from hydrogen.simulation.simulator import make_runner, new_logs, prepare_run
    p = prepare_run(dyn, name, kind, None, None, True, {})
    log = new_logs(dyn.model, p.n, p.ctrl.xc.size)
    runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    logs = {k: log[k] for k in ("q", "q_d", "l", "f", "pc", "u", "u_applied", "l_meas")}
    if p.ctrl.xc.size:
        logs["xc"] = log["xc"]
    assert runner.run(p.n, p.noise * factor, logs) == 0
    return log["q"]


def test_c_loop_matches_python_loop_with_the_whole_rig(robot):
    """Nothing adapts: the two loops agree over the whole rig run."""
    dyn, name = robot
    sc = scenario(name, dyn.model)
    assert sc.delay_split() == (1, 0.0) and sc.valve_bandwidth_hz > 0 and sc.quantization_l > 0 and sc.kalman
    for kind in ("p", "backstepping"):
        c = simulate(dyn, name, kind)
        py = simulate(dyn, name, kind, engine="python")
        assert c.t[-1] >= sc.duration - 2 / sc.control_rate
        np.testing.assert_allclose(c.q, py.q, atol=1e-10)
        np.testing.assert_allclose(c.u, py.u, atol=1e-10)
        np.testing.assert_allclose(c.u_applied, py.u_applied, atol=1e-10)
        np.testing.assert_array_equal(c.leg_lengths_measured, py.leg_lengths_measured)


def test_pressures_held_at_every_stage_run_alike_in_c_and_python():
    """pressure_bounds = "stage" (the bounds held at every RK4 stage too) on a run where a chamber
    cavitates (its pressure rests on 0: the crane's flow-limited cycle under P): the C and the Python
    loop agree, and the run differs from one that clips after each step only."""
    dyn = hydrogen.build(hydrogen.load_model("loader_crane"), controllers=("p",))
    c = simulate(dyn, "crane-flow", "p", duration=2.5, pressure_bounds="stage")
    py = simulate(dyn, "crane-flow", "p", duration=2.5, pressure_bounds="stage", engine="python")
    assert np.min(c.pressures) == 0.0  # a chamber on its bound
    np.testing.assert_allclose(c.q, py.q, atol=1e-10)
    np.testing.assert_allclose(c.pressures, py.pressures, rtol=1e-9, atol=1e-3)
    step = simulate(dyn, "crane-flow", "p", duration=2.5, pressure_bounds="step")
    assert np.abs(step.q - c.q).max() > 1e-9


def test_an_adaptive_run_that_diverges_says_so_with_its_cause():
    """The arm's flow-limited cycle with the predictor at 32 steps diverges on seed 1 (the robust
    observer's velocity estimate); the run's last logged row holds the non-finite state it stopped at.
    It raises the SimulationError naming the cause with the partial result, not an error of a metric
    computed over that row (the excitation of the estimates is not reported for a diverged run)."""
    dyn = hydrogen.build(hydrogen.load_model("excavator_arm"), controllers=("adaptive-robust",))
    with pytest.raises(hydrogen.SimulationError, match="velocity estimate .* diverged at t = ") as err:
        simulate(dyn, "arm-flow.predictor", "adaptive-robust", predictor_substeps=32, seed=1)
    res = err.value.result
    assert 0 < len(res.t) < 5120 and "excitation" not in res.metrics


@pytest.mark.parametrize("kind", ["adaptive-robust", "adaptive-observer"])
def test_c_and_python_loops_on_the_rig_agree_until_chaos_parts_them(robot, kind):
    dyn, name = robot
    c = simulate(dyn, name, kind)
    py = simulate(dyn, name, kind, engine="python")
    early = c.t < AGREE_S
    np.testing.assert_allclose(c.q[early], py.q[early], atol=1e-8)
    np.testing.assert_allclose(c.u[early], py.u[early], atol=1e-8)
    np.testing.assert_array_equal(c.leg_lengths_measured[early], py.leg_lengths_measured[early])
    nudged = _c_run_with_noise_scaled(dyn, name, kind, 1 + 1e-15)
    np.testing.assert_allclose(nudged[early], c.q[early], atol=1e-8)
    d_py, d_nudged = np.abs(c.q - py.q).max(), np.abs(c.q - nudged).max()
    if d_nudged < 1e-8:  # this loop does not amplify rounding here: the engines agree to the end
        assert d_py < 1e-8
    elif d_py > 1e-8:  # it does: C vs Python part no further than C vs C with the noise changed in its
        # 15th digit (they may part less: within a run the differences are still growing, from different seeds)
        assert d_py < 100 * d_nudged, (d_py, d_nudged)
    # else: the nudge moved a measured length into the next encoder cell (a discrete jump) while the
    # two engines' roundings did not: they agree to the end (the crane's adaptive-robust run: C vs
    # Python 2e-10 rad, C vs nudged C 7e-6 rad)


def test_result_holds_the_scenario_actually_run(dyn):
    res = simulate(dyn, "z-1hz", "p", duration=0.1, delay=2 / 512, valve_bandwidth_hz=60.0)
    assert isinstance(res.scenario, Scenario)
    assert res.scenario.delay == 2 / 512 and res.scenario.valve_bandwidth_hz == 60.0
    assert res.scenario.duration == 0.1
    assert res.scenario_name == "z-1hz" == res.metrics["scenario"]


@pytest.mark.parametrize("bad", [dict(delay=-1e-3), dict(delay=99 / 512), dict(delay=8.5 / 512), dict(delay="1"),
                                 dict(delay=float("nan")),
                                 dict(valve_lag=0.002, valve_bandwidth_hz=80.0), dict(valve_damping=0.0),
                                 dict(quantization_l=-1e-5), dict(valve_bandwidth_hz=5000.0),
                                 dict(pressure_bounds="stages"), dict(pressure_bounds=1)])
def test_bad_rig_settings_are_named(dyn, bad):
    with pytest.raises(hydrogen.ScenarioError, match=next(iter(bad))):
        simulate(dyn, "z-1hz", "p", duration=0.1, **bad)


def test_a_bad_pressure_bounds_in_a_description_is_named_on_the_command_line(tmp_path, capsys):
    """A description whose [rig] asks for a way of holding the pressures that does not exist: the run
    stops before its loop with one line naming the scenario, the field and the value; exit 2."""
    from hydrogen.cli import main as cli
    from hydrogen.model import model_path

    text = model_path("ubc_stewart").read_text(encoding="utf-8")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("[rig]\n", '[rig]\npressure_bounds = "stages"\n', 1), encoding="utf-8")
    assert cli(["simulate", "--model", str(bad), "--scenario", "z-1hz", "--controller", "p", "--duration", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "[scenarios.z-1hz] over [rig]: " in err and "pressure_bounds must be 'step' or 'stage', got 'stages'" in err
    assert "Traceback" not in err


def test_rig_scenarios_and_moving_coordinates():
    from hydrogen.simulation.tuning import rig_scenarios
    assert rig_scenarios("ubc_stewart") == {"z-1hz": ("z",), "z-2hz": ("z",), "psi-1hz": ("psi",)}
    assert rig_scenarios("excavator_arm") == {"arm-dig": ("boom", "stick", "bucket")}


#: Robots on whose rig no P gain of the grid keeps a margin of 2 (the search then stores its least bad
#: point): the crane's one K acts on the slew vane's angle error as on the cylinders' length errors,
#: and above K = 0.0059 the slew valve saturates in more than 1 % of the periods; on the arm the
#: judge sees ringing above K = 0.0071 on every seed (docs/loader_crane.md, docs/excavator_arm.md).
P_WITHOUT_MARGIN = ("loader_crane", "excavator_arm")


@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_p_default_gain_is_the_documented_search_result(name):
    from hydrogen.simulation.tuning import default_grid, tune
    stored = hydrogen.load_model(name).gains["p"]["Kleg"]
    # The documented grid up to 4x the stored gain: the lower points set the stability judge's
    # reference and hold the best, the edge lies within twice the best; the points above the edge
    # only ring, and simulating them took half the test's time.
    grid = default_grid("p")
    res = tune("p", grid[grid <= 4 * stored * (1 + 1e-9)], model=name, max_workers=2)
    assert res["best"] == pytest.approx(stored, rel=2e-3)
    assert res["largest_stable"] is not None
    if name in P_WITHOUT_MARGIN:  # the least bad point: the largest stable gain itself, margin < 2
        assert res["largest_stable"] < 2 * res["best"]
    else:
        assert res["largest_stable"] >= 2 * res["best"] * (1 - 1e-9)
    assert [r for r in res["table"] if r["gain"] > res["largest_stable"] and not r["stable"]]  # the edge was found


@pytest.mark.slow
def test_default_p_gain_has_a_margin_of_at_least_2():
    from hydrogen.simulation.tuning import margins
    rows = margins(["p"], model="ubc_stewart", scenarios=["z-1hz"], max_workers=2)["rows"]
    assert rows[0]["margin"] >= 2.0


@pytest.mark.parametrize("periods", [0.4, 1.5])
def test_a_fractional_delay_switches_the_command_inside_the_period(robot, periods):
    """A delay of a fraction of a period (low-latency: the command applied once computed):
    the C and the Python loops agree, the valves' commands are the whole-period ones, and the motion
    lies between that of the two whole-period delays around it."""
    dyn, name = robot
    sc = scenario(name, dyn.model)
    h, kw = 1.0 / sc.control_rate, dict(duration=0.4, noise_l=0.0, noise_p=0.0, noise_q=0.0, quantization_l=0.0)
    frac = simulate(dyn, name, "p", delay=periods * h, **kw)
    assert frac.scenario.delay_split() == (int(periods), pytest.approx(periods % 1))
    py = simulate(dyn, name, "p", delay=periods * h, engine="python", **kw)
    np.testing.assert_allclose(frac.q, py.q, atol=1e-10)
    d = int(periods)
    np.testing.assert_array_equal(frac.u_applied[d:], frac.u[:len(frac.u) - d])  # at each period's end
    lo, hi = (simulate(dyn, name, "p", delay=k * h, **kw) for k in (d, d + 1))
    to_lo, to_hi, span = (np.abs(a.q - b.q).max() for a, b in ((frac, lo), (frac, hi), (lo, hi)))
    assert 0 < to_lo < span and 0 < to_hi < span, (to_lo, to_hi, span)


def test_delay_periods_is_refused_with_its_new_name(dyn, tmp_path):
    text = hydrogen.model.model_path("ubc_stewart").read_text().replace(
        "delay = 0.001953125", "delay_periods = 1")
    path = tmp_path / "old.toml"
    path.write_text(text)
    with pytest.raises(hydrogen.ModelError, match=r"\[rig\].*'delay_periods' is now delay"):
        hydrogen.load_model(path)
    with pytest.raises(hydrogen.ScenarioError, match="delay_periods is now delay"):
        simulate(dyn, "z-1hz", "p", duration=0.01, delay_periods=1)


# --- the rig's variants ([variants.<name>]: the same scenarios at another timing) ----------------------

def _with_variant(tmp_path, table: str):
    """The Stewart platform's description with one more [variants.*] table."""
    from hydrogen.model import default_model_path
    path = tmp_path / "variant.toml"
    path.write_text(default_model_path().read_text() + "\n" + table + "\n")
    return path


def test_a_variant_sets_its_fields_over_every_scenario_and_its_gains_over_the_scenarios(tmp_path):
    import dataclasses
    path = _with_variant(tmp_path, '[variants.slow]\nlabel = "a slow target"\ndelay = 0.00390625\n'
                                   'gains.backstepping = { Lambda = 12.0 }\n'
                                   'gains.adaptive-observer = { Ktau = 99.0 }')
    model = hydrogen.load_model(path)
    for name in ("z-1hz", "z-step", "paper-sim"):
        base, var = scenario(name, model), scenario(f"{name}.slow", model)
        assert var.delay == 0.00390625 and var.name == f"{name}.slow"
        assert var.label == f"{base.label}, a slow target"
        same = [f.name for f in dataclasses.fields(Scenario) if f.name not in ("name", "label", "delay", "gains")]
        assert all(np.array_equal(np.asarray(getattr(base, f), dtype=object), np.asarray(getattr(var, f), dtype=object))
                   or getattr(base, f) == getattr(var, f) for f in same)
    assert scenario("z-1hz.slow", model).delay_split() == (2, 0.0)  # two periods at 512 Hz
    # paper-sim pins its own backstepping gains: the variant's Lambda replaces that one, the rest stays
    pinned, var = scenario("paper-sim", model).gains, scenario("paper-sim.slow", model).gains
    assert var["backstepping"] == {**pinned["backstepping"], "Lambda": 12.0}
    assert var["adaptive-observer"] == {**pinned["adaptive-observer"], "Ktau": 99.0}
    assert scenario("z-1hz.slow", model).gains == {"backstepping": {"Lambda": 12.0},
                                                    "adaptive-observer": {"Ktau": 99.0}}


def test_the_shipped_low_latency_runs_and_differs_from_the_full_period(dyn):
    from hydrogen.simulation.tuning import rig_scenarios
    assert list(rig_scenarios(dyn.model, "low-latency")) == ["z-1hz.low-latency", "z-2hz.low-latency",
                                                             "psi-1hz.low-latency"]
    full = simulate(dyn, "z-1hz", "backstepping", duration=0.3)
    fast = simulate(dyn, "z-1hz.low-latency", "backstepping", duration=0.3)
    assert fast.scenario.delay == 5e-6 and fast.scenario.delay_split() == (0, pytest.approx(5e-6 * 512))
    assert fast.scenario_name == "z-1hz.low-latency"
    # near-zero latency applies each command within the period it was computed in, not one period later
    np.testing.assert_array_equal(fast.u_applied, fast.u)
    assert not np.array_equal(full.u_applied[1:], full.u[1:]) and np.array_equal(full.u_applied[1:], full.u[:-1])


def _notes(call):
    """``call()``'s result and the DescriptionNotes it showed (as Python shows them: each once)."""
    import warnings

    from hydrogen.errors import DescriptionNote
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        out = call()
    return out, [str(w.message) for w in caught if issubclass(w.category, DescriptionNote)]


def test_a_former_variant_name_runs_the_same_variant_and_names_the_new_one_once(dyn, capsys):
    from hydrogen import cli
    from hydrogen.simulation.tuning import rig_scenarios
    new = simulate(dyn, "z-1hz.low-latency", "adaptive-robust", duration=0.3)
    old, notes = _notes(lambda: simulate(dyn, "z-1hz.paper-timing", "adaptive-robust", duration=0.3))
    assert old.scenario == new.scenario and old.scenario_name == "z-1hz.low-latency"
    for k in ("q", "u", "u_applied"):
        np.testing.assert_array_equal(getattr(old, k), getattr(new, k))
    assert len(notes) == 1 and "'paper-timing' is now 'low-latency'" in notes[0], notes
    assert _notes(lambda: rig_scenarios(dyn.model, "paper-timing"))[0] == rig_scenarios(dyn.model, "low-latency")
    # the command line: one note, and the run under the new name
    assert cli.main(["simulate", "--scenario", "z-1hz.paper-timing", "--controller", "p", "--duration", "0.1"]) == 0
    out, err = capsys.readouterr()
    assert "scenario z-1hz.low-latency" in out
    assert [line for line in err.splitlines() if "low-latency" in line] == [
        line for line in err.splitlines() if line.startswith("hydrogen: note: ") and "is now 'low-latency'" in line]
    assert sum("is now 'low-latency'" in line for line in err.splitlines()) == 1, err


def test_a_former_variant_name_over_seeds_is_noted_once_not_by_each_worker(dyn, capfd):
    (runs, notes) = _notes(lambda: simulate(dyn, "z-1hz.paper-timing", "p", duration=0.1, seeds=2, max_workers=2))
    assert not runs.failures and [r.scenario_name for r in runs.results] == ["z-1hz.low-latency"] * 2
    assert len(notes) == 1 and "is now 'low-latency'" in notes[0], notes
    assert "is now" not in capfd.readouterr().err  # the workers got the current name


@pytest.mark.parametrize("table, where", [
    ('[variants.slow]\ndelay_periods = 2', "[variants.slow]"),
    ('[variants.slow]\nbogus = 1', "[variants.slow]"),
    ('[variants.slow]\ngains.nosuch = { Lambda = 1.0 }', "[variants.slow] gains"),
    ('[variants."a.b"]\ndelay = 0.0', "[variants.a.b]"),
    ('[variants.slow]\nformerly = "fast"', "[variants.slow] formerly"),
    ('[variants.slow]\nformerly = ["predictor"]', "[variants.slow] formerly.*'predictor' is already"),
    ('[variants.slow]\nformerly = ["paper-timing"]', "[variants.slow] formerly.*already .variants.low-latency. formerly"),
    ('[variants.slow]\nformerly = ["a.b"]', "[variants.slow] formerly"),
])
def test_a_bad_variant_is_named_at_load(tmp_path, table, where):
    with pytest.raises(hydrogen.ModelError, match=where.replace("[", r"\[").replace("]", r"\]")):
        hydrogen.load_model(_with_variant(tmp_path, table))


def test_an_unknown_variant_is_one_clear_error(capsys):
    from hydrogen import cli
    from hydrogen.simulation.tuning import margins
    with pytest.raises(hydrogen.ScenarioError, match="unknown variant 'bogus'.*variants: low-latency, predictor"):
        margins(variant="bogus")
    with pytest.raises(hydrogen.ScenarioError, match=r"z-1hz.bogus.*variants: low-latency, predictor"):
        hydrogen.simulate("z-1hz.bogus", "p", duration=0.1)
    for argv in (["margins", "--variant", "bogus"], ["tune-p", "--variant", "bogus"],
                 ["simulate", "--scenario", "z-1hz.bogus"]):
        assert cli.main([*argv, "--quiet"] if argv[0] != "simulate" else argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "bogus" in err[0], err


def test_kalman_gain_is_solved_once_per_setting(monkeypatch):
    """A sweep's runs of one scenario share the filter's gain: the Riccati equation is solved once
    per (period, noise, acceleration) in a process, and each caller gets its own array."""
    import scipy.linalg

    from hydrogen.estimators import kalman

    calls = []
    real = scipy.linalg.solve_discrete_are
    monkeypatch.setattr(scipy.linalg, "solve_discrete_are", lambda *a: (calls.append(a), real(*a))[1])
    kalman._kalman_gain.cache_clear()
    a = kalman_gain(1 / 512, 2e-11, 1e-3)
    a[0] = -1.0  # the caller's own copy
    b = kalman_gain(1 / 512, 2e-11, 1e-3)
    assert len(calls) == 1 and b[0] != -1.0
    kalman_gain(1 / 512, 3e-11, 1e-3)
    assert len(calls) == 2


@pytest.mark.parametrize("name", hydrogen.models())
def test_a_variants_searched_gains_name_every_gain_the_rig_names(name):
    """A variant's gains for a controller are merged over the robot's: where they left out a gain the
    robot's table names (an adaptation rate), a new search of the robot's gains would silently change
    the variant's controller, which was searched with the old value. Each names them all."""
    m = hydrogen.load_model(name)
    for variant, table in m.variants.items():
        for c, gains in (table.get("gains") or {}).items():
            missing = sorted(set(m.gains.get(c, {})) - set(gains))
            assert not missing, f"{name} [variants.{variant}] gains.{c} inherits {missing} from [gains.{c}]"


def test_a_main_gain_the_secondary_search_also_sets_is_refused(monkeypatch):
    """A controller whose main gain is K_p: the secondary search's Kd_scale sets K_p at every point, so
    every grid column would be the same run under the main gain's name; refused before any run."""
    from hydrogen.simulation import tuning

    monkeypatch.setattr(tuning, "main_gain", lambda controller: "Kp")
    built = []
    monkeypatch.setattr(tuning, "_variant_gains", lambda *a: built.append(1) or [])
    with pytest.raises(hydrogen.ScenarioError, match=r"main gain 'Kp' is also set by the secondary search: "
                                                     r"Kd_scale sets Kd, Kp; .* without Kd_scale"):
        tuning.tune("backstepping", [1.0, 2.0], seeds=[0], progress=False)
    assert not built  # refused before the variants' libraries are compiled
    with pytest.raises(hydrogen.ScenarioError, match=r"Ktau sets Ktau"):
        monkeypatch.setattr(tuning, "main_gain", lambda controller: "Ktau")
        tuning.tune("backstepping", [1.0, 2.0], seeds=[0], progress=False, secondary={"Ktau": [1.0]})
