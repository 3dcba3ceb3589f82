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
    with pytest.raises(ScenarioError, match=r"controller 'backstepping': no value for its input\(s\) Gtau_inv"):
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
    path.write_text(text.replace("[gains.backstepping]\n", "[gains.backstepping]\nGtau_inv = 900.0\n", 1))
    g = default_gains(Dynamics(hydrogen.load_model(path), dyn.library), "backstepping")
    np.testing.assert_array_equal(g["Gtau_inv"], np.full(6, 900.0))
    assert default_gains(dyn, "p")["u_max"].shape == (1,)
