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
    elif name == "x":  # plant state [q, qdot, pc, spool]
        x = np.concatenate([_random_input("q", (6, 1), model, rng).ravel(), rng.normal(size=6) * 0.1,
                            rng.uniform(0.02, 0.98, 6) * ps, rng.uniform(-4, 4, 6) * d])
    elif name == "xc":  # controller state: [q_hat,] z, theta_hat, gamma1_hat, gamma2_hat
        tail = np.concatenate([rng.normal(size=6) * 0.1, _random_input("theta", (4, 1), model, rng).ravel(),
                               model.gamma[0] * rng.uniform(0.7, 1.3, 6), model.gamma[1] * rng.uniform(0.7, 1.3, 6)])
        x = tail if n == 22 else np.concatenate([_random_input("q", (6, 1), model, rng).ravel(), tail])
    elif name in ("friction",):
        x = np.array([100.0, 300.0, 1e-3])
    elif name in ("tau_valve", "sat_width", "u_max"):
        x = rng.uniform(1e-3, 1e-2, n)
    elif name in ("Lambda", "Kp", "Kd", "Ktau", "Gtau_inv", "Ko", "Lambda2", "Lp", "Kd_obs", "Gz_inv",
                  "Gtheta_inv", "Ggamma1_inv", "Ggamma2_inv", "Kleg", "lambda_o"):
        x = rng.uniform(0.5, 2.0, n) * {"Kp": 1e4, "Kd": 1e3, "Gtau_inv": 1e4, "Lp": 1e5, "Kd_obs": 1e3,
                                        "Ggamma1_inv": 1e18, "Ggamma2_inv": 1e10, "Kleg": 0.05,
                                        "Gz_inv": 0.01, "lambda_o": 0.01}.get(name, 30.0)
    elif name in ("theta_min", "theta_max"):
        x = np.array([250.0, 45, 45, 43]) * (0.6 if name == "theta_min" else 1.4)
    elif name in ("gamma1_min", "gamma1_max", "gamma2_min", "gamma2_max"):
        g = model.gamma[0] if name.startswith("gamma1") else model.gamma[1]
        x = np.array([g * (0.5 if name.endswith("min") else 2.0)])
    elif name == "adapt":
        x = np.array([1.0])
    elif name == "Dbar_inv":
        x = np.diag(1 / np.array([250.0, 250, 250, 45, 45, 43]))
    elif name == "Gbar":
        x = np.array([0, 0, 250 * 9.81, 0, 0, 0])
    elif name in ("qd0", "q_hat"):
        x = _random_input("q", (6, 1), model, rng).ravel()
    elif name == "ql_per_c":
        x = rng.uniform(-4, 4, n) * d * np.sqrt(ps)
    else:
        x = rng.normal(size=n)
    return np.asarray(x, float).reshape(shape, order="F")


_DERIVED = {f.name: f for f in derive_functions(hydrogen.load_model())}


def _sympy_numeric(sf, values: dict) -> list:
    """Evaluate ``sf`` with SymPy's own numeric path (lambdify, math module), stage by stage."""
    values = dict(values)
    for symbols, expr in sf.intermediates:
        if isinstance(expr, tuple):  # ("inverse", M)
            M = np.array(_lam(values, expr[1]), float).reshape(expr[1].shape)
            val = np.linalg.inv(M)
        else:
            val = np.array(_lam(values, expr), float)
        values.update({s: float(v) for s, v in zip(symbols, val.ravel())})  # row-major, like Matrix
    return [np.array(_lam(values, e), float).reshape(e.shape) for _, e in sf.outputs]


def _lam(values, matrix):
    return sp.lambdify(list(values), list(matrix), "math")(*values.values())


@pytest.mark.parametrize("fname", list(_DERIVED))
def test_compiled_equals_casadi_equals_sympy(fname, dyn, model, rng):
    sf = _DERIVED[fname]
    fun = to_casadi_function(sf)
    compiled = dyn.functions[fname]
    for _ in range(3):
        args = [_random_input(n, m.shape, model, rng) for n, m in sf.inputs]
        sub = {s: float(v) for (_, m), a in zip(sf.inputs, args) for s, v in zip(m.T, a.T.ravel())}
        out_c = compiled(*[a[:, 0] if a.shape[1] == 1 else a for a in args])
        out_c = out_c if isinstance(out_c, tuple) else (out_c,)
        out_ca = fun(*args)
        out_ca = out_ca if isinstance(out_ca, tuple) else (out_ca,)
        out_sp = _sympy_numeric(sf, sub)
        for c_val, ca_val, sp_val in zip(out_c, out_ca, out_sp):
            ca_val = np.array(ca_val).squeeze()
            scale = max(1.0, np.abs(ca_val).max())
            np.testing.assert_allclose(c_val, ca_val, rtol=1e-12, atol=1e-12 * scale)
            np.testing.assert_allclose(ca_val, sp_val.squeeze(), rtol=1e-8, atol=1e-9 * scale)


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

    def broken_render(model, folder, functions=None, progress=False):
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
