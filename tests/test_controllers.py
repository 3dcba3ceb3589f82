"""hydrogen/controllers: each controller declared once (its spec), and what the rest reads from it."""
import re
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.controllers import CONTROLLERS, adapts, baseline, controller, spec
from hydrogen.errors import ScenarioError
from hydrogen.simulation import tuning


@pytest.mark.parametrize("name", CONTROLLERS)
def test_each_controller_declares_a_consistent_spec(name, model):
    mod, sp = controller(name), spec(name)
    assert mod.NAME == sp.name == name and mod.DOC == sp.doc
    scale = np.ones(model.n)
    assert sp.main_gain in mod.default_gains(model, scale)
    assert sp.grid_low > 0
    assert tuning.main_gain(name) == sp.main_gain
    assert tuning.default_grid(name)[0] == sp.grid_low


def test_exactly_one_baseline_and_it_estimates_nothing(model):
    assert [c for c in CONTROLLERS if spec(c).baseline] == [baseline()]
    assert not adapts(baseline(), model)
    assert adapts("adaptive-robust", model) and not adapts("backstepping", model)


def test_the_registry_keeps_the_shipped_order_by_rank():
    assert CONTROLLERS[:5] == ("backstepping", "adaptive-robust", "adaptive-observer", "p", "p-task")
    assert [spec(c).rank for c in CONTROLLERS[:5]] == [0, 1, 2, 3, 4]


def _package(tmp_path, name, modules):
    """A package ``name`` in ``tmp_path`` holding ``modules`` (module name -> source)."""
    root = tmp_path / name
    root.mkdir()
    (root / "__init__.py").write_text("")
    for mod, text in modules.items():
        (root / f"{mod}.py").write_text(text)
    return root


_SPEC = "from hydrogen.controllers.spec import ControllerSpec\nSPEC = ControllerSpec(name={!r}, doc='', main_gain='K', grid_low=1.0{})\n"


def test_the_registry_finds_every_module_declaring_a_spec_ranked_then_by_name(tmp_path, monkeypatch):
    from hydrogen.controllers import _discover

    monkeypatch.syspath_prepend(str(tmp_path))
    root = _package(tmp_path, "found_ctrls", {"zeta": _SPEC.format("zeta", ""), "alpha": _SPEC.format("alpha", ""),
                                               "first": _SPEC.format("first", ", rank=0"),
                                               "helpers": "X = 1\n"})  # no SPEC: not a controller
    assert list(_discover("found_ctrls", [str(root)])) == ["first", "alpha", "zeta"]


def test_two_modules_declaring_one_name_are_refused_naming_both(tmp_path, monkeypatch):
    from hydrogen.controllers import _discover
    from hydrogen.errors import HydrogenError

    monkeypatch.syspath_prepend(str(tmp_path))
    root = _package(tmp_path, "twin_ctrls", {"a": _SPEC.format("same", ""), "b": _SPEC.format("same", "")})
    with pytest.raises(HydrogenError, match=r"b\.py: controller name 'same' is already declared by .*a\.py"):
        _discover("twin_ctrls", [str(root)])


def test_no_module_outside_the_controllers_tests_a_controller_name():
    root = Path(hydrogen.__file__).parent
    names = "|".join(re.escape(c) for c in CONTROLLERS)
    test = re.compile(rf"""(==|!=|\bin)\s*\(?\s*["']({names})["']|["']({names})["']\s*(==|!=)""")

    def tests_a_name(line):
        m = test.search(line)
        # a one-letter name ("p") is also an FMU variable kind: only a comparison about a controller counts
        return m and (len(m.group(2) or m.group(3)) > 1 or re.search(r"controller|nonlinear|ctrl", line))

    hits = [f"{p.relative_to(root)}:{i}: {line.strip()}"
            for p in root.rglob("*.py") if "controllers" not in p.parts
            for i, line in enumerate(p.read_text().splitlines(), 1) if tests_a_name(line)]
    assert not hits, "\n".join(hits)


@pytest.mark.parametrize("engine", ["c", "python"])
def test_a_gain_no_table_gives_is_an_error_naming_it_in_both_loops(monkeypatch, dyn, engine):
    mod = controller("backstepping")
    full = mod.default_gains

    def without_gtau(model, scale):
        g = full(model, scale)
        del g["Gtau_inv"]
        return g

    monkeypatch.setattr(mod, "default_gains", without_gtau)
    with pytest.raises(ScenarioError, match=r"controller 'backstepping': no value for its input\(s\) Gtau_inv: "
                                            r"wired to no loop signal"):
        hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, duration=0.01, engine=engine)


def test_the_state_follows_the_declared_layout_or_generation_stops():
    import sympy as sp

    from hydrogen.symbolic.control_laws import state_and_rates

    a, b = sp.symbols("a0:2"), sp.symbols("b0:3")
    xc, xc_dot = state_and_rates([("a", 2), ("b", 3)], [("a", a, a), ("b", b, b)])
    assert list(xc) == [*a, *b] and xc_dot.shape == (5, 1)
    with pytest.raises(ValueError, match="not the declared layout"):
        state_and_rates([("a", 2), ("b", 3)], [("b", b, b), ("a", a, a)])
    with pytest.raises(ValueError, match="the layout declares"):
        state_and_rates([("a", 2), ("b", 3)], [("a", a, a), ("b", b[:2], b[:2])])


def test_the_pose_p_controller_is_the_weighted_pose_error_mapped_by_JL(robot_dyn, robot_model, rng):
    from hydrogen.controllers import function_name

    from conftest import workspace_poses

    fn = robot_dyn.functions[function_name("p-task")]
    n = robot_model.n
    k, u_max = rng.uniform(0.01, 0.1, n), 3e-3
    for q, qd in zip(workspace_poses(robot_model, 5, rng), workspace_poses(robot_model, 5, rng, scale=0.1)):
        args = {"q": q, "qd0": qd, "Kq": k, "u_max": [u_max]}
        u = fn(*[args[name] for name in fn.in_names])
        expected = np.clip(robot_dyn.leg_jacobian(q) @ (k * (qd - q)), -u_max, u_max)
        np.testing.assert_allclose(u, expected, rtol=1e-12, atol=1e-15)
    # equal gains: to first order the cylinder-length P controller
    q = robot_model.neutral_pose
    dq = 1e-6 * np.ones(n)
    args = {"q": q, "qd0": q + dq, "Kq": 0.03 * np.ones(n), "u_max": [u_max]}
    u = fn(*[args[name] for name in fn.in_names])
    dl = robot_dyn.leg_lengths(q + dq) - robot_dyn.leg_lengths(q)
    np.testing.assert_allclose(u, 0.03 * dl, rtol=1e-4)


def test_a_gain_list_of_the_wrong_length_is_named_never_broadcast(dyn, tmp_path):
    """``Gtau_inv = [900.0]`` for six actuators was taken as 900 for each: a list must hold one value per
    entry (the message names the gain, the file and table, and the count: n, m or p); one scalar still
    applies to every entry."""
    from hydrogen.dynamics import Dynamics
    from hydrogen.model import model_path
    from hydrogen.simulation.control import default_gains

    text = model_path("ubc_stewart").read_text()
    path = tmp_path / "stewart.toml"
    path.write_text(text.replace("[gains.backstepping]\n", "[gains.backstepping]\nGtau_inv = [900.0]\n", 1))
    edited = Dynamics(hydrogen.load_model(path), dyn.library)
    with pytest.raises(ScenarioError, match=rf"{re.escape(str(path))}: \[gains.backstepping\]: controller "
                                            r"'backstepping': gain 'Gtau_inv' needs 6 values \(n = m = 6\) \(or one "
                                            r"scalar for all\), got \[900.0\]"):
        default_gains(edited, "backstepping")
    with pytest.raises(ScenarioError, match=r"gain 'Gtheta_inv' needs 4 values \(p = 4\)"):
        hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn, duration=0.01, gains={"Gtheta_inv": [1.0, 2.0]})
    with pytest.raises(ScenarioError, match=r"gain 'u_max' needs 1 value \(or one scalar"):
        hydrogen.simulate("paper-sim", "p", dyn=dyn, duration=0.01, gains={"u_max": [1.0, 1.0]})
    for switch in (True, [True] * 6):  # a switch where a number belongs ran as a gain of 1
        with pytest.raises(ScenarioError, match=r"gain 'Kleg' needs 6 values .*got \[?True"):
            hydrogen.simulate("paper-sim", "p", dyn=dyn, duration=0.01, gains={"Kleg": switch})
    path.write_text(text.replace("[gains.backstepping]\n", "[gains.backstepping]\nGtau_inv = 900.0\n", 1))
    g = default_gains(Dynamics(hydrogen.load_model(path), dyn.library), "backstepping")
    np.testing.assert_array_equal(g["Gtau_inv"], np.full(6, 900.0))
    assert default_gains(dyn, "p")["u_max"].shape == (1,)


# --- defaults on a robot that gives none ---------------------------------------------------------
#: A 2-DOF boom and stick in the vertical x-z plane on four-way cylinders (50 mm bore, 30 mm rod,
#: 14 MPa), written for this test: no [gains] table and no [control] scale, so every gain is the
#: controllers' default derived from the description. One ideal-plant scenario, a slow multi-sine
#: (0.15-0.5 Hz, 0.16 / 0.19 rad), with wrong initial estimates and adaptation on at 0.5 s.
BOOM_STICK = """
name = "boom_stick"
gravity = 9.81

[[links]]
name = "boom"
mass = 60.0
com = [0.75, 0.0, 0.0]              # a 1.5 m boom
inertia = [0.6, 11.5, 11.5]

[[links]]
name = "stick"
mass = 25.0
com = [0.5, 0.0, 0.0]               # a 1 m stick
inertia = [0.2, 2.1, 2.1]

[[joints]]
name = "shoulder"
type = "revolute"
parent = "base"
child = "boom"
axis = [0.0, -1.0, 0.0]

[[joints]]
name = "elbow"
type = "revolute"
parent = "boom"
child = "stick"
origin_xyz = [1.5, 0.0, 0.0]
axis = [0.0, -1.0, 0.0]

[coordinates]
neutral = [0.25, -1.1]

[hydraulics]
kind = "four_way_cylinder"
cap_area = 1.9635e-3                # pi/4 x 0.050^2
annulus_area = 1.2566e-3            # cap area - pi/4 x 0.030^2
dead_volume_A = 8.0e-5
dead_volume_B = 8.0e-5
supply_pressure = 14.0e6
tank_pressure = 0.0
underlap = 1.0e-5
flow_gain = 1.2e-4
bulk_modulus = 1.2e9
orifice_linear_below = 5.0e4

[[cylinders]]
name = "boom_cylinder"
from = { link = "base", point = [0.35, 0.0, -0.45] }
to = { link = "boom", point = [0.55, 0.0, -0.10] }
stroke = [0.36, 0.76]               # 0.53 m at the neutral pose; the reference keeps within 0.45..0.61

[[cylinders]]
name = "stick_cylinder"
from = { link = "boom", point = [0.60, 0.0, 0.14] }
to = { link = "stick", point = [-0.20, 0.0, 0.12] }
stroke = [0.75, 1.15]               # 0.92 m at the neutral pose

[adaptation]
parameters = ["boom.mcx", "boom.Iyy", "stick.mcx", "stick.Iyy"]
theta_min = [30.0, 20.0, 6.0, 3.0]
theta_max = [70.0, 60.0, 20.0, 12.0]
gamma1_min = 6.0e8
gamma1_max = 2.4e9
gamma2_min = 6.0e4
gamma2_max = 2.4e5

[sensors]
joint_encoders = true

[scenarios.slow-sines]
duration = 4.0
control_rate = 1000.0
substeps = 2
t_adapt = 0.5
metric_start = 2.0
theta0_factor = [1.15, 0.85, 1.2, 0.85]
gamma0_factor = [0.8, 1.2]
reference.sines = [
  ["shoulder", 0.12, 0.15], ["shoulder", 0.04, 0.4],
  ["elbow", -0.15, 0.2], ["elbow", 0.04, 0.5],
]
"""

#: The nonlinear controllers' max error on it, % of each coordinate's amplitude. They track the
#: ideal plant to well under 1 % (backstepping 0.02 %, the adaptive ones 0.05 % when written); 20 %
#: is below the P controllers' lag (about 25 %) and far below a lost or ringing loop's error, yet
#: leaves room for a default that is merely less tight.
NONLINEAR_MAX_ERROR_PCT = 20.0
#: Every controller's, P included: a loop that follows the reference at all stays within its
#: amplitude; one that is unstable or lost leaves it.
ANY_MAX_ERROR_PCT = 100.0


@pytest.fixture(scope="module")
def boom_stick(tmp_path_factory, cache):
    """The robot above, built once for every controller (its functions derived here)."""
    path = tmp_path_factory.mktemp("boom_stick") / "boom_stick.toml"
    path.write_text(BOOM_STICK)
    model = hydrogen.load_model(path)
    assert not model.gains and model.scale is None  # every gain is a default
    return hydrogen.build(model, cache=cache, controllers=CONTROLLERS)


@pytest.mark.slow
@pytest.mark.parametrize("name", CONTROLLERS)
def test_default_gains_are_stable_on_a_new_robots_ideal_plant(boom_stick, name):
    """Each controller at its default gains on a robot that gives none: finite (a divergence raises),
    the valves rarely at their stop, the pose inside the strokes, and the nonlinear controllers
    tracking."""
    from hydrogen.simulation.simulator import SATURATION
    res = hydrogen.simulate("slow-sines", name, dyn=boom_stick)
    m = boom_stick.model
    for signal in (res.q, res.u, res.pressures, res.theta_hat, res.gamma1_hat, res.gamma2_hat):
        assert np.all(np.isfinite(signal))
    assert np.all((res.leg_lengths >= m.leg_min) & (res.leg_lengths <= m.leg_max))
    assert res.metrics["u_saturation_frac"] <= SATURATION, res.metrics["u_saturation_frac_by_actuator"]
    worst = max(res.metrics["max_error_pct"].values())
    assert worst < ANY_MAX_ERROR_PCT, res.metrics["max_error_pct"]
    if not spec(name).baseline and not spec(name).compared:  # the nonlinear controllers
        assert worst < NONLINEAR_MAX_ERROR_PCT, res.metrics["max_error_pct"]


def test_the_start_and_projection_of_the_state_are_the_blocks_own(monkeypatch, dyn):
    """The runtime sets each block to the initial value it declares and clips it to the limits it
    declares (numbers, a gain's name or a model range's): no table of blocks by name."""
    import dataclasses

    from hydrogen.simulation.control import make_controller

    model, mod = dyn.model, controller("adaptive-robust")
    q0, qdot0 = model.neutral_pose, np.full(model.n, 0.01)
    ctrl = make_controller(dyn, "adaptive-robust")
    ctrl.reset(q0, qdot0)
    assert np.array_equal(ctrl.part("z"), qdot0) and np.array_equal(ctrl.part("theta_hat"), model.theta)
    assert np.array_equal(ctrl.part("gamma1_hat"), np.full(model.n_cylinders, model.gamma[0][0]))
    assert np.array_equal(ctrl.part("legl_prev"), np.asarray(dyn.leg_lengths(q0), float).ravel())
    lo, hi = ctrl.bounds
    assert np.array_equal(lo[ctrl.slices["theta_hat"]], model.theta_min)
    assert np.all(hi[ctrl.slices["gamma2_hat"]] == model.gamma2_max) and np.all(np.isinf(hi[ctrl.slices["z"]]))

    full = mod.state_layout
    changed = {"z": dict(initial=lambda s: 2.0 * s.q0, limits=(lambda m, g: -g["u_max"], "u_max")),
               "theta_hat": dict(limits=(0.0, 9.0))}
    monkeypatch.setattr(mod, "state_layout", lambda m: [dataclasses.replace(b, **changed.get(b.name, {}))
                                                        for b in full(m)])
    ctrl = make_controller(dyn, "adaptive-robust", gains={"u_max": 0.004})
    ctrl.reset(q0, qdot0)
    assert np.array_equal(ctrl.part("z"), 2.0 * q0)
    lo, hi = ctrl.bounds
    assert np.all(lo[ctrl.slices["z"]] == -0.004) and np.all(hi[ctrl.slices["z"]] == 0.004)
    assert np.all(lo[ctrl.slices["theta_hat"]] == 0.0) and np.all(hi[ctrl.slices["theta_hat"]] == 9.0)


def test_a_block_names_its_entries_and_units_from_the_model(robot_model):
    blocks = {b.name: b for b in controller("adaptive-observer").state_layout(robot_model)}
    m = robot_model
    assert blocks["z"].entry_names(m) == list(m.coordinate_names)
    assert blocks["z"].units(m) == [f"{u}/s" for u in m.coordinate_units]
    assert blocks["gamma1_hat"].entry_names(m) == [c.name for c in m.cylinders]
    assert blocks["theta_hat"].entry_names(m) == list(m.theta_names) and None not in blocks["theta_hat"].units(m)
    assert blocks["gamma_gain"].entry_names(m)[:2] == ["[1]", "[2]"] and blocks["gamma_gain"].units(m)[0] is None


# Friction compensation (a deviation from the paper, off by default): f_d gets F_c tanh(l̇_r/v_s) + b l̇_r.

#: The rig's own leg friction on the platform ([rig] friction: Coulomb N, viscous N s/m).
RIG_FRICTION = {"friction_coulomb": 100.0, "friction_viscous": 300.0}
#: The controllers generated with friction compensation.
COMPENSATING = ["backstepping", "adaptive-robust", "adaptive-observer"]


def _with_friction(model):
    import dataclasses
    return dataclasses.replace(model, friction_compensation=True)


@pytest.fixture(scope="module")
def fdyn(model, cache):
    """The Stewart platform generated with friction compensation ([control] friction_compensation)."""
    return hydrogen.build(_with_friction(model), cache=cache, controllers=COMPENSATING)


def _worst(res) -> float:
    return max(v for v in res.metrics["max_error_pct"].values() if v is not None)


@pytest.mark.parametrize("name", COMPENSATING)
def test_friction_compensation_off_leaves_the_paper_law_to_the_bit(dyn, fdyn, name):
    """Generated with compensation, its coefficients and rate 0 (the defaults) add exact zeros to f_d
    and ḟ_d whatever the other friction gains: the run equals the paper's law's (generated without
    it, as the shipped robots are) bit for bit."""
    other = {"friction_speed": 0.05}
    if name != "backstepping":
        other.update(friction_coulomb_max=50.0, friction_viscous_max=70.0)
    base = hydrogen.simulate("z-1hz", name, dyn=dyn, duration=0.3)
    off = hydrogen.simulate("z-1hz", name, dyn=fdyn, duration=0.3, gains=other)
    for series in ("q", "u", "pressures"):
        assert np.array_equal(getattr(base, series), getattr(off, series)), series
    if name != "backstepping":
        assert np.all(off.states["coulomb_hat"] == 0.0) and np.all(off.states["viscous_hat"] == 0.0)


def test_a_model_without_compensation_has_no_friction_gains(dyn):
    """The paper's laws are generated without the terms: their gains are refused by name."""
    with pytest.raises(ScenarioError, match="has no gain 'friction_coulomb'"):
        hydrogen.simulate("z-1hz", "backstepping", dyn=dyn, duration=0.01, gains=RIG_FRICTION)
    assert not any(b.name in ("coulomb_hat", "viscous_hat") for b in controller("adaptive-robust").state_layout(dyn.model))


def test_known_friction_compensation_lowers_backstepping_error_on_the_rig(fdyn):
    """With the plant's own leg friction known, backstepping's error on z-1hz drops by a quarter
    (11.4 % -> 8.3 % on seed 0)."""
    off = _worst(hydrogen.simulate("z-1hz", "backstepping", dyn=fdyn, duration=3.0))
    on = _worst(hydrogen.simulate("z-1hz", "backstepping", dyn=fdyn, duration=3.0, gains=RIG_FRICTION))
    assert on < 0.85 * off


def test_adapted_friction_stays_within_its_bounds_and_lowers_the_error(fdyn):
    """The friction estimates start at 0, are driven up against tight bounds (the projection holds them
    there) and the adaptive-robust controller's error on z-1hz drops (4.4 % -> 1.3 % on seed 0 with
    the default bounds)."""
    bounds = {"friction_coulomb_max": 30.0, "friction_viscous_max": 50.0}
    res = hydrogen.simulate("z-1hz", "adaptive-robust", dyn=fdyn, duration=3.0, gains={"rate_friction": 300.0, **bounds})
    for block, hi in (("coulomb_hat", 30.0), ("viscous_hat", 50.0)):
        x = np.asarray(res.states[block])
        assert np.all(x >= 0.0) and np.all(x <= hi), block
    assert np.isclose(np.asarray(res.states["coulomb_hat"]).max(), 30.0)  # it reached the bound
    off = _worst(hydrogen.simulate("z-1hz", "adaptive-robust", dyn=fdyn, duration=3.0))
    on = _worst(hydrogen.simulate("z-1hz", "adaptive-robust", dyn=fdyn, duration=3.0, gains={"rate_friction": 0.3}))
    assert on < 0.6 * off


def test_a_friction_start_above_its_bound_is_refused_naming_both(fdyn):
    with pytest.raises(ScenarioError, match=r"adaptive-observer.*'friction_coulomb'.*'friction_coulomb_max'"):
        hydrogen.simulate("z-1hz", "adaptive-observer", dyn=fdyn, duration=0.01,
                          gains={"friction_coulomb": 500.0, "friction_coulomb_max": 200.0})
    with pytest.raises(ScenarioError, match=r"gain 'friction_speed' must be > 0"):
        hydrogen.simulate("z-1hz", "backstepping", dyn=fdyn, duration=0.01, gains={"friction_speed": 0.0})


def test_friction_estimates_take_each_actuators_own_units(robot_model):
    robot_model = _with_friction(robot_model)
    blocks = {b.name: b for b in controller("adaptive-robust").state_layout(robot_model)}
    from hydrogen.actuators import actuator
    for c, fc, fv in zip(robot_model.cylinders, blocks["coulomb_hat"].units(robot_model),
                         blocks["viscous_hat"].units(robot_model)):
        t = actuator(c.kind).TRAVEL
        assert (fc, fv) == (("N", "N.s/m") if t.unit == "m" else ("N.m", "N.m.s/rad"))
    assert blocks["coulomb_hat"].entry_names(robot_model) == [c.name for c in robot_model.cylinders]
