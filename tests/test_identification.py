"""hydrogen.identify: θ and γ by least squares from a rig's log (leg lengths, pressures, spool commands)."""
import dataclasses

import numpy as np
import pytest

import hydrogen
from hydrogen import IdentificationError
from hydrogen.identification import _per_sample, noise_std
from hydrogen.logs import Log, log_from_result, read_log, write_log

#: The rig's sensor noise, as in the experiment scenarios (noise_l, noise_p).
RIG_NOISE = (5e-6, 2e4)


@pytest.fixture(scope="module")
def paper_sim(dyn):
    return hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn)


@pytest.fixture(scope="module")
def paper_sim_log(paper_sim):
    """paper-sim as the rig would have logged it: true leg lengths and pressures plus the rig's noise."""
    return log_from_result(paper_sim, *RIG_NOISE, seed=0)


@pytest.mark.slow
def test_recovers_theta_and_gamma_within_2_percent_from_the_noisy_paper_sim_log(dyn, model, paper_sim_log):
    res = hydrogen.identify(paper_sim_log, dyn=dyn)
    print(res.summary())
    err = 100 * (res.theta.estimate - model.theta) / model.theta
    assert np.all(np.abs(err) < 2.0), err
    assert res.theta.identifiable and res.theta.cond < 100 and res.theta.direction is None
    # the standard errors are of the size of the errors (no more than a few of them apart) ...
    assert np.all(np.abs(res.theta.estimate - model.theta) < 5 * res.theta.std_error + 0.005 * model.theta)
    # ... and γ = [β, βc] too, from the pressures and spool commands
    g_true = model.gamma.mean(axis=1)  # the platform's legs share β and c
    g_err = 100 * (res.gamma.estimate - g_true) / g_true
    assert np.all(np.abs(g_err) < 2.0), g_err
    m = dyn.leg_lengths(model.neutral_pose).size
    assert res.gamma_per_leg.shape == (m, len(model.gamma))
    assert res.theta.error_pct == pytest.approx(err)  # the log carries the truth: the result compares


@pytest.mark.slow
def test_the_remaining_bias_is_the_held_command_and_the_zoh_correction_removes_it(dyn, model, paper_sim):
    """Without noise, I_x and I_y come out 0.3 % low at any cutoff: a pressure sampled where the command
    changes is not the period's mean that differenced positions see. Corrected, the fit is exact."""
    log = log_from_result(paper_sim)
    plain = hydrogen.identify(log, dyn=dyn, gamma=False)
    for cutoff in (6.0, 25.0):
        np.testing.assert_allclose(hydrogen.identify(log, dyn=dyn, gamma=False, cutoff_hz=cutoff).theta.error_pct,
                                   plain.theta.error_pct, atol=0.02)
    assert -0.4 < plain.theta.error_pct[1] < -0.25 and -0.4 < plain.theta.error_pct[2] < -0.25
    fixed = hydrogen.identify(log, dyn=dyn, gamma=False, zoh_correction=True)
    assert np.all(np.abs(fixed.theta.error_pct) < 0.02), fixed.theta.error_pct


def test_csv_round_trip_gives_the_same_estimate(dyn, paper_sim_log, tmp_path):
    short = Log(paper_sim_log.t[:3000], {k: v[:3000] for k, v in paper_sim_log.columns.items()},
                paper_sim_log.meta, paper_sim_log.source)
    path = write_log(short, tmp_path / "log.csv")
    back = read_log(path)
    assert back.meta["noise_l"] == RIG_NOISE[0]
    np.testing.assert_array_equal(back.t, short.t)
    np.testing.assert_array_equal(back.columns["pc3"], short.columns["pc3"])
    a = hydrogen.identify(short, dyn=dyn)
    b = hydrogen.identify(path, dyn=dyn)
    np.testing.assert_array_equal(a.theta.estimate, b.theta.estimate)
    np.testing.assert_array_equal(a.gamma.estimate, b.gamma.estimate)
    assert b.source == str(path)


def test_a_mapping_of_columns_and_a_result_are_logs_too(dyn, paper_sim):
    short = dataclasses.replace(paper_sim, t=paper_sim.t[:2000], leg_lengths=paper_sim.leg_lengths[:2000],
                                pressures=paper_sim.pressures[:2000], u=paper_sim.u[:2000], q=paper_sim.q[:2000],
                                u_applied=paper_sim.u_applied[:2000])
    from_result = hydrogen.identify(short, dyn=dyn)  # true values, no noise added
    m = short.leg_lengths.shape[1]
    cols = {"t": short.t, **{f"l{i}": short.leg_lengths[:, i] for i in range(m)},
            **{f"pc{i}": short.pressures[:, i] for i in range(m)}}
    no_spool = hydrogen.identify(cols, dyn=dyn)
    np.testing.assert_allclose(no_spool.theta.estimate, from_result.theta.estimate, rtol=1e-12)
    assert no_spool.gamma is None and "spool" in no_spool.gamma_note


def test_a_log_that_moves_only_z_names_the_inertias_as_unidentifiable(dyn, model):
    from hydrogen.simulation.reference import MultiSine
    from hydrogen.simulation.scenarios import scenario
    z = hydrogen.load_model().coordinate_names.index("z")
    sc = dataclasses.replace(scenario("paper-sim", model), name="z-only", duration=3.0,
                             reference=MultiSine(np.asarray(model.neutral_pose, float), ((z, 0.02, 1.0), (z, 0.01, 2.0))))
    res = hydrogen.identify(log_from_result(hydrogen.simulate(sc, "adaptive-robust", dyn=dyn), *RIG_NOISE), dyn=dyn)
    assert not res.theta.identifiable and res.theta.cond > 1e3
    assert "theta not identifiable from this log: the data does not excite 3 direction(s)" in res.summary()
    # the inertias are said to be unknown rather than given a number; the mass keeps its estimate
    assert all(f"{n} = not identifiable" in res.summary() for n in res.theta.names[1:])
    assert list(res.theta.determined) == [True, False, False, False]
    est = res.theta.to_dict()["estimate"]
    assert est[0] == pytest.approx(res.theta.estimate[0]) and est[1:] == [None] * 3
    d = res.theta.direction
    names = res.theta.names
    assert abs(d[names[0]]) < 0.05  # the mass is excited (gravity, heave) ...
    assert max(abs(d[n]) for n in names[1:]) > 0.9  # ... an inertia is not
    assert len(res.theta.unexcited) == len(names) - 1  # none of the three
    assert abs(res.theta.error_pct[0]) < 1.0  # the mass alone is still right


def test_gamma_is_compensated_for_the_leg_length_noise(dyn, model):
    """On a roll-only trajectory the compressibility term is small against the differenced leg-length
    noise; uncompensated, β came out 24 % low (8 standard errors); compensated, within 4 of them."""
    from hydrogen.simulation.reference import MultiSine
    from hydrogen.simulation.scenarios import scenario
    psi = hydrogen.load_model().coordinate_names.index("psi")
    sc = dataclasses.replace(scenario("paper-sim", model), name="psi-only", duration=4.0,
                             reference=MultiSine(np.asarray(model.neutral_pose, float),
                                                 ((psi, 0.0873, 1.0), (psi, 0.0349, 2.0))))
    res = hydrogen.identify(log_from_result(hydrogen.simulate(sc, "adaptive-robust", dyn=dyn), *RIG_NOISE), dyn=dyn)
    assert np.all(np.abs(res.gamma.estimate - model.gamma.mean(axis=1)) < 4 * res.gamma.std_error), res.gamma.error_pct


def test_noise_level_is_estimated_from_the_log(paper_sim):
    noisy = log_from_result(paper_sim, *RIG_NOISE, seed=3)
    m = paper_sim.leg_lengths.shape[1]
    np.testing.assert_allclose(noise_std(noisy.group("l", m)), RIG_NOISE[0], rtol=0.1)
    assert np.all(noise_std(paper_sim.leg_lengths) < 1e-8)


def test_poses_equal_newton_forward_kinematics_sample_by_sample(dyn, paper_sim_log):
    from hydrogen.identification import _poses
    m = dyn.leg_lengths(dyn.model.neutral_pose).size
    L = paper_sim_log.group("l", m)[:1500]
    Q = _poses(dyn, L, paper_sim_log.t, "log")
    q, ref = dyn.model.neutral_pose, []
    for l in L:
        q = dyn.forward_kinematics(l, q0=q)
        ref.append(q)
    np.testing.assert_allclose(Q, ref, rtol=0, atol=1e-10)
    bad = L.copy()
    bad[700] = -1.0  # no pose has negative leg lengths
    with pytest.raises(IdentificationError, match=r"^log: sample 700 \(t = 0\.7 s\): forward kinematics.*at q = \["):
        _poses(dyn, bad, paper_sim_log.t, "log")


def test_per_sample_uses_a_batched_function_when_there_is_one(dyn):
    calls = []

    def batched(q):
        calls.append(np.shape(q))
        return np.asarray(q) * 2.0

    qs = np.arange(12.0).reshape(3, 4)
    np.testing.assert_array_equal(_per_sample(batched, qs), qs * 2.0)
    assert calls[0] == (3, 4)  # one stacked call (plus one row to check it)
    single = dyn.functions["leg_lengths"]  # today's compiled functions take one sample: a loop
    poses = np.tile(dyn.model.neutral_pose, (3, 1))
    np.testing.assert_array_equal(_per_sample(single, poses)[1], single(poses[1]))


# --- bad input: one clear error naming the column or count ----------------------------------
def _columns(paper_sim, n=2000):
    m = paper_sim.leg_lengths.shape[1]
    return {"t": paper_sim.t[:n], **{f"l{i}": paper_sim.leg_lengths[:n, i] for i in range(m)},
            **{f"pc{i}": paper_sim.pressures[:n, i] for i in range(m)},
            **{f"u{i}": paper_sim.u[:n, i] for i in range(m)}}


def test_bad_logs_are_named(dyn, paper_sim, tmp_path):
    m = paper_sim.leg_lengths.shape[1]
    cols = _columns(paper_sim)
    with pytest.raises(IdentificationError, match=f"missing column\\(s\\) pc{m - 1}"):
        hydrogen.identify({k: v for k, v in cols.items() if k != f"pc{m - 1}"}, dyn=dyn)
    with pytest.raises(IdentificationError, match="missing column t"):
        hydrogen.identify({k: v for k, v in cols.items() if k != "t"}, dyn=dyn)
    with pytest.raises(IdentificationError, match="missing column\\(s\\) u1"):  # spool columns: all or none
        hydrogen.identify({k: v for k, v in cols.items() if k != "u1"}, dyn=dyn)
    with pytest.raises(IdentificationError, match="too few samples: 100; identification needs at least"):
        hydrogen.identify(_columns(paper_sim, 100), dyn=dyn)
    with pytest.raises(IdentificationError, match="too few samples: 5"):
        hydrogen.identify(_columns(paper_sim, 5), dyn=dyn)
    bad = dict(cols, l2=cols["l2"].copy())
    bad["l2"][[17, 40]] = np.nan
    with pytest.raises(IdentificationError, match=r"column l2 is not finite at sample\(s\) \[17, 40\]"):
        hydrogen.identify(bad, dyn=dyn)
    jitter = dict(cols, t=cols["t"].copy())
    jitter["t"][500] += 0.05 * (cols["t"][1] - cols["t"][0])
    with pytest.raises(IdentificationError, match="not uniformly sampled"):
        hydrogen.identify(jitter, dyn=dyn)
    backwards = dict(cols, t=cols["t"].copy())
    backwards["t"][500] = backwards["t"][499]
    with pytest.raises(IdentificationError, match="increase strictly; it does not at sample 500"):
        hydrogen.identify(backwards, dyn=dyn)
    with pytest.raises(IdentificationError, match="cutoff_hz"):
        hydrogen.identify(cols, dyn=dyn, cutoff_hz=900.0)
    with pytest.raises(IdentificationError, match="not list"):
        hydrogen.identify([1, 2, 3], dyn=dyn)
    path = tmp_path / "bad.csv"
    path.write_text("t,l0\n0.0,1.8\n0.001,oops\n")
    with pytest.raises(IdentificationError, match="line 3, column l0: not a number"):
        hydrogen.identify(path, dyn=dyn)
    with pytest.raises(IdentificationError, match="log file not found"):
        hydrogen.identify(tmp_path / "none.csv", dyn=dyn)


def test_cli_identify_and_simulate_log(tmp_path, capsys, monkeypatch, cache):
    from hydrogen.cli import main
    monkeypatch.setenv("HYDROGEN_CACHE_DIR", str(cache))
    log, out = tmp_path / "run.csv", tmp_path / "id.json"
    assert main(["simulate", "--scenario", "paper-sim", "--duration", "3", "--log", str(log)]) == 0
    assert "log written" in capsys.readouterr().out
    assert main(["identify", str(log), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "platform.mass" in text and "beta" in text
    import json
    data = json.loads(out.read_text())
    assert set(data["theta"]) >= {"estimate", "std_error", "cond", "identifiable", "direction"}
    assert data["friction"] is None
    assert main(["identify", str(log), "--friction"]) == 0
    assert "friction: cond" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:
        main(["identify", str(log), "--friction", "--friction-speed", "0"])
    assert stop.value.code == 2 and "must be > 0" in capsys.readouterr().err
    short = tmp_path / "short.csv"
    short.write_text("\n".join(log.read_text().splitlines()[:40]) + "\n")
    assert main(["identify", str(short)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "too few samples" in err[0] and "Traceback" not in err[0]


# --- a log whose units or ranges do not fit the model: refused, naming the column --------------
def _refused(cols, dyn, match):
    with pytest.raises(IdentificationError, match=match) as info:
        hydrogen.identify(cols, dyn=dyn)
    assert "np." not in str(info.value)  # plain numbers, never np.float64(...)
    return str(info.value)


def test_lengths_that_do_not_move_say_no_excitation(dyn, paper_sim):
    cols = _columns(paper_sim, 4001)
    m = paper_sim.leg_lengths.shape[1]
    still = dict(cols, **{f"l{i}": np.full(4001, cols[f"l{i}"][0]) for i in range(m)})
    msg = _refused(still, dyn, r"no excitation: no actuator moves \(the most, for its range: '.+', column l\d, "
                               r"range 0 m; sensor noise 0 m\)")
    assert "too few samples" not in msg


def test_lengths_outside_the_strokes_name_the_cylinder_time_and_stroke(dyn, model, paper_sim):
    cols = _columns(paper_sim, 4001)
    bad = dict(cols, l0=cols["l0"].copy())
    bad["l0"][300] = 10.0
    c = model.cylinders[0]
    _refused(bad, dyn, rf"column l0 leaves actuator '{c.name}''s stroke: at t = 0.3 s it is length 10 m, "
                       rf"stroke \[{c.stroke_min:g}, {c.stroke_max:g}\] m \(1 of 4001 samples outside\)$")
    m = paper_sim.leg_lengths.shape[1]
    # every column in mm: each sample counts once, not once per column
    _refused(dict(cols, **{f"l{i}": 1000 * cols[f"l{i}"] for i in range(m)}), dyn,
             r"4001 of 4001 samples outside\); its lengths look like mm: write them in m")


def test_a_vanes_angle_column_is_checked_in_its_angle_range_and_rad():
    """A rotary vane's column is its angle: checked against its angle range in rad, and one logged in
    degrees is named so, never as a length in m or a stroke (the crane's slew; no build needed)."""
    from hydrogen.logcheck import check_lengths
    model = hydrogen.load_model("loader_crane")
    slew = [c.kind for c in model.cylinders].index("rotary")
    t = np.linspace(0.0, 2.0, 201)
    L = (model.leg_min + 0.5 * (model.leg_max - model.leg_min)) + 0.05 * np.sin(2 * np.pi * t)[:, None] * (
        model.leg_max - model.leg_min)
    check_lengths("log.csv", t, L, model)  # inside every range: accepted
    deg = L.copy()
    deg[:, slew] = np.degrees(0.3 + 0.5 * np.sin(2 * np.pi * t))
    with pytest.raises(IdentificationError) as err:
        check_lengths("log.csv", t, deg, model)
    msg = str(err.value)
    assert msg.startswith(f"log.csv: column l{slew} leaves actuator 'slew_motor''s angle range: at t = ")
    assert "rad, angle range [-1.8, 1.8] rad" in msg and msg.endswith("its angles look like degrees: write them in rad")
    assert "stroke" not in msg and "length" not in msg


def test_an_unlimited_actuators_column_is_never_outside_and_moves_past_turns():
    """An actuator of unlimited travel (range (−∞, ∞): a motor's turns) is never outside its range, and
    its column moving counts as excitation whatever the others do; held still with the rest, the log
    is refused as one that does not move (the crane, its slew taken as unlimited; no build needed)."""
    from hydrogen.logcheck import check_lengths
    model = hydrogen.load_model("loader_crane")
    slew = [c.kind for c in model.cylinders].index("rotary")
    lo, hi = model.leg_min.copy(), model.leg_max.copy()
    lo[slew], hi[slew] = -np.inf, np.inf
    from types import SimpleNamespace
    free = SimpleNamespace(leg_min=lo, leg_max=hi, cylinders=model.cylinders)
    t = np.linspace(0.0, 2.0, 201)
    L = np.tile(0.5 * (model.leg_min + model.leg_max), (t.size, 1))
    L[:, slew] = 3.0 * t * np.pi  # two turns and more, past any angle range
    check_lengths("log.csv", t, L, free)  # only the motor moves: excitation, never outside
    L[:, slew] = 0.25
    with pytest.raises(IdentificationError, match="no excitation: no actuator moves"):
        check_lengths("log.csv", t, L, free)


def test_pressures_all_zero_in_bar_or_above_supply_are_refused(dyn, model, paper_sim):
    cols = _columns(paper_sim, 4001)
    m = paper_sim.leg_lengths.shape[1]
    pcs = [f"pc{i}" for i in range(m)]
    _refused(dict(cols, **{c: 0 * cols[c] for c in pcs}), dyn, "pressures are all 0")
    _refused(dict(cols, pc3=0 * cols["pc3"]), dyn, r"pressure column\(s\) pc3 are all 0")
    _refused(dict(cols, **{c: cols[c] / 1e5 for c in pcs}), dyn, "pressures look like bar")
    high = dict(cols, pc2=cols["pc2"].copy())
    high["pc2"][1000] = 2 * model.supply_pressure[2]
    _refused(high, dyn, r"pressure column pc2 at t = 1 s is .* Pa, above the supply pressure")
    noisy = log_from_result(paper_sim, *RIG_NOISE)  # sensor noise around 0 and P_s is accepted
    assert hydrogen.identify(noisy, dyn=dyn, gamma=False).theta.identifiable


def test_a_time_column_in_ms_is_refused_against_the_control_rate(dyn, model, paper_sim):
    from hydrogen.logcheck import control_rates
    cols = _columns(paper_sim, 4001)
    rates = ", ".join(f"{r:g}" for r in control_rates(model))
    _refused(dict(cols, t=1000 * cols["t"]), dyn,
             rf"time column t looks like ms: sample interval 1 \(1 Hz if in s\), but the control rates? (is|are) "
             rf"{rates} Hz")


def test_a_pump_robots_log_carries_its_supply_pressure(pump_dyn, tmp_path):
    """Where the supply is a plant state its pressure is a log column, ps0 (Pa), after the pressures
    and measured like them (noise_p, drawn after theirs: l and pc are what they were), read back
    exactly; the simulate CLI's --log writes it and its --json gives its range."""
    import json

    from hydrogen.cli import main as cli

    res = hydrogen.simulate("arm-sim", "backstepping", dyn=pump_dyn, duration=0.1)
    ps = res.supply_pressure
    log = read_log(res.save_log(tmp_path / "pump.csv"))
    np.testing.assert_array_equal(log.columns["ps0"], ps)
    names = list(log.columns)
    at = names.index("ps0")
    assert names[at - 1] == f"pc{res.pressures.shape[1] - 1}" and names[at + 1] == "u0"
    noisy = log_from_result(res, noise_l=1e-5, noise_p=2e4, seed=3)
    without = log_from_result(dataclasses.replace(res, supply_pressure=None), noise_l=1e-5, noise_p=2e4, seed=3)
    assert "ps0" not in without.columns and "l, pc and ps are" in noisy.meta["note"]
    for name, col in without.columns.items():
        np.testing.assert_array_equal(noisy.columns[name], col)
    assert 1e4 < np.std(noisy.columns["ps0"] - ps) < 4e4
    back = read_log(write_log(noisy, tmp_path / "noisy.csv"))
    np.testing.assert_array_equal(back.columns["ps0"], noisy.columns["ps0"])
    # the CLI, on the pump robot's description
    out = tmp_path / "cli.csv"
    metrics = tmp_path / "metrics.json"
    assert cli(["simulate", "--scenario", "arm-sim", "--controller", "backstepping", "--model", str(pump_dyn.model.source), "--duration", "0.1",
                "--log", str(out), "--log-noise-l", "0", "--log-noise-p", "0", "--json", str(metrics)]) == 0
    np.testing.assert_array_equal(read_log(out).columns["ps0"], ps)
    assert json.loads(metrics.read_text())["supply_pressure"] == {"min": ps.min(), "max": ps.max(), "final": ps[-1]}


def test_a_pump_robots_parameters_are_identified_at_its_logged_supply_pressure(pump_dyn):
    """A three-way cylinder's rod side is at the supply pressure: on a pump robot the forces (and the
    flows of γ) are at the log's ps0, not the nominal supply_pressure (θ off by ~95 % then); a log
    without ps0 is refused naming the column."""
    res = hydrogen.simulate("arm-sim", "backstepping", dyn=pump_dyn, duration=4.0)
    assert np.ptp(res.supply_pressure) > 5e5  # the supply moves
    est = hydrogen.identify(res, dyn=pump_dyn)
    np.testing.assert_allclose(est.theta.estimate, res.theta_true, rtol=0.01)
    log = log_from_result(res)
    del log.columns["ps0"]
    with pytest.raises(IdentificationError, match=r"missing column\(s\) ps0"):
        hydrogen.identify(log, dyn=pump_dyn)


def test_a_log_saved_with_a_utf8_byte_order_mark_is_read(tmp_path):
    """Spreadsheets save CSV as "UTF-8 with BOM": the mark before the header is no part of column t."""
    t = np.arange(5) * 1e-3
    log = Log(t, {"l0": 1.8 + t, "pc0": 1e6 + t, "u0": 0.1 * t})
    written = write_log(log, tmp_path / "log.csv")
    plain = tmp_path / "plain.csv"
    plain.write_text("t,l0,pc0,u0\n" + "\n".join(",".join(map(repr, map(float, row))) for row in
                                                  zip(t, *log.columns.values())))
    for path in (written, plain):
        bom = tmp_path / f"bom-{path.name}"
        bom.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
        back = read_log(bom)
        np.testing.assert_array_equal(back.t, t)
        assert list(back.columns) == ["l0", "pc0", "u0"]
        np.testing.assert_array_equal(back.columns["pc0"], log.columns["pc0"])


def test_a_tab_separated_log_is_read_and_mixed_delimiters_are_named(dyn, paper_sim_log, tmp_path):
    short = Log(paper_sim_log.t[:50], {k: v[:50] for k, v in paper_sim_log.columns.items()}, paper_sim_log.meta)
    comma = write_log(short, tmp_path / "log.csv")
    tab = tmp_path / "tab.tsv"
    tab.write_text(comma.read_text().replace(",", "\t"))
    back = read_log(tab)
    assert list(back.columns) == list(short.columns)
    np.testing.assert_array_equal(back.columns["pc2"], short.columns["pc2"])
    lines = comma.read_text().splitlines()
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("\n".join(lines[:4] + [lines[4].replace(",", "\t")] + lines[5:]) + "\n")
    with pytest.raises(IdentificationError, match="line 5: values separated by tabs, but the header "
                                                  r"\(line 3\) by commas: use one delimiter throughout, a comma"):
        read_log(mixed)
    semi = tmp_path / "semi.csv"
    semi.write_text("t;l0;l1\n0;1.8;1.8\n")
    with pytest.raises(IdentificationError, match="line 1: .* separated by semicolons: the delimiter must be a comma"):
        read_log(semi)


def test_a_fit_that_no_robot_has_is_not_identifiable_and_out_of_bounds_is_warned():
    from hydrogen.identification import ParameterFit, _check_physical
    fit = ParameterFit(["beta", "beta_c"], np.array([-3.0e5, 1.0e5]), np.array([1e5, 1e3]), 3.0, True, None,
                       1.0, 100)
    _check_physical(fit, [True, True], [1e8, 5e4], [1e9, 2e5], "[adaptation] bounds")
    assert not fit.identifiable and list(fit.determined) == [False, True]
    assert "beta = -3e+05 by least squares, not > 0" in fit.reason
    text = "\n".join(fit.describe("gamma"))
    assert "gamma not identifiable from this log" in text and "beta = not identifiable" in text
    assert fit.to_dict()["estimate"] == [None, 1.0e5]
    high = ParameterFit(["platform.mass"], np.array([3480.0]), np.array([45.0]), 1.0, True, None, 1.0, 100)
    _check_physical(high, [True], [150.0], [350.0], "[adaptation] theta_min/theta_max")
    assert high.identifiable and "outside the model's bounds [150, 350]" in high.warnings[0]
    assert "warning: platform.mass = 3480 is outside" in "\n".join(high.describe("theta"))


def test_cli_identify_refuses_pressures_in_bar(tmp_path, capsys, paper_sim_log):
    from hydrogen.cli import main
    cols = {k: (v / 1e5 if k.startswith("pc") else v) for k, v in paper_sim_log.columns.items()}
    path = write_log(Log(paper_sim_log.t, cols, paper_sim_log.meta), tmp_path / "bar.csv")
    assert main(["identify", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pressures look like bar" in err[0] and "write them in Pa" in err[0]


def test_an_identified_parameter_whose_true_value_is_zero_reports_an_absolute_error():
    from hydrogen.identification import ParameterFit

    fam = ParameterFit(names=["a.mcy", "a.mass"], estimate=np.array([0.01, 10.5]), std_error=np.array([0.1, 0.1]),
                       cond=1.0, identifiable=True, direction=None, residual_rms=0.0, rows=10,
                       true=np.array([0.0, 10.0]))
    assert fam.error_pct.tolist() == [None, pytest.approx(5.0)]
    d = fam.to_dict()
    assert d["error_pct"][0] is None and d["error"][0] == pytest.approx(0.01)
    text = "\n".join(fam.describe("theta"))
    assert "nan" not in text.lower() and "inf" not in text.lower() and "true 0, error +0.01" in text


# --- friction, fitted with theta ---------------------------------------------------------------------
def test_friction_is_estimated_with_theta_from_a_log_made_with_a_known_friction(plain_stewart_dyn):
    """A paper-sim run on a plant with the rig's friction (100 N Coulomb, 300 N s/m viscous on every
    leg, the loop's tanh at 1 mm/s: the Stewart platform without its seal table, whose Stribeck dip and
    pressure load the fit's law lacks), logged without noise: identify(friction=True) gives every leg's
    Coulomb within 10 % and viscous within 15 % of the truth, and θ closer to the truth than the fit
    that ignores friction (which ascribes the friction to θ)."""
    dyn = plain_stewart_dyn
    res = hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, friction=[100.0, 300.0, 1e-3])
    plain = hydrogen.identify(res, dyn=dyn, gamma=False)
    fit = hydrogen.identify(res, dyn=dyn, gamma=False, friction=True)
    est = dict(zip(fit.friction.names, fit.friction.estimate))
    for c in dyn.model.cylinders:
        assert est[f"{c.name}.coulomb"] == pytest.approx(100.0, rel=0.10), est
        assert est[f"{c.name}.viscous"] == pytest.approx(300.0, rel=0.15), est
    assert fit.theta.names == plain.theta.names and fit.identifiable
    assert fit.theta.explained == fit.friction.explained > 0.9  # the joint fit's share, on both parts
    assert np.max(np.abs(fit.theta.error_pct)) < 0.6 * np.max(np.abs(plain.theta.error_pct))
    text = fit.summary()
    assert "friction: cond" in text and "leg1.coulomb" in text
    assert fit.to_dict()["friction"]["estimate"] == pytest.approx(list(fit.friction.estimate))
    frictionless = hydrogen.identify(hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, duration=6.0), dyn=dyn,
                                     gamma=False, friction=True)
    assert np.max(np.abs(frictionless.friction.estimate[:dyn.model.n_cylinders])) < 5.0  # N: none where there is none
    with pytest.raises(IdentificationError, match="friction_speed must be a positive speed"):
        hydrogen.identify(res, dyn=dyn, gamma=False, friction=True, friction_speed=0.0)


@pytest.fixture(scope="module")
def excavator(cache):
    arm = hydrogen.build(hydrogen.load_model("excavator_arm"), cache=cache, controllers=("backstepping",))
    return arm, hydrogen.simulate("arm-sim", "backstepping", dyn=arm, duration=10.0)


def test_gamma_pooled_over_cylinders_whose_values_differ_is_refused_and_each_cylinder_is_reported(excavator):
    """The excavator's bucket valve has half the others' βc: one [β, βc] for all three cylinders
    explains little of the force increments (least squares gave β 99 % low with a small standard
    error), so it is not reported; each cylinder's own fit, which explains its data, is, by name."""
    arm, res = excavator
    fit = hydrogen.identify(res, dyn=arm)  # noise-free
    assert not fit.gamma.identifiable and not fit.gamma.determined.any() and fit.gamma.explained < 0.5
    assert "the model's cylinders have different values" in fit.gamma.reason
    np.testing.assert_allclose(fit.gamma_per_leg, arm.model.gamma.T, rtol=0.01)
    assert min(fit.gamma_per_leg_explained) > 0.99
    text = fit.summary()
    assert "beta = not identifiable" in text and "explains" in text
    for c, (beta, beta_c) in zip(arm.model.cylinders, fit.gamma_per_leg):
        assert f"    {c.name}: {beta:.6g}, {beta_c:.6g} (" in text
    assert fit.to_dict()["gamma"]["estimate"] == [None, None]
    assert fit.to_dict()["gamma_per_leg_names"] == [c.name for c in arm.model.cylinders]


def test_gamma_that_the_pressure_noise_drives_is_not_reported(dyn, model):
    """paper-sim logged with 200 kPa of pressure noise: the noise is most of the force increments over a
    sample and the fit explains a fifth of them; the estimate is refused with that reason instead of a
    value biased towards 0. With 20 kPa (the rig's) the fit explains 96 %, the rest the noise's share:
    reported, within 1 %."""
    res = hydrogen.simulate("paper-sim", "p", dyn=dyn)
    fit = hydrogen.identify(log_from_result(res, 5e-6, 2e5, seed=0), dyn=dyn)
    assert not fit.gamma.identifiable and "the pressure sensors' noise is" in fit.gamma.reason
    assert "and drives the rest" in fit.gamma.reason
    assert fit.theta.identifiable  # θ is still determined
    rig = hydrogen.identify(log_from_result(res, *RIG_NOISE, seed=0), dyn=dyn)
    assert rig.gamma.identifiable and np.all(np.abs(rig.gamma.error_pct) < 1.0)


def test_gamma_leaving_more_than_the_noise_explains_is_not_reported(dyn):
    """z-1hz on the rig under P (second-order valves, seal friction), logged without noise: the fit
    explains 89 % of the force increments, and the noise none of the other 11 %; least squares gave β
    17 % low there with a few % of standard error. Refused naming the unexplained share."""
    res = hydrogen.simulate("z-1hz", "p", dyn=dyn)
    fit = hydrogen.identify(res, dyn=dyn)
    assert fit.gamma.explained > 0.8 and not fit.gamma.identifiable
    assert "left unexplained (at most 3 % allowed)" in fit.gamma.reason
    assert "does not describe this log" in fit.gamma.reason


def test_gamma_from_a_log_its_model_does_not_describe_is_refused_as_such(dyn):
    """The rig's z-1hz (second-order valves, seal friction) logged without sensor noise: the γ model (the
    spool where commanded, no friction) explains a third of the force increments, and the noise none of
    the rest: refused naming the model, not the noise."""
    res = hydrogen.simulate("z-1hz", "backstepping", dyn=dyn, duration=3.0)
    fit = hydrogen.identify(res, dyn=dyn)
    assert not fit.gamma.identifiable and fit.gamma.explained < 0.5
    assert "does not describe this log" in fit.gamma.reason and "drives the rest" not in fit.gamma.reason


def test_a_log_of_another_robot_names_the_model_its_header_records(excavator, dyn, tmp_path):
    """The excavator's log file read for the Stewart platform (identify's default model), or for the crane
    (as many travel and pressure columns): refused before anything is built, naming the model its
    header records; in memory (a result, a Log) alike, from the run's record (a result identified with
    the default robot ran on the Stewart platform's model before); a log without that entry (a rig's)
    says what missing columns stand for."""
    _, res = excavator
    path = tmp_path / "arm.csv"
    write_log(log_from_result(res), path)
    assert read_log(path).meta["model"] == "excavator_arm"
    for model in (None, "loader_crane"):
        with pytest.raises(IdentificationError) as err:
            hydrogen.identify(path, model=model)
        text = str(err.value)
        assert "header says it is a log of model 'excavator_arm', not of '" in text and "--model excavator_arm" in text
    with pytest.raises(IdentificationError, match=r"record \(meta\) says it is a log of model 'excavator_arm', "
                                                  r"not of 'ubc_stewart': pass that model \(model='excavator_arm'"):
        hydrogen.identify(res, dyn=dyn)
    log = log_from_result(res)
    log.meta.pop("model")
    with pytest.raises(IdentificationError, match=r"needs l0..l5: the travel of the model's 6 actuators"):
        hydrogen.identify(log, dyn=dyn)


@pytest.mark.parametrize("seed", [-1, 2.5, True, "0"])
def test_a_logs_noise_seed_must_be_a_non_negative_integer(seed):
    """Refused before anything is drawn (numpy's own ValueError came after the run, with a traceback)."""
    with pytest.raises(IdentificationError, match=rf"seed must be an integer >= 0 .*got {seed!r}"):
        log_from_result(None, 1e-6, 1e3, seed=seed)


@pytest.mark.parametrize("written,advice", [("excavator_arm", "model='excavator_arm' (--model excavator_arm), or its "
                                                              "description file"),
                                            ("my_arm", "its description file: model= or --model path/to/the.toml "
                                                       "naming 'my_arm'")])
def test_a_log_of_another_robot_names_how_to_pass_it(tmp_path, written, advice):
    """A shipped robot is passed by name; a user's own description only by its file (a name alone
    would not be found)."""
    t = np.arange(10) * 1e-3
    path = write_log(Log(t, {"l0": t}, {"model": written}), tmp_path / "log.csv")
    with pytest.raises(IdentificationError, match="the log's header says it is a log of model") as err:
        hydrogen.identify(path)
    assert advice in str(err.value)


@pytest.mark.parametrize("option,value", [("order", 0), ("order", -2), ("order", 2.5), ("max_cond", -1.0),
                                          ("max_cond", float("nan")), ("max_cond", "x"), ("edge_cycles", -1.0),
                                          ("edge_cycles", float("nan")), ("zoh_correction", "no"),
                                          ("friction", "yes"), ("gamma", 1)])
def test_identify_refuses_an_option_out_of_its_range_before_any_work(option, value):
    """order 0 fitted a wrong mass, a string switched a feature on, a negative edge raised an IndexError."""
    with pytest.raises(IdentificationError, match=rf"identify: {option} must be .*got {value!r}"):
        hydrogen.identify({"t": [0.0, 1.0]}, **{option: value})


def test_a_log_made_by_hand_is_checked_like_a_csv():
    """A Log whose columns are longer or shorter than t (it was cut after its columns), or whose parts are
    of the wrong kind, is refused naming what is wrong (it was identified on its first rows, or a raw
    IndexError)."""
    t = np.arange(100) * 1e-3
    for log, message in ((Log(t[:50], {"l0": t}), r"column l0 holds 100 values, t holds 50"),
                         (Log(t, {"l0": t[:3]}), r"column l0 holds 3 values, t holds 100"),
                         (Log(t, None), "columns must map names to columns"),
                         (Log(None, {}), "t must be one column of times"),
                         (Log(t, {"l0": t}, "x"), "meta must be a dict")):
        with pytest.raises(IdentificationError, match=message):
            hydrogen.identify(log)


def test_save_log_names_a_path_it_cannot_write_and_a_noise_that_is_no_number(paper_sim, tmp_path):
    from hydrogen.errors import OutputPathError

    for path, message in ((tmp_path, "is a folder"), (".", "needs a file name"), (5, "a path .* is needed, got int 5")):
        with pytest.raises(OutputPathError, match=message):
            paper_sim.save_log(path)
    with pytest.raises(IdentificationError, match=r"noise_l must be a finite number >= 0, got '5e-6'"):
        paper_sim.save_log(tmp_path / "log.csv", noise_l="5e-6")
    assert list(tmp_path.iterdir()) == []


def test_a_logs_record_of_the_true_parameters_of_another_size_is_named(paper_sim_log, dyn):
    """theta_true of another length in a log's meta (a record of another description) made the
    comparison None in silence."""
    log = Log(paper_sim_log.t, paper_sim_log.columns, {**paper_sim_log.meta, "theta_true": [1.0, 2.0]})
    with pytest.raises(IdentificationError, match=r"meta theta_true holds 2 values, the model has 4"):
        hydrogen.identify(log, dyn=dyn, gamma=False)
