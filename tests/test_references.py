"""The reference kinds (hydrogen.references): each declares its contract, its derivatives are those of
its positions, its configuration sets its own fields and leaves the others idle, and the C loop's
reference function gives what its numpy twin gives."""
from __future__ import annotations

import ctypes as C

import numpy as np
import pytest

import hydrogen
from hydrogen import references
from hydrogen.simulation.scenarios import scenario


@pytest.fixture(scope="module")
def dyn():
    return hydrogen.build(controllers=("p",))


def test_each_kind_declares_the_contract():
    assert references.KINDS == ("moves", "sines", "step")
    seen = set()
    for key in references.KINDS:
        mod = references.kind(key)
        assert mod.KEY == key and mod.SYNTAX and mod.COMMENT and mod.C_BODY.strip()
        names = [f[0] for f in mod.FIELDS]
        assert set(mod.IDLE) == set(names) and not seen & set(names)  # no field of two kinds
        seen |= set(names)
        assert mod.Reference.__dataclass_fields__ and list(mod.Reference.__dataclass_fields__)[0] == "bias"
    comment, fields = references.config_fields()
    assert [f[0] for f in fields] == ["bias", *(f[0] for k in references.KINDS for f in references.kind(k).FIELDS)]
    assert all(references.kind(k).SYNTAX in references.syntax() for k in references.KINDS)


def test_a_second_module_declaring_a_kind_is_refused(tmp_path):
    pkg = tmp_path / "refs"
    pkg.mkdir()
    for name in ("a", "b"):
        (pkg / f"{name}.py").write_text("KEY = 'same'\nclass Reference: pass\n")
    (pkg / "__init__.py").write_text("")
    import sys
    sys.path.insert(0, str(tmp_path))
    try:
        with pytest.raises(ImportError, match="declared twice"):
            references._discover([str(pkg)], "refs")
        (pkg / "b.py").write_text("KEY = 'other'\nclass Reference: pass\n")
        for mod in [m for m in sys.modules if m.startswith("refs")]:
            del sys.modules[mod]
        assert list(references._discover([str(pkg)], "refs")) == ["other", "same"]  # by key
    finally:
        sys.path.remove(str(tmp_path))


def test_the_sines_derivatives_are_those_of_their_positions():
    ref = references.kind("sines").Reference(np.array([0.1, -0.2]), ((0, 0.02, 1.0), (1, 0.01, 3.0), (0, 0.005, 2.5)))
    t, d = 0.37, 1e-5

    def at(tt):
        return ref(tt)

    for order in range(3):  # each derivative the central difference of the one before
        fd = (at(t + d)[order] - at(t - d)[order]) / (2 * d)
        np.testing.assert_allclose(at(t)[order + 1], fd, rtol=1e-6, atol=1e-9)
    ts = np.linspace(0, 2, 7)
    np.testing.assert_allclose(ref.positions(ts), [ref(x)[0] for x in ts], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ref.velocities(ts), [ref(x)[1] for x in ts], rtol=0, atol=1e-15)
    assert ref.amplitude().tolist() == [0.025, 0.01] and ref.frequencies() == (1.0, 3.0, 2.5)


def test_the_step_holds_its_bias_until_its_time():
    ref = references.kind("step").Reference(np.zeros(3), 1, 0.02, 1.0)
    assert ref(0.999)[0].tolist() == [0, 0, 0] and ref(1.0)[0].tolist() == [0, 0.02, 0]
    assert all(not np.any(ref(2.0)[k]) for k in (1, 2, 3)) and ref.frequencies() == ()
    np.testing.assert_array_equal(ref.positions([0.5, 1.5]), [[0, 0, 0], [0, 0.02, 0]])


@pytest.mark.parametrize("name", ["z-1hz", "z-step"])
def test_each_kind_sets_its_own_fields_and_leaves_the_others_idle(model, name):
    ref = scenario(name, model).reference
    own = references.reference_kind(ref)
    values = references.config_values(ref)
    for key in references.KINDS:
        mod = references.kind(key)
        for field, _, _ in mod.FIELDS:
            want = ref.config()[field] if mod is own else mod.IDLE[field]
            np.testing.assert_array_equal(values[field], want)
    np.testing.assert_array_equal(values["bias"], ref.bias)
    assert references.config_axes(values) == ([2] if name == "z-step" else [2.0])  # z, the coordinate moved


@pytest.mark.parametrize("name", ["z-1hz", "z-step", "psi-1hz"])
def test_the_c_reference_function_equals_its_numpy_twin(dyn, name):
    from hydrogen.simulation.simulator import make_runner, prepare_run

    p = prepare_run(dyn, name, "p", None, 0.1, True, {})
    runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    stages = runner.stages()
    n = dyn.model.n
    for t in (0.0, 0.3, 0.999, 1.0, 1.7):
        stages.signals.t = t
        stages.reference()
        got = np.ctypeslib.as_array(C.cast(stages.signals.qd, C.POINTER(C.c_double)), (4 * n,)).reshape(4, n)
        np.testing.assert_allclose(got, np.array(p.sc.reference(t)), rtol=1e-14, atol=1e-15)


def test_an_edited_reference_kind_makes_the_generated_code_stale(tmp_path, monkeypatch):
    """The reference kinds shape every robot's loop (its configuration, its C reference function): an
    edit of any of their modules changes the drivers' hash the generated folders record (and not the
    functions' derivation hash: no function is derived again)."""
    import shutil
    from pathlib import Path

    from hydrogen.codegen import generate as G

    copy = tmp_path / "hydrogen"
    shutil.copytree(Path(G.__file__).resolve().parent.parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__", "_templates", "_generated"))
    monkeypatch.setattr(G, "_PACKAGE", copy)
    before, functions = G.drivers_hash(), G.derivation_hash()
    for key in references.KINDS:
        path = copy / "references" / Path(references.kind(key).__file__).name
        text = path.read_text()
        path.write_text(text + "\n# edited\n")
        assert G.drivers_hash() != before, key
        assert G.derivation_hash() == functions, key  # the generated functions do not read it
        path.write_text(text)
    assert G.drivers_hash() == before


def _moves():
    return references.kind("moves").Reference(np.array([0.1, -0.2, 0.0]),
                                              ((0, 0.3, 0.5, 2.0), (1, -0.1, 1.0, 0.5), (0, 0.05, 1.5, 1.0)))


def test_a_move_is_minimum_jerk_its_derivatives_those_of_its_positions():
    ref = _moves()
    d = 1e-5
    for t in (0.7, 1.2, 1.9, 2.4):  # inside the moves, two of them overlapping
        for order in range(3):
            fd = (ref(t + d)[order] - ref(t - d)[order]) / (2 * d)
            np.testing.assert_allclose(ref(t)[order + 1], fd, rtol=1e-6, atol=1e-8)
    q0, q1 = ref(0.0), ref(10.0)
    np.testing.assert_array_equal(q0[0], ref.bias)  # before: the bias
    np.testing.assert_allclose(q1[0], ref.bias + [0.35, -0.1, 0.0], rtol=0, atol=1e-15)  # after: held
    for k in (1, 2, 3):
        assert not np.any(q0[k]) and not np.any(q1[k])
    # velocity and acceleration zero at both ends of a move, its midpoint half the distance
    np.testing.assert_allclose(ref(1.25)[0][1] - ref.bias[1], -0.05, atol=1e-15)
    for t in (1.0, 1.5):
        assert abs(ref(t)[1][1]) < 1e-12 and abs(ref(t)[2][1]) < 1e-12
    ts = np.linspace(0, 3, 13)
    np.testing.assert_allclose(ref.positions(ts), [ref(x)[0] for x in ts], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ref.velocities(ts), [ref(x)[1] for x in ts], rtol=0, atol=1e-15)
    assert ref.amplitude().tolist() == [0.35, 0.1, 0.0] and ref.frequencies() == ()


def test_a_bad_move_is_refused_naming_it():
    from hydrogen.errors import ScenarioError
    from hydrogen.simulation.checks import check_reference

    ok = _moves()
    check_reference(ok, "s", 3)
    for moves, field in ((((0, 0.3, 0.5, 0.0),), "reference.moves[0] duration"),
                         (((5, 0.3, 0.5, 1.0),), "reference.moves[0] axis"),
                         (((0, float("nan"), 0.5, 1.0),), "reference.moves[0] distance"),
                         (((0, 0.3),), "reference.moves[0]")):
        with pytest.raises(ScenarioError, match=field.replace("[", r"\[").replace("]", r"\]")):
            check_reference(type(ok)(ok.bias, moves), "s", 3)


def test_the_c_reference_function_runs_a_move_as_its_numpy_twin(dyn, model):
    from hydrogen.simulation.simulator import make_runner, prepare_run

    n = model.n
    ref = references.kind("moves").Reference(np.asarray(scenario("z-1hz", model).reference.bias),
                                             ((2, 0.02, 0.2, 1.0), (5, 0.05, 0.4, 0.6)))
    p = prepare_run(dyn, "z-1hz", "p", None, 0.1, True, {"reference": ref})
    runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    stages = runner.stages()
    for t in (0.0, 0.2, 0.35, 0.7, 0.95, 1.2, 2.0):
        stages.signals.t = t
        stages.reference()
        got = np.ctypeslib.as_array(C.cast(stages.signals.qd, C.POINTER(C.c_double)), (4 * n,)).reshape(4, n)
        np.testing.assert_allclose(got, np.array(ref(t)), rtol=1e-13, atol=1e-15)


def test_a_described_work_cycle_of_moves_runs_on_the_excavator(tmp_path):
    """reference.moves in a description: the boom raised, then the stick and the bucket curled, on the
    arm's rig; backstepping tracks it (its max error under a fifth of each move, under half of P's) and
    the two loops agree."""
    import shutil
    from pathlib import Path

    from hydrogen.simulation.simulator import simulate

    src = Path(hydrogen.__file__).parent / "data"
    for f in ("excavator_arm.toml", "excavator_arm.urdf"):
        shutil.copy(src / f, tmp_path / f)
    toml = tmp_path / "excavator_arm.toml"
    toml.write_text(toml.read_text() + """
[scenarios.cycle]
rig = true
duration = 4.0
metric_start = 0.5
reference.moves = [["boom", 0.1, 0.5, 1.5], ["stick", -0.1, 1.0, 1.5], ["bucket", 0.2, 1.5, 1.0]]
""")
    model = hydrogen.load_model(toml)
    dyn = hydrogen.build(model, controllers=("backstepping", "p"))
    res, p = simulate(dyn, "cycle", "backstepping"), simulate(dyn, "cycle", "p")
    err, err_p = res.metrics["max_error_pct"], p.metrics["max_error_pct"]
    assert set(err) == {"boom", "stick", "bucket"}
    assert all(err[c] < 20.0 and err[c] < 0.5 * err_p[c] for c in err), (err, err_p)
    assert "hf_error_rms" not in res.metrics  # not periodic: no high-frequency metric
    py = simulate(dyn, "cycle", "backstepping", engine="python", duration=0.6)
    c = simulate(dyn, "cycle", "backstepping", duration=0.6)
    np.testing.assert_allclose(py.q, c.q, rtol=0, atol=1e-9)
    # the exported program runs the same cycle from its params.h (the moves read off the kind's fields)
    from test_export import reproduces_the_simulation

    from hydrogen.export import export
    folder = export(tmp_path / "export", "cycle", "backstepping", duration=2.0, dyn=dyn, metric_start=0.5)
    assert "P_REF_MOVES" in (folder / "params.h").read_text()
    got, _, _ = reproduces_the_simulation(folder, dyn, "cycle", "backstepping", 2.0, 0.5)
    assert got.min() > 1e-6  # every coordinate moved and tracked with an error


@pytest.mark.parametrize("entry,words", [('[["tail", 0.1, 0.5, 1.0]]', "coordinate 'tail' is not one of"),
                                         ('[["boom", 0.1, 0.5]]', "malformed reference.moves"),
                                         ('[["boom", 0.1, 0.5, 0.0]]', "reference.moves[0] duration must be > 0 s")])
def test_a_bad_move_in_a_description_is_one_message_naming_the_file_once(tmp_path, entry, words):
    import shutil
    from pathlib import Path

    from hydrogen.errors import HydrogenError

    src = Path(hydrogen.__file__).parent / "data"
    for f in ("excavator_arm.toml", "excavator_arm.urdf"):
        shutil.copy(src / f, tmp_path / f)
    toml = tmp_path / "excavator_arm.toml"
    toml.write_text(toml.read_text() + f"\n[scenarios.cycle]\nrig = true\nreference.moves = {entry}\n")
    with pytest.raises(HydrogenError) as exc:
        hydrogen.simulate("cycle", "p", model=hydrogen.load_model(toml))
    assert words in str(exc.value) and str(exc.value).count("excavator_arm.toml") <= 1


@pytest.mark.parametrize("key,entry,words", [
    ("sines", '[["z", "0.05", 1.0]]', "malformed reference.sines ('0.05' is not a number)"),
    ("sines", '[["z", true, 1.0]]', "malformed reference.sines (True is not a number)"),
    ("sines", '[["z", 0.05, -1.0]]', "reference.sines[0] frequency must be >= 0 Hz"),
    ("sines", '[["z", 0.05, 300.0]]', "reference frequency 300 Hz must be below half the control rate (256 Hz"),
    ("step", '{ coordinate = "z", height = "0.02", time = 1.0 }', "malformed reference.step ('0.02' is not"),
    ("step", '{ coordinate = "z", height = 0.02, time = false }', "malformed reference.step (False is not"),
    ("moves", '[["z", 0.02, "1", 1.0]]', "malformed reference.moves ('1' is not a number)")])
def test_a_reference_number_of_the_wrong_type_or_range_is_refused_naming_the_table(tmp_path, key, entry, words):
    """A quoted number or a boolean where a reference takes a number, a negative frequency, and a
    frequency the loop cannot sample (at or above half the control rate): each one message naming the
    file and the scenario's tables, before anything runs."""
    from hydrogen.model import default_model_path
    from hydrogen.errors import HydrogenError

    toml = tmp_path / "stewart.toml"
    toml.write_text(default_model_path().read_text() + f"\n[scenarios.mine]\nrig = true\nreference.{key} = {entry}\n")
    with pytest.raises(HydrogenError) as exc:
        scenario("mine", hydrogen.load_model(toml))
    text = str(exc.value)
    assert words in text and text.startswith(f"{toml}: [scenarios.mine]"), text


def test_metrics_need_two_samples_and_say_when_the_reference_never_moves(dyn):
    """A metric window holding only the run's last sample (duration = metric_start) is the whole run,
    with a note; a step after the run's end leaves its coordinate still: the note says its % is of an
    amplitude the run never reaches."""
    from hydrogen.simulation.checks import metric_window

    t = np.arange(5) * 0.5
    sel, start, note = metric_window(t, 2.0)
    assert sel.all() and start == 0.0 and "starts at the last simulated period" in note
    sel, start, note = metric_window(t, 1.5)
    assert sel.sum() == 2 and start == 1.5 and note is None
    res = hydrogen.simulate("z-step", "p", dyn=dyn, duration=0.5)  # its step is at 1 s
    assert "the reference of z does not move within the run" in res.metrics["metric_note"]
    moving = hydrogen.simulate("z-1hz", "p", dyn=dyn, duration=0.5)
    assert "metric_note" in moving.metrics and "does not move" not in moving.metrics["metric_note"]
