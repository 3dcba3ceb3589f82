"""Generated C: agrees with CasADi and SymPy, is deterministic, compiles warning-free, detects staleness."""
import filecmp
import functools
import json
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
from hydrogen.controllers import CONTROLLERS
from hydrogen.runtime.build import repo_generated_dir
from hydrogen.symbolic.functions import derive_functions

from conftest import MODELS


def _random_input(name, shape, model, rng, fname=""):
    """A plausible value of a generated function's input, from the model (any robot)."""
    from hydrogen.controllers import CONTROLLERS, controller, function_name, rates_function_name
    from conftest import workspace_poses

    size = shape[0] * shape[1]
    n, m, p = model.n, model.n_cylinders, model.n_theta
    ps, d = model.supply_pressure, model.underlap
    from hydrogen.pressures import bounds as pressure_bounds
    p_lo, p_hi = pressure_bounds(model)
    if name in ("q", "qd0", "q_hat"):
        x = workspace_poses(model, 1, rng)[0]
    elif name == "theta":
        x = model.theta * rng.uniform(0.7, 1.3, p)
    elif name in ("gamma1", "gamma2"):
        x = model.gamma[0 if name == "gamma1" else 1] * rng.uniform(0.7, 1.3, m)
    elif name == "pc":  # chamber pressures inside each state's bounds
        x = p_lo + (p_hi - p_lo) * rng.uniform(0.02, 0.98, p_lo.size)
    elif name in ("u", "u_applied"):
        x = rng.uniform(-4, 4, m) * d
    elif name == "l":
        x = rng.uniform(model.leg_min, model.leg_max)
    elif name == "x":  # plant state, from the plant's layout ([q, qdot, pc, spool, spool rate] and a supply's p_s)
        from hydrogen.plant import plant_layout
        parts = {"q": lambda k: workspace_poses(model, 1, rng)[0], "qdot": lambda k: rng.normal(size=k) * 0.1,
                 "pc": lambda k: p_lo + (p_hi - p_lo) * rng.uniform(0.02, 0.98, k),
                 "spool": lambda k: rng.uniform(-4, 4, k) * np.resize(d, k),
                 "spool_rate": lambda k: rng.normal(size=k) * 0.01,
                 "ps": lambda k: np.resize(ps, k) * rng.uniform(0.7, 1.0, k)}
        x = np.concatenate([parts[sl.name](sl.size) for sl in plant_layout(model)])
    elif name == "ps":  # a measured supply pressure, below and near its nominal value
        x = np.resize(ps, size) * rng.uniform(0.7, 1.0, size)
    elif name == "xc":  # controller state, from the controller's layout
        kind = next(k for k in CONTROLLERS if fname in (function_name(k), rates_function_name(k)))
        parts = {"z": lambda k: rng.normal(size=k) * 0.1,
                 "q_hat": lambda k: workspace_poses(model, 1, rng)[0],
                 "theta_hat": lambda k: model.theta * rng.uniform(0.7, 1.3, k),
                 "gamma1_hat": lambda k: model.gamma[0] * rng.uniform(0.7, 1.3, k),
                 "gamma2_hat": lambda k: model.gamma[1] * rng.uniform(0.7, 1.3, k),
                 # composite adaptation: filters, copies of the previous period, least-squares gains
                 "force_filter": lambda k: rng.normal(size=k) * 1e4,
                 "log_chamber_filter": lambda k: rng.uniform(-1.0, 0.0, k),
                 "g0_filter": lambda k: rng.normal(size=k) * 0.1,
                 "pc_prev": lambda k: p_lo + (p_hi - p_lo) * rng.uniform(0.02, 0.98, k),
                 "legl_prev": lambda k: rng.uniform(model.leg_min, model.leg_max),
                 "gamma_gain": lambda k: np.tile([1.0, 0.1, 0.5], k // 3),
                 "theta_gain": lambda k: np.concatenate([[1.0 if j == i else 0.01 for j in range(i, p)]
                                                        for i in range(p)])}
        # friction compensation: estimates inside and past their bounds (the projection's both branches)
        parts.update(coulomb_hat=lambda k: rng.uniform(0.0, 1500.0, k), viscous_hat=lambda k: rng.uniform(0.0, 1500.0, k))
        for b in ("momentum_filter", "momentum_offset_filter", "bias_filter", "bias_offset_filter", "torque_filter"):
            parts[b] = lambda k: rng.normal(size=k) * 1e3
        x = np.concatenate([parts[b](k) for b, k in controller(kind).state_layout(model)])
    elif name in ("friction",):  # per actuator: [F_c, b, v_s] and, with seal friction, its three terms
        from hydrogen.plant.friction import parameters_of
        row = {"coulomb": 100.0, "viscous": 300.0, "smooth_speed": 1e-3, "breakaway": 130.0, "stribeck_speed": 0.01,
               "pressure_coefficient": 2e-3}
        width = len(parameters_of(model.seal_friction))
        x = np.tile([row[q.name] for q in parameters_of(model.seal_friction)], size // width)
    elif name in ("friction_coulomb", "friction_viscous", "friction_coulomb_max", "friction_viscous_max"):
        x = rng.uniform(100.0, 1000.0, size)
    elif name == "friction_speed":  # the smooth sign's slope, not only its saturation, at q̇ ~ 0.1
        x = rng.uniform(0.05, 0.2, size)
    elif name == "rate_friction":
        x = rng.uniform(0.1, 1.0, size)
    elif name == "valve":  # per actuator [lag s, natural frequency rad/s, damping, overlap m, full opening m]:
        # second-order valves; a datasheet valve's overlap and opening read only where generated
        from hydrogen.plant.valve import WIDTH
        x = np.concatenate([[0.0, 2 * np.pi * rng.uniform(30, 100), rng.uniform(0.5, 1.0), 1e-5, 1e-3][:WIDTH]
                            for _ in range(size // WIDTH)])
    elif name in ("sat_width", "u_max"):
        x = rng.uniform(1e-3, 1e-2, size)
    elif name in ("Lambda", "Kp", "Kd", "Ktau", "Gtau_inv", "Ko", "Lambda2", "Lp", "Kd_obs", "Gz_inv",
                  "Gtheta_inv", "Ggamma1_inv", "Ggamma2_inv", "Kleg", "lambda_o"):
        x = rng.uniform(0.5, 2.0, size) * {"Kp": 1e4, "Kd": 1e3, "Gtau_inv": 1e4, "Lp": 1e5, "Kd_obs": 1e3,
                                           "Ggamma1_inv": 1e18, "Ggamma2_inv": 1e10, "Kleg": 0.05,
                                           "Gz_inv": 0.01, "lambda_o": 0.01}.get(name, 30.0)
    elif name in ("gamma_ref", "theta_ref", "theta_row_scale"):
        x = {"gamma_ref": np.concatenate(list(model.gamma)), "theta_ref": np.abs(model.theta),
             "theta_row_scale": np.ones(n) * 100.0}[name] * rng.uniform(0.5, 2.0, size)
    elif name in ("lambda_f_gamma", "lambda_f_theta", "rate_ls_gamma", "rate_ls_theta", "P0_gamma", "P0_theta",
                  "ls_floor", "ls_nu_gamma", "ls_nu_theta", "period"):
        x = rng.uniform(0.5, 2.0, size) * {"ls_floor": 1e-4, "ls_nu_gamma": 1e-3, "ls_nu_theta": 1e-3,
                                           "period": 1e-3, "P0_gamma": 1.0, "P0_theta": 1.0}.get(name, 30.0)
    elif name in ("theta_min", "theta_max"):
        lo, hi = np.minimum(model.theta * 0.6, model.theta * 1.4), np.maximum(model.theta * 0.6, model.theta * 1.4)
        x = lo if name == "theta_min" else hi
    elif name in ("gamma1_min", "gamma1_max", "gamma2_min", "gamma2_max"):
        g = model.gamma[0 if name.startswith("gamma1") else 1].mean()
        x = np.array([g * (0.5 if name.endswith("min") else 2.0)])
    elif name == "adapt":
        x = np.array([1.0])
    elif name == "g0":  # the valve inverse's target: every branch of the orifice law (q_l/c = g0 (l - L) ~ ±4 d √ps)
        x = rng.uniform(-4, 4, m) * d * np.sqrt(ps)
    else:
        x = rng.normal(size=size)
    return np.asarray(x, float).reshape(shape, order="F")


#: A case's model name with this suffix: the shipped robot generated with friction compensation
#: (``[control] friction_compensation``), whose controllers differ from the committed ones.
FRICTION = "+friction"
#: The controllers generated differently with friction compensation, checked on this robot.
FRICTION_CASES = [("loader_crane" + FRICTION, f) for f in (
    "ctrl_backstepping", "ctrl_adaptive_robust", "ctrl_adaptive_robust_rates", "ctrl_adaptive_observer",
    "ctrl_adaptive_observer_rates")]


@functools.lru_cache(maxsize=None)
def _model(mname):
    """A shipped robot by name, or with :data:`FRICTION` appended, with friction compensation."""
    import dataclasses
    base = hydrogen.load_model(mname.removesuffix(FRICTION))
    return dataclasses.replace(base, friction_compensation=True) if mname.endswith(FRICTION) else base


@functools.lru_cache(maxsize=None)
def _derived(mname) -> dict:
    """The model's derived functions by name, derived on first use (not at collection)."""
    return {f.name: f for f in derive_functions(_model(mname))}


def _composed_names() -> set:
    """Functions that code generation composes from derived ones (steps, lean variants): tested below."""
    from hydrogen.controllers import CONTROLLERS, LEAN, function_name, rates_function_name, step_function_name

    return {step_function_name(k) for k in CONTROLLERS} | {
        f(k, LEAN) for k in CONTROLLERS for f in (function_name, rates_function_name, step_function_name)}


def _symbolic_cases() -> list:
    """(model, function) for each derived SymPy function, named by the committed manifests (cheap to
    read); test_every_derived_function_is_compared checks the list against the derivation."""
    composed = _composed_names()
    return [(name, e["name"]) for name in MODELS
            for e in gen.read_manifest(repo_generated_dir() / name)["functions"] if e["name"] not in composed]


_CASES = _symbolic_cases()


def _sympy_numeric(sf, states: list) -> list:
    """Evaluate ``sf`` at each state (a dict symbol -> value) with SymPy's own arithmetic, stage by
    stage: each stage's expressions with the state's numbers substituted as SymPy Floats (53-bit,
    as a double) evaluate to Floats. The outputs per state. (Substituting is several times faster
    than printing the expressions for lambdify, which took most of the test's time.)"""
    out = []
    for state in states:
        v = {s: sp.Float(x) for s, x in state.items()}

        def num(matrix):
            return np.array(matrix.xreplace(v), float)

        for symbols, expr in sf.intermediates:
            if isinstance(expr, tuple) and expr[0] == "inverse":
                val = np.linalg.inv(num(expr[1]).reshape(expr[1].shape))
            elif isinstance(expr, tuple):  # ("solve", A, b)
                val = np.linalg.solve(num(expr[1]).reshape(expr[1].shape), num(expr[2]).ravel())
            else:
                val = num(expr)
            v.update({s: sp.Float(float(x)) for s, x in zip(symbols, val.ravel())})  # row-major, like Matrix
        out.append([num(e).reshape(e.shape) for _, e in sf.outputs])
    return out


#: SymPy evaluates a controller's expressions (thousands of operations) in seconds per state: it is
#: compared at the first of the states CasADi and the compiled code are compared at; others at all.
SYMPY_STATES_OF_A_CONTROLLER = 1


def test_every_derived_function_is_compared(robot_model):
    derived = {n for n, f in _derived(robot_model.name).items() if hasattr(f, "inputs")}
    assert derived == {f for m, f in _CASES if m == robot_model.name}


@pytest.mark.parametrize("mname,fname", _CASES + FRICTION_CASES)
def test_compiled_equals_casadi_equals_sympy(mname, fname, cache, rng):
    model = _model(mname)
    dyn = hydrogen.build(model, cache=cache, controllers=["backstepping", "adaptive-robust", "adaptive-observer"]
                         if mname.endswith(FRICTION) else None)
    sf = _derived(mname)[fname]
    fun = to_casadi_function(sf)
    compiled = dyn.functions[fname]
    states, outs_ca = [], []
    for _ in range(3):
        args = [_random_input(n, m.shape, model, rng, fname) for n, m in sf.inputs]
        states.append({s: float(v) for (_, m), a in zip(sf.inputs, args) for s, v in zip(m.T, a.T.ravel())})
        out_c = compiled(*[a[:, 0] if a.shape[1] == 1 else a for a in args])
        out_c = out_c if isinstance(out_c, tuple) else (out_c,)
        out_ca = fun(*args)
        out_ca = [np.array(v).squeeze() for v in (out_ca if isinstance(out_ca, tuple) else (out_ca,))]
        for c_val, ca_val in zip(out_c, out_ca):
            scale = max(1.0, np.abs(ca_val).max())
            np.testing.assert_allclose(c_val, ca_val, rtol=1e-12, atol=1e-12 * scale)
        outs_ca.append(out_ca)
    # SymPy's own evaluation at the same states (a controller's at the first only: see above)
    if fname.startswith("ctrl_"):
        states = states[:SYMPY_STATES_OF_A_CONTROLLER]
    outs_sp = _sympy_numeric(sf, states)
    assert len(outs_sp) == len(states) >= 1
    for out_ca, out_sp in zip(outs_ca, outs_sp):
        assert len(out_sp) == len(out_ca)
        for ca_val, sp_val in zip(out_ca, out_sp):
            scale = max(1.0, np.abs(ca_val).max())
            np.testing.assert_allclose(ca_val, sp_val.squeeze(), rtol=1e-8, atol=1e-9 * scale)


@pytest.fixture(scope="session")
def fresh_render(tmp_path_factory):
    """``fresh_render(model)``: a folder with the model's C rendered afresh in this process, once per
    run and model (the tests only read it)."""
    folders = {}

    def get(model):
        if model.name not in folders:
            folder = tmp_path_factory.mktemp(f"fresh-{model.name}")
            gen.render(model, folder)
            folders[model.name] = folder
        return folders[model.name]
    return get


def test_generation_is_deterministic(tmp_path, model, fresh_render):
    a, b = fresh_render(model), tmp_path / "b"
    b.mkdir()
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


def test_committed_generated_code_is_current(robot_model):
    folder = repo_generated_dir() / robot_model.name
    assert gen.check(robot_model, folder) == []


def test_committed_generated_code_is_byte_identical_to_fresh(robot_model, fresh_render):
    model = robot_model
    folder = repo_generated_dir() / model.name
    manifest = gen.read_manifest(folder)
    if manifest["casadi_version"] != ca.__version__ or manifest["sympy_version"] != sp.__version__:
        pytest.skip("committed code comes from other CasADi/SymPy versions")
    fresh = fresh_render(model)
    for name in os.listdir(folder):
        assert (folder / name).read_bytes() == (fresh / name).read_bytes(), name


def test_generated_c_compiles_warning_free(robot_model, cache):
    """Every committed .c compiles warning-free: each is compiled, with -Wall -Wextra -Werror, into one
    of the model's libraries (built here or by the run's other tests, in the run's cache: no file is
    compiled twice for the check), and each passes the compiler's -pedantic checks of C99 (the front
    end's: -fsyntax-only, no code generated)."""
    import json

    from hydrogen.runtime.compiler import Toolchain
    from hydrogen.runtime.library import group_sources

    folder = repo_generated_dir() / robot_model.name
    sources = sorted(folder.glob("*.c"), key=lambda p: p.name)
    dyn = hydrogen.build(robot_model, cache=cache)
    assert dyn.library.generated_dir.resolve() == folder.resolve()  # the committed files, not a cache copy
    compiled = set()
    for group in dyn.library.groups():
        info = json.loads((dyn.library.load(group).parent / "build.json").read_text())
        assert {"-Wall", "-Wextra", "-Werror", "-std=c99"} <= set(info["argv"]), (group, info["argv"])
        assert info["sources"] == group_sources(dyn.library.manifest, group)
        compiled |= set(info["sources"])
    assert compiled == {p.name for p in sources}
    proc = subprocess.run([Toolchain().executable(), "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                           "-fsyntax-only", *map(str, sources)], capture_output=True, text=True)
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

    def broken_render(model, folder, functions=None, progress=False, numbers="constants", controllers=None,
                      written=None, first=None):
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


def test_check_compares_output_not_source_text(tmp_path, model, monkeypatch):
    """A derivation edit that changes nothing generated (a comment) leaves ``generate --check`` one
    reason, the recorded hash (a build would generate the folder again), naming no file; an edited
    file is named."""
    out = tmp_path / "gen"
    gen.generate(model, out)
    monkeypatch.setattr(gen, "derivation_hash", lambda kinds=(): "0" * 64)  # as after a comment edit
    assert gen.check(model, out) and all("derivation_hash" in r for r in gen.check(model, out))
    (reason,) = gen.check_output(model, out)
    assert "output is what a fresh generation writes" in reason and "hydrogen generate --model" in reason
    victim = next(out.glob("*_gravity.c"))
    victim.write_text(victim.read_text() + "\n/* hand edit */\n")
    assert any(victim.name in r for r in gen.check_output(model, out))


def _stateful():
    from hydrogen.controllers import controller

    return [(name, kind) for name in MODELS for kind in hydrogen.load_model(name).controllers
            if controller(kind).state_layout(hydrogen.load_model(name))]


_STATEFUL = _stateful()


@pytest.mark.parametrize("mname,kind", _STATEFUL)
def test_rates_function_equals_the_controllers_xc_dot(mname, kind, cache, rng):
    """The rates-only function (the loop's state update) takes the controller's inputs and gives
    exactly its xc_dot output, at random inputs; and it is generated smaller (no τ̇_d, no valve inverse)."""
    from hydrogen.controllers import function_name, rates_function_name

    model = hydrogen.load_model(mname)
    dyn = hydrogen.build(model, cache=cache)
    ctrl, rates = dyn.functions[function_name(kind)], dyn.functions[rates_function_name(kind)]
    entries = {e["name"]: e for e in dyn.library.manifest["functions"]}
    assert entries[rates.name]["inputs"] == entries[ctrl.name]["inputs"]
    assert [o[0] for o in entries[rates.name]["outputs"]] == ["xc_dot"]
    assert entries[rates.name]["instructions"] < entries[ctrl.name]["instructions"]
    sf = _derived(mname)[ctrl.name]
    k = ctrl.out_names.index("xc_dot")
    for _ in range(5):
        args = [_random_input(n, m.shape, model, rng, ctrl.name) for n, m in sf.inputs]
        args = [a[:, 0] if a.shape[1] == 1 else a for a in args]
        want = ctrl(*args)[k]
        np.testing.assert_allclose(rates(*args), want, rtol=1e-13, atol=1e-13 * np.abs(want).max())


@pytest.mark.parametrize("mname,kind", _STATEFUL)
def test_gamma2_law_uses_the_applied_spool(mname, kind, cache, rng):
    """γ̂̇2 = κ Γ_γ2⁻¹ Γ_τ f̃ g0(u_applied), g0 = q_l/(c (l − L)) at the input u_applied (compiled valve
    law, numpy), not at this call's command u (the paper's law: composite rates 0); u_applied moves
    γ̂̇2 (and the composite filter of g0) only, never u."""
    from hydrogen.controllers import controller, function_name
    from hydrogen.controllers.common import initial_gain_matrix

    model = hydrogen.load_model(mname)
    dyn = hydrogen.build(model, cache=cache)
    ctrl = dyn.functions[function_name(kind)]
    sf = _derived(mname)[ctrl.name]
    names = [n for n, _ in sf.inputs]
    blocks, i = {}, 0
    for b, size in controller(kind).state_layout(model):
        blocks[b] = slice(i, i + size)
        i += size
    from controller_inputs import kind_laws
    for _ in range(3):
        args = [_random_input(n, m.shape, model, rng, ctrl.name) for n, m in sf.inputs]
        v = {n: (a[:, 0] if a.shape[1] == 1 else a) for n, a in zip(names, args)}
        v.update(gamma2_min=np.array([1e-3]), gamma2_max=np.array([1e12]))  # the projection inactive
        # the paper's law: no composite term (its rate 0 keeps the gain at P0 I, so set it there)
        v.update(rate_ls_gamma=np.array([0.0]), rate_ls_theta=np.array([0.0]))
        v["xc"] = v["xc"].copy()
        v["xc"][blocks["gamma_gain"]] = initial_gain_matrix(2, model.n_cylinders, float(v["P0_gamma"][0]))
        out = dict(zip(ctrl.out_names, ctrl(*[v[n] for n in names])))
        l = np.asarray(dyn.leg_lengths(v["q"])).ravel()
        f, _, g0 = kind_laws(model, l, np.zeros_like(l), v["pc"], v["u_applied"], v.get("ps"))
        want = v["adapt"][0] * v["Ggamma2_inv"] / v["Gtau_inv"] * (f - out["f_d"]) * g0
        got = out["xc_dot"][blocks["gamma2_hat"]]
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())
        assert not np.allclose(v["u_applied"], out["u"])  # the test tells the two apart
        other = dict(v, u_applied=-v["u_applied"])
        out2 = dict(zip(ctrl.out_names, ctrl(*[other[n] for n in names])))
        np.testing.assert_array_equal(out2["u"], out["u"])
        changed = np.flatnonzero(out2["xc_dot"] != out["xc_dot"])
        # γ̂2 and the composite filter of g0 at the held spool (a state rate, not an estimate's)
        allowed = {i for b in ("gamma2_hat", "g0_filter") for i in range(*blocks[b].indices(len(out["xc_dot"])))}
        assert set(changed) <= allowed and set(changed) & set(range(*blocks["gamma2_hat"].indices(len(out["xc_dot"]))))


@pytest.mark.parametrize("mname,kind", _STATEFUL)
def test_semi_implicit_step_is_the_clipped_rate_update_then_the_command(mname, kind, cache, rng):
    """One call of the step equals the two calls it replaces: xc⁺ = clip(xc + h F(y, xc, u_applied)) with
    the rates function and numpy's clip, then u = U(y, xc⁺) with the controller; some entries of xc⁺
    on each bound."""
    from hydrogen.controllers import function_name, rates_function_name, step_function_name

    model = hydrogen.load_model(mname)
    dyn = hydrogen.build(model, cache=cache)
    ctrl, rates = dyn.functions[function_name(kind)], dyn.functions[rates_function_name(kind)]
    step = dyn.functions[step_function_name(kind)]
    assert step.in_names == ctrl.in_names + ["h", "xc_lo", "xc_hi"] and step.out_names == ["u", "xc_next"]
    sf = _derived(mname)[ctrl.name]
    ix = ctrl.in_names.index("xc")
    for _ in range(5):
        args = [_random_input(n, m.shape, model, rng, ctrl.name) for n, m in sf.inputs]
        args = [a[:, 0] if a.shape[1] == 1 else a for a in args]
        h = rng.uniform(1e-4, 2e-3)
        moved = args[ix] + h * rates(*args)
        lo, hi = args[ix] - 1e-3 * np.abs(args[ix]), args[ix] + 1e-3 * np.abs(args[ix])
        lo[::3], hi[1::3] = -1e300, 1e300
        want_xc = np.clip(moved, lo, hi)
        assert np.any(want_xc == lo) or np.any(want_xc == hi)
        want_u = ctrl(*args[:ix], want_xc, *args[ix + 1:])[0]
        u, xc = step(*args, np.array([h]), lo, hi)
        np.testing.assert_array_equal(xc, want_xc)
        np.testing.assert_allclose(u, want_u, rtol=1e-13, atol=1e-13 * np.abs(want_u).max())


def test_render_refuses_functions_derived_for_the_other_numbers_mode(tmp_path, model):
    """Functions handed to render must be what derive gives for its numbers mode: folded functions
    rendered as "inputs" (or parametric ones without their names) would write a manifest that claims
    inputs the C does not take."""
    with pytest.raises(ValueError, match="come with the names"):
        gen.render(model, tmp_path, functions=[], numbers="inputs")
    with pytest.raises(ValueError, match="come with no names"):
        gen.render(model, tmp_path, functions=[], numbers="constants", names=["a"])
    assert not list(tmp_path.iterdir())


def test_a_folder_grown_controller_by_controller_is_a_whole_generation(tmp_path, fresh_render):
    """Generated for one controller, then for all: only the missing controllers are derived, and the
    folder is byte for byte the whole generation (the manifest's functions in the same order)."""
    model = hydrogen.load_model("loader_crane")
    folder = tmp_path / "grown"
    assert gen.generate(model, folder, controllers=("adaptive-robust",))
    manifest = gen.read_manifest(folder)
    assert gen.held_controllers(manifest) == ("adaptive-robust",)
    assert gen.check(model, folder) == []  # current for what it holds
    assert "adaptive-observer" in gen.check_output(model, folder)[0]  # but not a whole generation
    derived = []
    real = gen.derive
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(gen, "derive", lambda *a, **k: (derived.append((tuple(a[2]), k["core"])), real(*a, **k))[1])
        assert not gen.generate(model, folder, controllers=("adaptive-robust",))  # holds it: nothing done
        assert gen.generate(model, folder)
    assert derived == [(tuple(c for c in model.controllers if c != "adaptive-robust"), False)]  # those alone
    fresh = fresh_render(model)
    assert sorted(os.listdir(folder)) == sorted(os.listdir(fresh))
    for name in os.listdir(fresh):
        assert (folder / name).read_bytes() == (fresh / name).read_bytes(), name
    assert gen.check_output(model, folder) == []


def test_controllers_reading_a_number_the_folder_lacks_regenerate_it_whole(tmp_path, monkeypatch):
    model = hydrogen.load_model("loader_crane")
    folder = tmp_path / "grown"
    gen.generate(model, folder, controllers=("p",))
    monkeypatch.setattr(gen, "extend", lambda *a, **k: False)  # as when a new number was met
    rendered = []
    real = gen.render
    monkeypatch.setattr(gen, "render", lambda *a, **k: (rendered.append(k["controllers"]), real(*a, **k))[1])
    assert gen.generate(model, folder, controllers=("p-task",))
    assert rendered == [("p", "p-task")] and gen.held_controllers(gen.read_manifest(folder)) == ("p", "p-task")


def test_a_controller_module_shapes_its_own_functions_alone(package_copy):
    """The folder's derivation hash leaves out the controllers' modules (each function records its
    controller's): editing or adding a controller stales no other function."""
    copy = package_copy
    kinds = ("three_way_cylinder",)
    before, own = gen.derivation_hash(kinds), gen.block_hash("controller", "p")
    other = gen.block_hash("controller", "backstepping")
    path = copy / "controllers" / "p.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    assert gen.derivation_hash(kinds) == before
    assert gen.block_hash("controller", "p") != own
    assert gen.block_hash("controller", "backstepping") == other
    (copy / "controllers" / "helper_not_registered.py").write_text("# shared by controllers\n")
    assert gen.derivation_hash(kinds) != before  # a shared module of the blocks counts for all


def test_an_edited_controller_is_derived_again_alone(tmp_path, monkeypatch, fresh_render, package_copy):
    """A folder whose one controller's module changed is stale for that controller only; generating
    derives it alone and writes what a whole generation writes."""
    model = hydrogen.load_model("loader_crane")
    folder = tmp_path / "gen"
    assert gen.generate(model, folder)
    path = package_copy / "controllers" / "p.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    reasons = gen.check(model, folder)
    assert len(reasons) == 1 and gen.STALE_CONTROLLER in reasons[0] and "'p'" in reasons[0]
    untouched = {p.name: p.stat().st_mtime_ns for p in folder.iterdir() if "_ctrl_p" not in p.name}
    fresh = fresh_render(model)  # a whole generation, before derive is watched
    derived = []
    real = gen.derive
    monkeypatch.setattr(gen, "derive", lambda *a, **k: (derived.append((tuple(a[2]), k["core"])), real(*a, **k))[1])
    assert gen.generate(model, folder)
    assert derived == [(("p",), False)]
    assert gen.check(model, folder) == []
    assert sorted(os.listdir(folder)) == sorted(os.listdir(fresh))
    for name in os.listdir(fresh):
        if name != gen.MANIFEST:
            assert (folder / name).read_bytes() == (fresh / name).read_bytes(), name
    assert gen.check_output(model, folder) == []
    assert untouched  # the core's files were copied, not written again
    for name, mtime in untouched.items():
        if name != gen.MANIFEST:
            assert (folder / name).stat().st_mtime_ns == mtime, name


def _without_code_hashes(folder):
    """A generated folder's manifest without the hashes of the code it was generated by."""
    manifest = json.loads((folder / gen.MANIFEST).read_text())
    for key in ("derivation_hash", "drivers_hash"):
        manifest.pop(key)
    for e in manifest["functions"]:
        e.pop("block_hash", None)
    return manifest


def _regenerated(model, folder, monkeypatch, fresh, numbers="inputs", whole=None):
    """Generate ``folder`` again, watching what is derived: ``(the derive calls as (controllers, core),
    the files written again)``; the folder then reads byte for byte as ``fresh``, a whole generation."""
    before = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    derived = []
    real = gen.derive

    def watched(model, numbers, controllers=None, **k):
        derived.append((tuple(model.controllers if controllers is None else controllers), k.get("core", True)))
        return real(model, numbers, controllers, **k)
    monkeypatch.setattr(gen, "derive", watched)
    assert gen.generate(model, folder, numbers=numbers, whole=whole)
    monkeypatch.setattr(gen, "derive", real)
    assert gen.check(model, folder) == []
    assert sorted(os.listdir(folder)) == sorted(os.listdir(fresh))
    for name in os.listdir(fresh):
        if name != gen.MANIFEST:
            assert (folder / name).read_bytes() == (fresh / name).read_bytes(), name
    assert _without_code_hashes(folder) == _without_code_hashes(fresh)  # those are held by check() above
    assert gen.check_output(model, folder) == []
    return derived, sorted(name for name, t in before.items() if (folder / name).stat().st_mtime_ns != t)


@pytest.fixture(scope="session")
def pump_arm(tmp_path_factory):
    """The four-way arm with a pump (its plant meets the supply's numbers first) and one controller:
    a whole generation in about a second."""
    from test_supply import PUMP_TABLE

    text = (Path(__file__).parent / "data" / "four_way_arm.toml").read_text()
    path = tmp_path_factory.mktemp("pump-arm") / "pump_arm.toml"
    path.write_text(text.replace('name = "four_way_arm"', 'name = "pump_arm"\ncontrollers = ["p"]', 1) + PUMP_TABLE)
    return hydrogen.load_model(path)


def test_an_edited_plant_block_derives_the_plant_alone(tmp_path, monkeypatch, fresh_render, package_copy, pump_arm):
    """A folder whose plant's blocks changed is stale for the plant's function and the loop drivers
    only; generating derives the plant alone (it meets the numbers it met before, the pump's among
    them) and writes what a whole generation writes."""
    model = pump_arm
    folder = tmp_path / "gen"
    assert gen.generate(model, folder)
    span = json.loads((folder / gen.MANIFEST).read_text())[gen.NUMBERS_MET]
    assert span[1] > span[0]  # the plant meets numbers no function before it met (the supply's)
    path = package_copy / "plant" / "friction.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    assert gen.stale_parts(model, folder) == {"plant": True, "drivers": True}
    assert any(gen.STALE_PLANT in r for r in gen.check(model, folder))
    derived, written = _regenerated(model, folder, monkeypatch, fresh_render(model))
    assert derived == [((), ("plant",))]
    assert written == sorted([gen.MANIFEST, *(f"{model.name}{s}" for _, s in gen.DRIVERS),
                              f"{model.name}_plant_rhs.c", f"{model.name}_plant_rhs.h"])


def test_an_edit_of_what_renders_the_loop_drivers_derives_nothing(tmp_path, monkeypatch, fresh_render,
                                                                  package_copy, pump_arm):
    """An edit of a reference kind (what the drivers alone are rendered from) leaves every function
    current: generating renders the drivers again and derives nothing."""
    model = pump_arm
    folder = tmp_path / "gen"
    assert gen.generate(model, folder)
    path = package_copy / "references" / "step.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    assert gen.stale_parts(model, folder) == {"drivers": True}
    derived, written = _regenerated(model, folder, monkeypatch, fresh_render(model))
    assert derived == []
    assert written == sorted([gen.MANIFEST, *(f"{model.name}{s}" for _, s in gen.DRIVERS)])


def test_a_plant_meeting_other_numbers_first_is_generated_whole(tmp_path, monkeypatch, fresh_render,
                                                                package_copy, pump_arm):
    """Where the plant derived again alone meets other numbers first than the folder recorded, only a
    whole generation gives the numbers' order one would write: the folder is generated whole."""
    model = pump_arm
    folder = tmp_path / "gen"
    assert gen.generate(model, folder)
    manifest = json.loads((folder / gen.MANIFEST).read_text())
    manifest[gen.NUMBERS_MET] = [manifest[gen.NUMBERS_MET][0], manifest[gen.NUMBERS_MET][1] - 1]
    (folder / gen.MANIFEST).write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    friction = package_copy / "plant" / "friction.py"
    friction.write_text(friction.read_text() + "\n# an edit\n")
    told = []
    derived, _ = _regenerated(model, folder, monkeypatch, fresh_render(model), whole=lambda: told.append(1))
    # tried alone, then the core and the controllers; the caller told (a build's progress says so)
    assert derived == [((), ("plant",)), ((), True), (tuple(model.controllers), False)] and told == [1]


def test_a_folder_of_another_casadi_is_generated_whole(tmp_path, monkeypatch, fresh_render, package_copy,
                                                       pump_arm):
    """Functions written now would not join a folder another CasADi wrote (each file carries its
    version, which the runtime holds to the manifest's): a plant edit there generates it whole."""
    model = pump_arm
    folder = tmp_path / "gen"
    assert gen.generate(model, folder)
    manifest = json.loads((folder / gen.MANIFEST).read_text())
    manifest["casadi_version"] = "3.8.0"  # a folder of another patch release: current for check()
    (folder / gen.MANIFEST).write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    assert gen.check(model, folder) == []
    friction = package_copy / "plant" / "friction.py"
    friction.write_text(friction.read_text() + "\n# an edit\n")
    assert gen.stale_parts(model, folder) is None
    derived, _ = _regenerated(model, folder, monkeypatch, fresh_render(model))
    assert derived == [((), True), (tuple(model.controllers), False)]


def test_a_change_of_what_the_drivers_read_of_the_model_renders_them_again(tmp_path, monkeypatch, pump_arm):
    """With the numbers folded, the model's hash covers what the functions bake in, not what the
    drivers read of the model (its sensors): the recorded summary does, and the drivers follow it."""
    from dataclasses import replace

    folder, whole = tmp_path / "gen", tmp_path / "whole"
    assert gen.generate(pump_arm, folder, numbers="constants")
    encoders = replace(pump_arm, joint_encoders=not pump_arm.joint_encoders)
    assert gen.stale_parts(encoders, folder) == {"drivers": True}
    assert gen.generate(encoders, whole, numbers="constants")
    derived, written = _regenerated(encoders, folder, monkeypatch, whole, "constants")
    assert derived == [] and written == sorted([gen.MANIFEST, *(f"{encoders.name}{s}" for _, s in gen.DRIVERS)])


def test_the_plant_modules_the_derivation_imports_shape_every_function(package_copy):
    """The supply's module names the supply pressure the controllers and the hydraulics take: an edit
    of it, or of a plant module it imports, changes the functions' derivation hash; an edit of a block
    only the plant reads does not."""
    before = gen.derivation_hash()
    for name, shared in (("friction.py", False), ("supply.py", True)):
        path = package_copy / "plant" / name
        text = path.read_text()
        path.write_text(text + "\n# an edit\n")
        assert (gen.derivation_hash() != before) == shared, name
        path.write_text(text)
    supply = package_copy / "plant" / "supply.py"
    supply.write_text(supply.read_text() + "\n\ndef _helper():\n    from .helper import x\n    return x\n")
    (package_copy / "plant" / "helper.py").write_text("x = 1\n")
    assert "plant/helper.py" in gen._plant_imports()
    before = gen.derivation_hash()
    (package_copy / "plant" / "helper.py").write_text("x = 2\n")
    assert gen.derivation_hash() != before


def test_the_import_scan_finds_every_import_the_parser_finds():
    """The hashes' import scan (a regular expression, fast enough for every build's check) finds every
    module of the package each of its modules imports by a relative import, as Python's own parser
    reads them: function-local, parenthesised over lines, with comments between."""
    import ast

    def parsed(rel, source):
        here, found = rel.split("/")[:-1], set()
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.ImportFrom) and node.level and node.level - 1 <= len(here):
                parts = here[:len(here) - (node.level - 1)] + (node.module.split(".") if node.module else [])
                found |= {"/".join(parts) + ".py"} if parts else set()
                found |= {"/".join(parts + [a.name]) + ".py" for a in node.names}
        return found

    modules = [str(p.relative_to(gen._PACKAGE)) for p in gen._PACKAGE.rglob("*.py")]
    assert len(modules) > 50
    for rel in modules:
        source = (gen._PACKAGE / rel).read_bytes()
        missing = parsed(rel, source) - gen._imports_of(rel, source)
        assert not missing, (rel, sorted(missing))


def test_the_derivation_code_imports_the_package_relatively():
    """The plant's modules the derivation imports are found by its relative imports and absolute ones
    of ``hydrogen``; the package imports itself relatively, so none is missed by another spelling."""
    import ast

    for rel in [*gen.DERIVATION_FILES, *(r for sub in gen.DERIVATION_DIRS for r in gen._modules(sub))]:
        for node in ast.walk(ast.parse((gen._PACKAGE / rel).read_bytes())):
            if isinstance(node, ast.ImportFrom) and not node.level:
                assert not (node.module or "").startswith("hydrogen"), (rel, node.module)
            if isinstance(node, ast.Import):
                assert not any(a.name.startswith("hydrogen") for a in node.names), rel


def test_the_functions_needed_first_are_written_first_and_every_byte_is_the_same(tmp_path):
    """``render(first=...)`` writes the functions a build compiles first (steps leading), and the
    folder reads byte for byte as without it: the order of writing changes no C."""
    from hydrogen.controllers import LEAN, step_function_name

    model = hydrogen.load_model(Path(__file__).parent / "data" / "four_way_arm.toml")
    folders, orders = [], []
    for first in (None, lambda name: name.endswith(LEAN) or LEAN + "_" in name):
        folder = tmp_path / f"gen{len(folders)}"
        folder.mkdir()
        order = []
        gen.render(model, folder, controllers=("adaptive-robust",), written=lambda n, p: order.append(n),
                   first=first)
        folders.append({p.name: p.read_bytes() for p in folder.iterdir()})
        orders.append(order)
    assert folders[0] == folders[1]
    lean_step = step_function_name("adaptive-robust", LEAN)
    own = [n for n in orders[1] if n is not None and "adaptive_robust" in n]
    assert own[0] == lean_step and all(LEAN in n for n in own[:3]) and not any(LEAN in n for n in own[3:])
    assert own[3] == step_function_name("adaptive-robust")  # then the others, their step first
    assert orders[0].index(step_function_name("adaptive-robust")) < orders[0].index(lean_step)


@pytest.mark.parametrize("numbers", ["inputs", "constants"])
def test_a_rates_function_selected_from_its_controllers_graph_is_the_same_c(tmp_path, numbers):
    """A controller's rates function (its ``xc_dot`` alone) is taken from the controller's CasADi graph
    when that is converted already: the same C, byte for byte, as converting it from SymPy."""
    model = hydrogen.load_model(Path(__file__).parent / "data" / "four_way_arm.toml")
    functions, _ = gen.derive(model, numbers, ("adaptive-robust",), core=False)
    full = next(f for f in functions if f.name == "ctrl_adaptive_robust")
    rates = next(f for f in functions if f.name == "ctrl_adaptive_robust_rates")
    assert rates.selects == full.name
    texts = []
    for cache in ({}, None):  # the controller converted first (selected), then rates alone (from SymPy)
        folder = tmp_path / f"c{len(texts)}"
        folder.mkdir()
        if cache is not None:
            gen.write_function(full, model.name, folder, cache)
        gen.write_function(rates, model.name, folder, {} if cache is None else cache)
        texts.append((folder / f"{model.name}_ctrl_adaptive_robust_rates.c").read_bytes())
    assert texts[0] == texts[1]
