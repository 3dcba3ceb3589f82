"""Generated C: agrees with CasADi and SymPy, is deterministic, compiles warning-free, detects staleness."""
import filecmp
import os
import subprocess
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.cli import main as cli
from hydrogen.codegen import generate as gen
from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.runtime.build import repo_generated_dir
from hydrogen.symbolic.functions import derive_functions


def _random_input(name, shape, model, rng):
    n = shape[0] * shape[1]
    ps, d = model.supply_pressure, model.underlap
    if name == "q":
        x = model.neutral_pose + rng.uniform(-1, 1, 6) * [0.05, 0.05, 0.05, 0.15, 0.15, 0.15]
    elif name == "theta":
        x = np.array([250.0, 45, 45, 43]) * rng.uniform(0.7, 1.3, 4)
    elif name == "gamma":
        x = model.gamma * rng.uniform(0.7, 1.3, 2)
    elif name == "pc":
        x = rng.uniform(0.02, 0.98, n) * ps
    elif name == "u":
        x = rng.uniform(-4, 4, n) * d
    elif name == "l":
        x = rng.uniform(model.leg_min, model.leg_max, n)
    elif name == "ql_per_c":
        x = rng.uniform(-4, 4, n) * d * np.sqrt(ps)
    else:
        x = rng.normal(size=n)
    return np.asarray(x, float).reshape(shape, order="F")


@pytest.mark.parametrize("fname", [sf.name for sf in derive_functions(hydrogen.load_model())])
def test_compiled_equals_casadi_equals_sympy(fname, dyn, model, rng):
    sf = {f.name: f for f in derive_functions(model)}[fname]
    fun = to_casadi_function(sf)
    compiled = dyn.functions[fname]
    for _ in range(4):
        args = [_random_input(n, m.shape, model, rng) for n, m in sf.inputs]
        sub = {s: float(v) for (_, m), a in zip(sf.inputs, args) for s, v in zip(m.T, a.T.ravel())}
        out_c = compiled(*[a[:, 0] if a.shape[1] == 1 else a for a in args])
        out_ca = np.array(fun(*args)).squeeze()  # one output each: a DM
        out_sp = np.array(sf.outputs[0][1].evalf(subs=sub), dtype=float).squeeze()
        np.testing.assert_allclose(out_c, out_ca, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out_ca, out_sp, rtol=1e-9, atol=1e-9)


def test_generation_is_deterministic(tmp_path, model):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    gen.render(model, a)
    # a separate interpreter with another hash seed: no dict/set order may leak into the files
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    code = ("import hydrogen; from hydrogen.codegen.generate import render; "
            f"render(hydrogen.load_model(), {str(b)!r})")
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
    cmp = filecmp.dircmp(a, b)
    assert sorted(os.listdir(a)) == sorted(os.listdir(b))
    assert not cmp.diff_files and not cmp.left_only and not cmp.right_only
    for name in os.listdir(a):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_committed_generated_code_is_current(model):
    folder = repo_generated_dir() / model.name
    assert gen.check(model, folder) == []


def test_committed_generated_code_is_byte_identical_to_fresh(tmp_path, model):
    folder = repo_generated_dir() / model.name
    manifest = gen.read_manifest(folder)
    if manifest["casadi_version"] != ca.__version__ or manifest["sympy_version"] != sp.__version__:
        pytest.skip("committed code comes from other CasADi/SymPy versions")
    gen.render(model, tmp_path)
    for name in os.listdir(folder):
        assert (folder / name).read_bytes() == (tmp_path / name).read_bytes(), name


def test_generated_c_compiles_warning_free(tmp_path, model):
    folder = repo_generated_dir() / model.name
    for src in sorted(folder.glob("*.c")):
        proc = subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O1",
                               "-c", str(src), "-o", str(tmp_path / (src.stem + ".o"))],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def test_check_detects_edits_and_cli_reports_stale(tmp_path, model, capsys):
    out = tmp_path / "gen"
    assert gen.generate(model, out) is True
    assert gen.generate(model, out) is False  # unchanged model regenerates nothing
    assert cli(["generate", "--out", str(out), "--check"]) == 0
    victim = next(out.glob("*_regressor.c"))
    victim.write_text(victim.read_text() + "\n/* hand edit */\n")
    reasons = gen.check(model, out)
    assert any("edited" in r and victim.name in r for r in reasons)
    assert cli(["generate", "--out", str(out), "--check"]) == 1
    assert "stale" in capsys.readouterr().err
    assert gen.generate(model, out) is True
    assert gen.check(model, out) == []


def test_interrupted_generation_keeps_previous_files(tmp_path, model, monkeypatch):
    out = tmp_path / "gen"
    gen.generate(model, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken_render(model, folder, functions=None):
        (Path(folder) / "half_written.c").write_text("int x")
        raise KeyboardInterrupt

    monkeypatch.setattr(gen, "render", broken_render)
    with pytest.raises(KeyboardInterrupt):
        gen.generate(model, out, force=True)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".gen.new")]


def test_cli_prints_model_errors_without_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [")
    assert cli(["generate", "--model", str(bad), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "malformed TOML" in err and str(bad) in err and "Traceback" not in err
