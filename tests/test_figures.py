"""Figures and table from synthetic results (no simulation runs)."""
import numpy as np
import pytest

import hydrogen
from hydrogen import figures
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.simulator import SimulationResult

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _result(controller, scenario="z-1hz", n=200, err_scale=1e-3, step=False, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n)
    bias = np.array([0.0, 0.0, -2.34, 0.0, 0.0, 0.0])
    amp = np.array([0.0, 0.0, 0.05, 0.09, 0.0, 0.0])
    q_d = np.tile(bias, (n, 1))
    if step:
        q_d[t >= 1.0, 2] += 0.02
        amp = np.array([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
    else:
        q_d[:, 2] += 0.05 * np.sin(2 * np.pi * t)
        q_d[:, 3] += 0.09 * np.sin(2 * np.pi * t)
    q = q_d + err_scale * rng.standard_normal((n, 6))
    theta_true = np.array([500.0, 80.0, 80.0, 120.0])
    gamma_true = np.array([[7e8] * 6, [7e8 * 1e-8] * 6])
    decay = np.exp(-t)[:, None]
    theta_hat = theta_true * (1.0 + 0.2 * decay * np.array([1.0, -0.3, 0.3, -0.2]))
    gamma1_hat = gamma_true[0] * (1.0 - 0.3 * decay)
    gamma2_hat = gamma_true[1] * (1.0 + 0.3 * decay)
    res = SimulationResult(
        scenario=named_scenario(scenario, hydrogen.load_model()), controller=controller, t=t, q=q, q_d=q_d,
        leg_lengths=np.full((n, 6), 2.0), leg_forces=np.zeros((n, 6)), pressures=np.full((n, 6), 1e7),
        u=np.zeros((n, 6)), u_applied=np.zeros((n, 6)), leg_lengths_measured=np.full((n, 6), 2.0), theta_hat=theta_hat, gamma1_hat=gamma1_hat, gamma2_hat=gamma2_hat,
        theta_true=theta_true, gamma_true=gamma_true, amplitude=amp, metric_start=0.5,
        coordinates=("x", "y", "z", "psi", "theta", "phi"), units=("m",) * 3 + ("rad",) * 3,
        theta_names=("platform.mass", "platform.Ixx", "platform.Iyy", "platform.Izz"))
    res.compute_metrics()
    return res


def _check_png(path):
    assert path.exists()
    data = path.read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    assert len(data) > 5000
    # no temporary files left beside it
    assert not [p for p in path.parent.iterdir() if p.name.endswith(".tmp")]


def test_tracking_errors(tmp_path):
    out = tmp_path / "fig2.png"
    assert figures.plot_tracking_errors(_result("adaptive-robust", "paper-sim"), out, t_adapt=0.5) == out
    _check_png(out)
    out2 = tmp_path / "fig2_noline.png"
    figures.plot_tracking_errors(_result("adaptive-robust", "paper-sim"), out2)
    _check_png(out2)


def test_parameter_errors(tmp_path):
    out = tmp_path / "sub" / "fig3.png"  # missing folder is created
    figures.plot_parameter_errors(_result("adaptive-robust", "paper-sim"), out)
    _check_png(out)


@pytest.mark.parametrize("coord", ["z", "psi"])
def test_experiment(tmp_path, coord):
    nl = _result("adaptive-robust", err_scale=1e-4, seed=1)
    p = _result("p", err_scale=5e-3, seed=2)
    assert nl.metrics["max_error_pct"][coord] < p.metrics["max_error_pct"][coord]
    out = tmp_path / f"exp_{coord}.png"
    figures.plot_experiment(nl, p, coord, out, title="test")
    _check_png(out)


def test_experiment_coord_without_amplitude(tmp_path):
    # y has no reference amplitude: max_error_pct is None, shown as n/a
    nl, p = _result("adaptive-robust"), _result("p")
    assert nl.metrics["max_error_pct"]["y"] is None
    out = tmp_path / "exp_y.png"
    figures.plot_experiment(nl, p, "y", out)
    _check_png(out)


def test_experiment_rejects_unknown_coord(tmp_path):
    with pytest.raises(KeyError, match="unknown coordinate"):
        figures.plot_experiment(_result("adaptive-robust"), _result("p"), "w", tmp_path / "x.png")


def test_step(tmp_path):
    nl = _result("adaptive-robust", "z-step", step=True, err_scale=1e-4)
    p = _result("p", "z-step", step=True, err_scale=2e-3)
    out = tmp_path / "fig8.png"
    figures.plot_step(nl, p, out)
    _check_png(out)


def test_figures_are_closed(tmp_path):
    import matplotlib.pyplot as plt
    before = len(plt.get_fignums())
    figures.plot_tracking_errors(_result("adaptive-robust"), tmp_path / "a.png")
    figures.plot_step(_result("a", step=True), _result("p", step=True), tmp_path / "b.png")
    assert len(plt.get_fignums()) == before


def test_comparison_table():
    table = figures.comparison_table([("z 1 Hz", "z", 3.21, 40.0, 4, 43), ("psi 1 Hz", "psi", None, 41.5, 4, 41)])
    lines = table.strip().splitlines()
    assert lines[0].startswith("| scenario | coordinate |")
    assert "nonlinear" in lines[0] and "paper" in lines[0]
    assert set(lines[1]) <= set("|-: ")
    assert "| z 1 Hz | z | 3.2 | 40.0 | 4.0 | 43.0 |" in lines
    assert "| psi 1 Hz | psi | n/a | 41.5 | 4.0 | 41.0 |" in lines
    assert len(lines) == 4


def test_a_comparison_without_paper_numbers_has_no_paper_columns():
    table = figures.comparison_table([("arm-dig", "boom", 0.1, 31.3, None, None, 0.6)])
    assert "paper" not in table
    assert "| arm-dig | boom | 0.1 | 31.3 | 0.6 |" in table.splitlines()


def test_make_all_names_the_nonlinear_controller(tmp_path, cache):
    dyn = hydrogen.build(hydrogen.load_model("excavator_arm"), cache=cache)
    short = {"arm-sim": 0.2, "arm-dig": 0.2}
    paths = figures.make_all(dyn, tmp_path / "a", durations=short, seeds=1)  # the description's: adaptive-robust
    assert '"nonlinear" is the adaptive-robust controller' in paths["table"].read_text()
    assert "vs paper" not in paths["table"].read_text() and "reports no numbers" in paths["table"].read_text()
    # "P" is the better of the fixed-gain controllers on each scenario, named in the row
    assert '"P" the better of p, p-task on each scenario' in paths["table"].read_text()
    assert "(P: p)" in paths["table"].read_text() or "(P: p-task)" in paths["table"].read_text()
    paths = figures.make_all(dyn, tmp_path / "b", durations=short, nonlinear="adaptive-observer", seeds=2,
                             max_workers=2)
    table = paths["table"].read_text()
    assert '"nonlinear" is the adaptive-observer controller' in table
    assert "median (min-max) over 2 sensor-noise seeds" in table
    m = hydrogen.simulate("arm-dig", "adaptive-observer", dyn=dyn, duration=0.2, seeds=2, max_workers=2).metrics
    med, lo, hi = (m[k]["max_error_pct"]["boom"] for k in ("median", "min", "max"))
    assert f"| boom | {med:.1f} ({lo:.1f}-{hi:.1f}) |" in table
    with pytest.raises(hydrogen.ScenarioError, match="nonlinear"):
        figures.make_all(dyn, tmp_path / "c", durations=short, nonlinear="p")


def test_step_metrics_give_the_rise_time_and_overshoot_of_a_known_response():
    """A second-order response to a 0.02 m step at t = 1 s: its 90 % crossing and its overshoot
    against the closed forms of the underdamped step (ζ = 0.3, ω = 20 rad/s)."""
    res = _result("p", step=True, n=20001, err_scale=0.0)
    t = res.t
    zeta, w = 0.3, 20.0
    wd, tau = w * np.sqrt(1 - zeta ** 2), np.clip(t - 1.0, 0.0, None)
    y = 1 - np.exp(-zeta * w * tau) * (np.cos(wd * tau) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * tau))
    res.q[:, 2] = res.q_d[0, 2] + 0.02 * np.where(t >= 1.0, y, 0.0)
    m = figures.step_metrics(res, 2)
    assert m["overshoot_pct"] == pytest.approx(100 * np.exp(-np.pi * zeta / np.sqrt(1 - zeta ** 2)), rel=1e-3)
    first90 = t[np.nonzero((t >= 1.0) & (y >= 0.9))[0][0]] - 1.0
    assert m["rise_s"] == pytest.approx(first90) and 0.05 < m["rise_s"] < 0.15
    res.q[:, 2] = res.q_d[0, 2]  # never moves
    assert figures.step_metrics(res, 2) == {"rise_s": None, "overshoot_pct": 0.0}


def test_a_figure_of_something_that_is_no_run_is_named(tmp_path):
    """plot_tracking_errors('z-1hz', ...) raised an AttributeError from inside matplotlib's setup."""
    with pytest.raises(hydrogen.ScenarioError, match=r"a figure draws a run .*got str 'z-1hz'"):
        figures.plot_tracking_errors("z-1hz", tmp_path / "a.png")
    assert not (tmp_path / "a.png").exists()
