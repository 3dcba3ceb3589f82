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
    assert references.KINDS == ("sines", "step")
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
    runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.kf_gain, p.h)
    stages = runner.stages()
    n = dyn.model.n
    for t in (0.0, 0.3, 0.999, 1.0, 1.7):
        stages.signals.t = t
        stages.reference()
        got = np.ctypeslib.as_array(C.cast(stages.signals.qd, C.POINTER(C.c_double)), (4 * n,)).reshape(4, n)
        np.testing.assert_allclose(got, np.array(p.sc.reference(t)), rtol=1e-14, atol=1e-15)


def test_an_edited_reference_kind_makes_the_generated_code_stale(tmp_path, monkeypatch):
    """The reference kinds shape every robot's loop (its configuration, its C reference function): an
    edit of any of their modules changes the derivation hash the generated folders record."""
    import shutil
    from pathlib import Path

    from hydrogen.codegen import generate as G

    copy = tmp_path / "hydrogen"
    shutil.copytree(Path(G.__file__).resolve().parent.parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__", "_templates", "_generated"))
    monkeypatch.setattr(G, "_PACKAGE", copy)
    before = G.derivation_hash()
    for key in references.KINDS:
        path = copy / "references" / Path(references.kind(key).__file__).name
        text = path.read_text()
        path.write_text(text + "\n# edited\n")
        assert G.derivation_hash() != before, key
        path.write_text(text)
    assert G.derivation_hash() == before
