"""A valve per actuator from its datasheet: the rating gives the flow gain, the spool's response, its
overlap and saturation (hydrogen.plant.valve; the description's ``valve`` table, hydrogen.model)."""
import math
import tomllib

import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.actuators import actuator
from hydrogen.errors import HydrogenError
from hydrogen.model import model_from_dict, model_path
from hydrogen.plant import valve
from hydrogen.plant.valve import values as valve_parameters
from hydrogen.simulation.scenarios import scenario

from conftest import plain_stewart_data

#: The Stewart platform's valve (Table I's) as a datasheet gives it: 17 L/min at 35 bar per edge, 1 mm spool travel, an
#: underlap of 5.54 % of the travel (the description's 55.4 um exactly), 80 Hz, damping 0.7.
DATASHEET = {"rated_flow": 2.8e-4, "rated_drop": 3.5e6, "spool_travel": 1e-3, "bandwidth_hz": 80.0,
             "damping": 0.7, "overlap": -0.0554}


def _description(name="ubc_stewart"):
    """A robot's description data; the Stewart platform's with Table I's valve and no seal friction."""
    return plain_stewart_data() if name == "ubc_stewart" else tomllib.loads(model_path(name).read_text())


@pytest.fixture(scope="module")
def model(plain_stewart):
    """The Stewart platform with Table I's valve (no datasheet valve), without seal friction."""
    return plain_stewart


@pytest.fixture(scope="module")
def dyn(plain_stewart_dyn):
    return plain_stewart_dyn


def _stewart_with(table, where="hydraulics"):
    """ubc_stewart with ``table`` as the valve of [hydraulics] (or of cylinder ``where``)."""
    data = _description()
    if where == "hydraulics":
        for key in ("flow_gain", "underlap"):
            data["hydraulics"].pop(key)
        data["hydraulics"]["valve"] = table
    else:
        next(c for c in data["cylinders"] if c["name"] == where)["valve"] = table
    return model_from_dict(data, "valve.toml")


def _chamber_flow(c, u_eff, drop):
    """The flow into chamber A (m^3/s) of actuator ``c`` at effective spool ``u_eff`` with ``drop`` across
    its supply edge, at rest, mid-travel, read off its kind's numeric pressure-rate law: ṗ = β (q − a ẋ)/V,
    a = ∂f/∂p_A from its force law, β/V from the rate's change with ẋ."""
    kind = actuator(c.kind)
    P = kind.parameters(c.table)
    x = 0.5 * (c.stroke_min + c.stroke_max) if math.isfinite(c.stroke_min) else 0.0
    ps = P["supply_pressure"]
    p = tuple([ps - drop] + [0.5 * ps] * (len(kind.STATES) - 1))
    beta, gain = c.bulk_modulus, c.flow_gain
    area = kind.Numeric.force((p[0] + 1.0, *p[1:]), P) - kind.Numeric.force(p, P)
    at_rest = kind.Numeric.pressure_rates(x, 0.0, p, u_eff, beta, gain, P)[0]
    moving = kind.Numeric.pressure_rates(x, 1e-3, p, u_eff, beta, gain, P)[0]
    beta_over_v = (at_rest - moving) / (area * 1e-3)
    return at_rest / beta_over_v


def _full_open(c):
    row = [c.valve[par.name] for par in valve.PARAMETERS]
    s = c.valve["full_opening"]
    return float(valve.Numeric.effective([2 * s], [2 * s], row)[0])  # commanded past full: saturated


@pytest.mark.parametrize("overlap", [-0.0554, 0.0, 0.15])
def test_full_opening_at_the_rated_drop_passes_the_rated_flow(overlap):
    m = _stewart_with({**DATASHEET, "overlap": overlap})
    for c in m.cylinders:
        q = _chamber_flow(c, _full_open(c), DATASHEET["rated_drop"])
        assert q == pytest.approx(DATASHEET["rated_flow"], rel=0.01)
    assert m.cylinders[0].underlap == pytest.approx(max(-overlap, 0.0) * 1e-3, rel=1e-12, abs=0)


def test_the_shipped_stewart_valves_rating_gives_back_table_is_constants():
    from conftest import TABLE_I_VALVE
    shipped = hydrogen.load_model("ubc_stewart")
    for c in shipped.cylinders:
        assert c.flow_gain == pytest.approx(TABLE_I_VALVE["flow_gain"], rel=1e-6)
        assert c.underlap == pytest.approx(TABLE_I_VALVE["underlap"], rel=1e-12)
        assert c.valve["full_opening"] == 5e-3 and c.valve["omega"] == pytest.approx(2 * np.pi * 80.0)
    # the controllers' spool command saturates where the spool does
    assert hydrogen.simulate("z-1hz", "backstepping", model=shipped, duration=0.01).u_max == 5e-3


@pytest.mark.parametrize("name", ["excavator_arm", "loader_crane"])
def test_a_four_way_or_rotary_actuators_rating_holds_through_its_own_law(name):
    today = hydrogen.load_model(name)
    data = _description(name)
    travel, drop = 3e-3, 1.5e6
    for cy, c in zip(data["cylinders"], today.cylinders):
        cy.pop("flow_gain", None)
        cy.pop("underlap", None)
        # today's orifice as a first-order datasheet valve (20 Hz), critically centred
        cy["valve"] = {"rated_flow": c.flow_gain * travel * math.sqrt(drop), "rated_drop": drop,
                       "spool_travel": travel, "bandwidth_hz": 20.0}
    for key in ("flow_gain", "underlap"):
        data.get("hydraulics", {}).pop(key, None)
    m = model_from_dict(data, f"{name}.toml", base_dir=model_path(name).parent)
    assert {c.kind for c in m.cylinders} == {c.kind for c in today.cylinders}
    for c, was, cy in zip(m.cylinders, today.cylinders, data["cylinders"]):
        assert c.flow_gain == pytest.approx(was.flow_gain, rel=1e-12)
        q = _chamber_flow(c, _full_open(c), drop)
        assert q == pytest.approx(cy["valve"]["rated_flow"], rel=0.01)
        assert c.valve["omega"] == 0.0 and c.valve["lag"] == pytest.approx(1 / (2 * np.pi * 20.0))


def _phase_deg(row, f, periods=30, steps=400):
    """Phase (deg) of the spool against a unit sine command at ``f`` Hz, the plant's spool law
    (valve.Numeric.rates) integrated by RK4; the last 10 periods projected on sin and cos."""
    h = 1.0 / (f * steps)
    s = np.zeros(2)  # spool, spool rate

    def rate(t, s):
        u = np.sin(2 * np.pi * f * t)
        r = valve.Numeric.rates([s[0]], [s[1]], [u], row)
        return np.array([r["spool"][0], r["spool_rate"][0]])
    out, t = [], 0.0
    for _ in range(periods * steps):
        k1 = rate(t, s)
        k2 = rate(t + h / 2, s + h / 2 * k1)
        k3 = rate(t + h / 2, s + h / 2 * k2)
        k4 = rate(t + h, s + h * k3)
        s, t = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h
        out.append((t, s[0]))
    t, y = np.array(out[-10 * steps:]).T
    a, b = (2 * np.mean(y * np.sin(2 * np.pi * f * t)), 2 * np.mean(y * np.cos(2 * np.pi * f * t)))
    return math.degrees(math.atan2(b, a))


@pytest.mark.parametrize("damping, crossing", [(0.7, -90.0), (0.3, -90.0), (None, -45.0)])
def test_the_simulated_spool_crosses_its_phase_at_the_bandwidth(damping, crossing):
    f = 80.0
    sheet = {**DATASHEET, "bandwidth_hz": f}
    if damping is None:
        sheet.pop("damping")
    else:
        sheet["damping"] = damping
    c = _stewart_with(sheet).cylinders[0]
    row = [c.valve[par.name] for par in valve.PARAMETERS]
    row[3:] = [0.0, 0.0]  # the spool's own response: no dead band, no saturation on the unit sine
    below, above = _phase_deg(row, 0.95 * f), _phase_deg(row, 1.05 * f)
    assert below > crossing > above


def test_overlap_gives_no_flow_inside_the_dead_band():
    c = _stewart_with({**DATASHEET, "overlap": 0.2}).cylinders[0]
    row = [c.valve[par.name] for par in valve.PARAMETERS]
    o = 0.2 * DATASHEET["spool_travel"]
    assert c.valve["overlap"] == pytest.approx(o) and c.underlap == 0.0
    for u in np.linspace(-o, o, 9):
        eff = valve.Numeric.effective([u], [u], row)
        assert _chamber_flow(c, eff, 1e6) == 0.0
    for u in (1.05 * o, -1.05 * o):
        assert abs(_chamber_flow(c, valve.Numeric.effective([u], [u], row), 1e6)) > 0


@pytest.mark.parametrize("overlap, limits", [(-0.0554, (True, False)), (0.0, (True, False)), (0.2, (True, True))])
def test_only_a_datasheet_valve_puts_its_saturation_and_dead_band_in_the_plant(model, overlap, limits):
    m = _stewart_with({**DATASHEET, "overlap": overlap}, where="leg2")
    assert [c.valve_limits for c in m.cylinders] == [(False, False), limits] + [(False, False)] * 4
    assert [c.valve_limits for c in model.cylinders] == [(False, False)] * 6
    # structure: such a robot gets its own generated plant; one without keeps today's hash
    assert m.structure() != model.structure() and "valve_limits" not in str(model.baked())
    spool, u = (sp.Matrix(sp.symbols(f"{k}0:6", real=True)) for k in ("s", "u"))
    eff = valve.Symbolic.effective(spool, u, valve.Symbolic.parameters(6), [c.valve_limits for c in m.cylinders])
    terms = [len(e.atoms(sp.Min, sp.Max)) for e in eff]
    assert terms == [0, 2 * sum(limits), 0, 0, 0, 0]  # a Min and a Max per term, on leg2 alone


def test_an_actuators_valve_overrides_the_rigs_for_it_alone(model):
    m = _stewart_with({**DATASHEET, "damping": 0.5, "bandwidth_hz": 120.0}, where="leg2")
    rows = valve_parameters(scenario("z-1hz", m), m)
    rig = valve_parameters(scenario("z-1hz", model), model)
    assert rig[0, 1] > 0  # the rig's valve has its dynamics
    assert np.array_equal(rows[[0, 2, 3, 4, 5]], rig[[0, 2, 3, 4, 5]])
    assert np.array_equal(rig[:, 3:], np.zeros((6, 2)))  # today's valves: no dead band, no saturation
    assert rows[1].tolist() == pytest.approx([0.0, 2 * np.pi * 120.0, 0.5, 0.0, 1e-3])
    # an ideal valve's scenario: the spool follows at once, the datasheet valve's geometry stays
    ideal = scenario("paper-sim", m)
    assert ideal.valve_lag == 0 and ideal.valve_bandwidth_hz == 0
    assert valve_parameters(ideal, m)[1].tolist() == pytest.approx([0.0, 0.0, 0.5, 0.0, 1e-3])


def test_a_scenario_sets_one_actuators_spool_response_over_its_datasheets_or_the_rigs(model):
    m = _stewart_with({**DATASHEET, "damping": 0.5, "bandwidth_hz": 120.0}, where="leg2")
    rig = scenario("z-1hz", m)
    rows = valve_parameters(rig.with_overrides(actuators={"leg2": {"valve": {"bandwidth_hz": 40.0}},
                                                          "leg3": {"valve": {"damping": 0.3}}}), m)
    base = valve_parameters(rig, m)
    assert rows[1].tolist() == pytest.approx([0.0, 2 * np.pi * 40.0, 0.5, 0.0, 1e-3])  # its damping, geometry kept
    assert rows[2].tolist() == pytest.approx([*base[2, :2], 0.3, *base[2, 3:]])  # the rig's 80 Hz, damping 0.3
    assert np.array_equal(rows[[0, 3, 4, 5]], base[[0, 3, 4, 5]])  # the others as they were
    # in an ideal valve's scenario the given response acts: second order where the datasheet's is
    ideal = scenario("paper-sim", m).with_overrides(actuators={"leg2": {"valve": {"bandwidth_hz": 40.0}},
                                                               "leg1": {"valve": {"bandwidth_hz": 40.0}}})
    rows = valve_parameters(ideal, m)
    assert rows[1].tolist() == pytest.approx([0.0, 2 * np.pi * 40.0, 0.5, 0.0, 1e-3])
    assert rows[0].tolist() == pytest.approx([1 / (2 * np.pi * 40.0), 0.0, *rows[0, 2:]])  # none to replace: a lag
    assert np.array_equal(valve_parameters(ideal, m)[2:], valve_parameters(scenario("paper-sim", m), m)[2:])
    with pytest.raises(hydrogen.ScenarioError, match=r"'paper-sim': actuators\.leg1\.valve\.damping = 0\.3 needs a "
                       r"second-order spool"):
        valve_parameters(scenario("paper-sim", m).with_overrides(actuators={"leg1": {"valve": {"damping": 0.3}}}), m)
    with pytest.raises(hydrogen.ScenarioError, match=r"actuator 'leg2': its valve's bandwidth_hz 4000 Hz must be "
                       r"<= control_rate \* substeps"):
        valve_parameters(rig.with_overrides(actuators={"leg2": {"valve": {"bandwidth_hz": 4000.0}}}), m)


@pytest.mark.parametrize("table, text", [
    ({"rated_flow": 1e-3}, r"actuators\.leg2\.valve: unknown key\(s\) \['rated_flow'\]; a scenario sets the spool's "
                           r"response"),
    ({"bandwidth_hz": -40.0}, r"actuators\.leg2\.valve\.bandwidth_hz must be a finite number in \[0\.1, 10000\] Hz "
                              r"\(declared in hydrogen\.plant\.valve\), got -40\.0"),
    ({"damping": float("nan")}, r"actuators\.leg2\.valve\.damping must be a finite number in \[0\.001, 10\] \("),
    ({"damping": True}, r"actuators\.leg2\.valve\.damping must be a finite number"),
    ({"bandwidth_hz": 1e5}, r"actuators\.leg2\.valve\.bandwidth_hz must be a finite number in \[0\.1, 10000\] Hz "
                            r"\(declared in hydrogen\.plant\.valve\), got 100000\.0"),
    ({"damping": 20.0}, r"actuators\.leg2\.valve\.damping must be a finite number in \[0\.001, 10\] "
                        r"\(declared in hydrogen\.plant\.valve\), got 20\.0"),
    ({}, r"actuators\.leg2\.valve: expected a table \{ bandwidth_hz, damping \}"),
    (40.0, r"actuators\.leg2\.valve: expected a table"),
])
def test_a_bad_scenario_valve_response_is_refused_by_name(model, table, text):
    with pytest.raises(hydrogen.ScenarioError, match=r"scenario 'z-1hz': " + text):
        scenario("z-1hz", model).with_overrides(actuators={"leg2": {"valve": table}})


def test_a_scenario_valve_response_runs_in_both_loops_alike(dyn):
    kw = dict(duration=0.2, actuators={"leg1": {"valve": {"bandwidth_hz": 30.0, "damping": 0.9}}})
    c_run = hydrogen.simulate("z-1hz", "backstepping", dyn=dyn, **kw)
    py_run = hydrogen.simulate("z-1hz", "backstepping", dyn=dyn, engine="python", **kw)
    np.testing.assert_allclose(c_run.q, py_run.q, rtol=0, atol=1e-10)
    plain = hydrogen.simulate("z-1hz", "backstepping", dyn=dyn, duration=0.2)
    assert not np.array_equal(c_run.q, plain.q)


def test_a_datasheet_valve_loads_builds_and_runs_closed_loop(dyn):
    m = _stewart_with(DATASHEET)
    assert m.underlap.tolist() == [55.4e-6] * 6  # the flow gain is an input; the saturation is structure
    d = hydrogen.build(m)
    kw = dict(duration=0.3, noise_l=0.0, noise_p=0.0, noise_q=0.0)
    c_run = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=d, **kw)
    py_run = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=d, engine="python", **kw)
    assert np.all(np.isfinite(c_run.q))
    np.testing.assert_allclose(c_run.q, py_run.q, rtol=0, atol=1e-9)
    today = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn, **kw)
    assert not np.array_equal(c_run.pressures, today.pressures)  # another flow gain, a saturating spool
    # the tracking stays as good as with the rig's ideal-orifice valve (the spool saturates at 1 mm)
    assert np.abs(c_run.q - c_run.q_d).max() < 2 * np.abs(today.q - today.q_d).max() + 1e-3


@pytest.mark.parametrize("table, where, text", [
    ({**DATASHEET, "rated_flow": -1.0}, "hydraulics", "valve.rated_flow: must be > 0"),
    ({**DATASHEET, "overlap": 1.0}, "hydraulics", "valve.overlap: must be in (-1, 1)"),
    ({**DATASHEET, "damping": 0.0}, "hydraulics", "valve.damping: must be > 0"),
    ({**DATASHEET, "bandwidth_hz": "80"}, "hydraulics", "valve.bandwidth_hz: expected a number"),
    ({k: v for k, v in DATASHEET.items() if k != "spool_travel"}, "hydraulics", "missing key 'spool_travel'"),
    ({**DATASHEET, "rated_flw": 1.0}, "hydraulics", "rated_flw"),
    ({**DATASHEET, "rated_flow": 1e-7, "rated_drop": 1e8, "spool_travel": 0.1}, "hydraulics",
     "valve.rated_flow (the flow gain it gives)"),  # a flow gain below any valve's
    (DATASHEET, "leg1", "flow_gain both given"),
])
def test_bad_valve_values_are_refused_by_name(table, where, text):
    with pytest.raises(HydrogenError) as err:
        if where == "leg1":  # [hydraulics] flow_gain stays: the leg's own valve is more specific, but not its own flow_gain
            data = _description()
            data["cylinders"][0].update(valve=table, flow_gain=1e-4)
            model_from_dict(data, "valve.toml")
        else:
            _stewart_with(table, where)
    assert "valve.toml" in str(err.value) and text in str(err.value)


def test_the_cli_names_a_bad_scenario_valve_response_without_a_traceback(tmp_path, capsys):
    from hydrogen import cli
    from hydrogen.model import default_model_path
    path = tmp_path / "valves.toml"
    path.write_text(default_model_path().read_text() + "\n[variants.bad]\nactuators.leg1.valve = { lag = 0.01 }\n")
    assert cli.main(["simulate", "--model", str(path), "--scenario", "z-1hz.bad", "--controller", "p",
                     "--duration", "0.05"]) == 2
    err = capsys.readouterr().err
    assert "[scenarios.z-1hz] over [rig] with [variants.bad]: actuators.leg1.valve: unknown key(s) ['lag']" in err and "Traceback" not in err
    assert path.exists()
