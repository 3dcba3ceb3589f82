"""Nothing lost, nothing silent: each fault or bad input gives one clear error, files stay intact and
results are kept. One test (or more) per kind of fault."""
import dataclasses
import json
import os
import subprocess
import sys
import textwrap
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen import cli
from hydrogen.codegen import generate as gen
from hydrogen.errors import (BuildCacheError, CompilerError, HydrogenError, ModelError, OutputPathError,
                             ScenarioError, SimulationError)
from hydrogen.fileio import locked, replace_dir
from hydrogen.model import default_model_path, load_model
from hydrogen.simulation.loop_config import Run, config_values
from hydrogen.simulation.reference import MultiSine, Step
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.simulator import Stepper, _describe, simulate


def _unit(model, axis):
    """A pose offset of 1 along ``axis``, sized by the model."""
    return np.eye(len(model.neutral_pose))[axis]


# 1 -------------------------------------------------------------------------------------------------
def test_generate_refuses_a_folder_it_did_not_write_and_a_file(tmp_path, model):
    mine = tmp_path / "d"
    mine.mkdir()
    (mine / "keep").write_text("x")
    for force in (False, True):
        with pytest.raises(OutputPathError, match="not a hydrogen generated folder"):
            gen.generate(model, mine, force=force)
        assert (mine / "keep").read_text() == "x"
    # a web app's manifest.json does not make a folder a generated one
    (mine / "manifest.json").write_text('{"name": "my app"}')
    with pytest.raises(OutputPathError):
        gen.generate_locked(model, mine, force=True)
    assert (mine / "keep").read_text() == "x"
    a_file = tmp_path / "f"
    a_file.write_text("data")
    with pytest.raises(OutputPathError, match="is a file"):
        gen.generate(model, a_file, force=True)
    assert a_file.read_text() == "data"


def test_generate_refuses_a_generated_folder_holding_a_file_it_did_not_write(tmp_path, model):
    import shutil

    from hydrogen.resources import committed_generated_dir

    out = tmp_path / "gen"
    shutil.copytree(committed_generated_dir() / model.name, out)  # a generated folder, as generate writes it
    (out / "my_notes.c").write_text("/* mine */")
    for force in (False, True):
        with pytest.raises(OutputPathError, match=r"holds my_notes.c, which hydrogen did not write"):
            gen.generate(model, out, force=force)
    assert (out / "my_notes.c").read_text() == "/* mine */"
    (out / "manifest.json").write_text("{broken")
    with pytest.raises(OutputPathError, match=r"manifest.json cannot be read") as err:
        gen.generate(model, out, force=True)
    assert str(out / "manifest.json") in str(err.value)


# 2, 15 ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("make_ref, field", [
    (lambda b: MultiSine(b, ((-1, 0.01, 1),)), "sines[0] axis"),
    (lambda b: MultiSine(b, ((len(b), 0.01, 1),)), "sines[0] axis"),
    (lambda b: MultiSine(b, ((2.5, 0.01, 1),)), "sines[0] axis"),
    (lambda b: Step(b, -1, 0.02, 1.0), "reference.axis"),
    (lambda b: MultiSine(b, ((2, float("nan"), 1),)), "sines[0] amplitude"),
    (lambda b: MultiSine(b, ((2, 0.01, float("inf")),)), "sines[0] frequency"),
    (lambda b: Step(b, 2, float("nan"), 1.0), "reference.height"),
    (lambda b: MultiSine(b[:-1], ()), "reference.bias"),
])
def test_a_bad_reference_is_refused_before_anything_runs(dyn, make_ref, field):
    ref = make_ref(np.asarray(dyn.model.neutral_pose, float))
    with pytest.raises(ScenarioError, match=field.replace("[", r"\[").replace("]", r"\]")):
        simulate(dyn, "z-1hz", "p", duration=0.05, reference=ref)


def test_the_loop_runtime_refuses_an_out_of_range_axis_before_calling_c(dyn):
    from hydrogen.runtime.loop import LoopRunner
    from hydrogen.simulation.control import make_controller

    bias = np.asarray(dyn.model.neutral_pose, float)
    ctrl = make_controller(dyn, "p")
    sc = named_scenario("z-1hz", dyn.model)
    for ref in (MultiSine(bias, ((-1, 0.01, 1),)), Step(bias, len(bias), 0.01, 0.0)):
        # the scenario's own check is bypassed (a frozen dataclass edited in place), as a caller of
        # the runtime with hand-made values would
        bad = dataclasses.replace(sc)
        object.__setattr__(bad, "reference", ref)
        with pytest.raises(ValueError, match="axis"):
            LoopRunner(dyn, ctrl, config_values(Run(dyn, bad, ctrl, 1e-3)))


def test_the_loop_runtime_refuses_a_missing_or_misshapen_value(dyn):
    from hydrogen.runtime.loop import LoopRunner
    from hydrogen.simulation.control import make_controller

    ctrl = make_controller(dyn, "p")
    good = config_values(Run(dyn, named_scenario("z-1hz", dyn.model), ctrl, 1e-3))
    LoopRunner(dyn, ctrl, good)  # the values as derived are accepted
    with pytest.raises(ValueError, match=r"no value for \['quant_l'\]"):
        LoopRunner(dyn, ctrl, {k: v for k, v in good.items() if k != "quant_l"})
    with pytest.raises(ValueError, match=f"valve must hold {5 * dyn.model.n_cylinders} numbers"):
        LoopRunner(dyn, ctrl, {**good, "valve": good["valve"][:2]})
    with pytest.raises(ValueError, match="delay must be"):
        LoopRunner(dyn, ctrl, {**good, "delay": 9})


# 3 -------------------------------------------------------------------------------------------------
def test_sweep_keeps_every_good_result_when_entries_are_bad(model):
    good = dict(scenario="z-step", controller="p", duration=0.05)
    runs = [good, "z-1hz", {"bogus": 1}, {**good, "model": model}, {**good, "duration": "abc"}, 42, good]
    with ThreadPoolExecutor(1) as ex:
        out = hydrogen.sweep(runs, executor=ex, model=model)
    assert len(out) == len(runs)
    assert "max_error" in out[0] and "max_error" in out[-1]
    assert out[0]["max_error"] == out[-1]["max_error"]
    for i, what in ((1, "must be a dict"), (2, "unknown key"), (3, "model"), (4, "duration"), (5, "must be a dict")):
        assert what in out[i]["error"], (i, out[i])


@pytest.mark.parametrize("runs", ["z-1hz", None, {"scenario": "z-1hz"}, 3])
def test_a_malformed_sweep_call_raises(runs):
    with pytest.raises(ScenarioError, match="runs must be a list"):
        hydrogen.sweep(runs)


# 4 -------------------------------------------------------------------------------------------------
def test_export_refuses_names_that_would_inject_into_the_makefile(tmp_path, dyn):
    from hydrogen.export import export

    sc = dataclasses.replace(named_scenario("z-step", dyn.model), name='x"\n$(shell touch pwned)')
    with pytest.raises(ScenarioError, match="cannot be written into generated files"):
        export(tmp_path / "out", sc, "p", duration=0.05, dyn=dyn)
    assert not (tmp_path / "out").exists() and not (tmp_path / "pwned").exists()
    bad_model = dataclasses.replace(dyn.model, name="x$(shell id)")
    with pytest.raises(ModelError, match="model name"):
        gen.generate_locked(bad_model, tmp_path / "gen")


def test_labels_and_identifiers():
    from hydrogen.names import check_identifier, check_label

    for ok in ("z-1hz", "paper-sim", "run.2", "a"):
        assert check_label(ok, "s") == ok
    for bad in ("", "a b", "x\ny", "$(shell id)", "a*/b", "-x", "ä", "a" * 65, None):
        with pytest.raises(ModelError):
            check_label(bad, "s")
    assert check_identifier("ubc_stewart", "m") == "ubc_stewart"


# 5 -------------------------------------------------------------------------------------------------
def test_a_metric_window_after_the_run_is_clamped_and_said(dyn):
    sc = named_scenario("z-1hz", dyn.model)
    res = simulate(dyn, "z-1hz", "p", duration=sc.metric_start / 4)
    m = res.metrics
    assert m["metric_start_s"] == 0.0
    assert "whole run" in m["metric_note"] and f"{sc.metric_start:g} s" in m["metric_note"]
    assert m["max_error"]["z"] == pytest.approx(float(np.abs(res.error[:, 2]).max()))
    # a window inside the run is used as is, and says nothing
    res = simulate(dyn, "z-1hz", "p", duration=sc.metric_start + 0.1)
    assert res.metrics["metric_start_s"] == sc.metric_start and "metric_note" not in res.metrics


# 6 -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, why", [("_robot", "start with a letter"), ("robot_", "end with an underscore"),
                                       ("my__robot", "double underscore"), ("rôbot", "non-ASCII"),
                                       ("r" * 300, "300 characters")])
def test_model_names_that_break_code_generation_are_refused(tmp_path, name, why):
    text = default_model_path().read_text()
    assert 'name = "ubc_stewart"' in text
    path = tmp_path / "m.toml"
    path.write_text(text.replace('name = "ubc_stewart"', f'name = "{name}"'), encoding="utf-8")
    with pytest.raises(ModelError, match=why) as err:
        load_model(path)
    assert str(path) in str(err.value)


# 8 -------------------------------------------------------------------------------------------------
def test_output_paths_are_checked_before_the_run(tmp_path, monkeypatch, capsys):
    ran = []
    monkeypatch.setattr(hydrogen, "simulate", lambda *a, **k: ran.append(1))
    a_file = tmp_path / "f"
    a_file.write_text("x")
    for opt, path, what in (("--json", tmp_path, "is a folder"), ("--json", a_file / "m.json", "is a file"),
                            ("--plot", tmp_path / "p.xyz", "unknown figure format"),
                            ("--plot", tmp_path / "noext", "unknown figure format")):
        assert cli.main(["simulate", "--scenario", "z-step", opt, str(path)]) == 2
        assert what in capsys.readouterr().err
    # unwritable (a read-only folder, or root-proof: the probe file cannot be created)
    import hydrogen.outputs as outputs

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(outputs.tempfile, "mkstemp", refuse)
    assert cli.main(["simulate", "--json", str(tmp_path / "m.json")]) == 2
    assert "cannot write in" in capsys.readouterr().err
    assert not ran and a_file.read_text() == "x"


def test_no_output_replaces_what_the_command_reads(tmp_path, monkeypatch, capsys):
    """--json, --log or --plot naming the robot's description, its URDF or the log being identified, or
    two outputs naming one file: refused before the run, naming both, and every file kept as it was."""
    import shutil

    from hydrogen.model import model_path

    ran = []
    monkeypatch.setattr(hydrogen, "simulate", lambda *a, **k: ran.append(1))
    monkeypatch.setattr(hydrogen, "identify", lambda *a, **k: ran.append(1))
    for name in ("ubc_stewart", "excavator_arm"):
        shutil.copy(model_path(name), tmp_path / f"{name}.toml")
    shutil.copy(model_path("excavator_arm").with_suffix(".urdf"), tmp_path / "excavator_arm.urdf")
    toml, arm, urdf = tmp_path / "ubc_stewart.toml", tmp_path / "excavator_arm.toml", tmp_path / "excavator_arm.urdf"
    log = tmp_path / "rig.csv"
    log.write_text("t,l0\n0,1\n")
    (tmp_path / "link").symlink_to(tmp_path, target_is_directory=True)
    before = {f: f.read_bytes() for f in (toml, arm, urdf, log)}
    for argv, says in (
            (["simulate", "--model", str(toml), "--json", str(toml)], "robot description this command reads"),
            (["simulate", "--model", str(arm), "--log", str(urdf)], "URDF this command reads"),
            (["simulate", "--model", str(toml), "--json", str(tmp_path / ".." / tmp_path.name / "ubc_stewart.toml")],
             "robot description"),
            (["simulate", "--log", str(tmp_path / "x.csv"), "--json", str(tmp_path / "x.csv")], "also --json's file"),
            (["simulate", "--json", str(tmp_path / "link" / "y.json"), "--log", str(tmp_path / "y.json")],
             "also --json's file"),  # one file through a symlinked folder
            (["identify", str(log), "--json", str(log)], "log this command reads"),
            (["identify", str(log), "--model", str(toml), "--json", str(toml)], "robot description")):
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err, (argv, err)
    assert not ran
    assert {f: f.read_bytes() for f in before} == before
    assert not (tmp_path / "x.csv").exists() and not (tmp_path / "y.json").exists()


def test_plot_writes_the_format_its_extension_names(tmp_path, dyn):
    from hydrogen.figures import plot_tracking_errors

    res = simulate(dyn, "z-step", "p", duration=0.05)
    assert plot_tracking_errors(res, tmp_path / "p.pdf").read_bytes().startswith(b"%PDF")
    assert b"<svg" in plot_tracking_errors(res, tmp_path / "p.svg").read_bytes()[:1000]
    assert plot_tracking_errors(res, tmp_path / "p.png").read_bytes().startswith(b"\x89PNG")
    with pytest.raises(OutputPathError, match=r"\.pdf"):  # 18: refused, naming what is possible
        plot_tracking_errors(res, tmp_path / "p.xyz")
    assert not (tmp_path / "p.xyz").exists()


def test_a_diverged_run_still_writes_json_and_plot(tmp_path, dyn, monkeypatch, capsys):
    res = simulate(dyn, "z-step", "p", duration=0.05)

    def diverge(*a, **k):
        raise SimulationError("simulation 'z-step' with 'p' diverged at t = 0.0500 s: test", result=res)
    monkeypatch.setattr(hydrogen, "simulate", diverge)
    j, p = tmp_path / "m.json", tmp_path / "p.png"
    assert cli.main(["simulate", "--scenario", "z-step", "--controller", "p", "--json", str(j),
                     "--plot", str(p)]) == 2
    data = json.loads(j.read_text())
    assert data["diverged"] is True and "diverged at t = 0.0500 s" in data["error"]
    assert data["max_error"]["z"] == res.metrics["max_error"]["z"]
    assert p.read_bytes().startswith(b"\x89PNG")
    assert "diverged" in capsys.readouterr().err


# 9 -------------------------------------------------------------------------------------------------
def test_export_and_figures_refuse_folders_they_would_clobber(tmp_path, dyn, capsys):
    from hydrogen.export import export

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    with pytest.raises(OutputPathError, match="not an earlier hydrogen export"):
        export(mine, "z-step", "p", duration=0.05, dyn=dyn)
    a_file = tmp_path / "file"
    a_file.write_text("keep")
    with pytest.raises(OutputPathError, match="is a file"):
        export(a_file, "z-step", "p", duration=0.05, dyn=dyn)
    assert cli.main(["figures", "--out", str(a_file), "--quiet"]) == 2
    assert "is a file" in capsys.readouterr().err
    assert (mine / "notes.txt").read_text() == "keep me" and a_file.read_text() == "keep"


# 10, 19: see test_every_subcommand_refuses_bad_arguments_with_status_2 below.
def test_bench_refuses_unknown_modules():
    from hydrogen.bench import run_suite

    with pytest.raises(HydrogenError, match="bogus"):
        run_suite(only=["bogus"])


# 11 ------------------------------------------------------------------------------------------------
def test_a_run_too_large_for_memory_is_refused_with_the_limit_and_the_way_round(dyn, monkeypatch):
    for kw in (dict(duration=1e7), dict(control_rate=1e12, delay=0.0)):
        with pytest.raises(ScenarioError, match="HYDROGEN_MAX_RUN_BYTES") as err:
            simulate(dyn, "z-1hz", "p", **kw)
        assert "hydrogen.stepper" in str(err.value) and "chunks" in str(err.value)
    with pytest.raises(ScenarioError, match="HYDROGEN_MAX_RUN_BYTES"):
        Stepper(dyn, "z-1hz", "p", duration=1e7)
    # the stepper keeps no logs, so it runs what simulate refuses
    monkeypatch.setenv("HYDROGEN_MAX_RUN_BYTES", "1000000")
    with pytest.raises(ScenarioError, match="1,2|periods"):
        simulate(dyn, "z-1hz", "p", duration=4.0)
    st = Stepper(dyn, "z-1hz", "p", duration=4.0)
    st.step()
    assert st.t > 0


# 12 ------------------------------------------------------------------------------------------------
def test_cache_folder_that_is_a_file_or_under_one(tmp_path, model):
    a_file = tmp_path / "cachefile"
    a_file.write_text("x")
    for cache, what in ((a_file, "is a file"), (a_file / "sub", "sits under the file")):
        with pytest.raises(BuildCacheError, match=what) as err:
            hydrogen.build(model, cache=cache)
        assert str(cache) in str(err.value)


def _refuse_locks(monkeypatch):
    import hydrogen.fileio as fileio

    class NoLock:
        def __init__(self, path):
            self.path = path

        def acquire(self, timeout=None):
            raise PermissionError(13, "Permission denied", self.path)

    monkeypatch.setattr(fileio, "FileLock", NoLock)


def test_a_warm_read_only_cache_stays_usable_and_a_cold_one_is_named(tmp_path, model, dyn, cache, monkeypatch):
    from conftest import warm_copy

    warm = warm_copy(cache, tmp_path / "warm")  # the run's build, copied: warm without compiling again
    hydrogen.build(model, cache=warm)
    _refuse_locks(monkeypatch)  # no lock file can be created anywhere (a read-only cache, as for a user)
    if os.geteuid() != 0:
        for d, _, files in os.walk(warm):
            os.chmod(d, 0o555)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no fallback to ctypes: the cached extension needs no lock either
            d = hydrogen.build(model, cache=warm)
        assert d.backend == dyn.backend
        assert d.leg_lengths(model.neutral_pose).shape == (model.n_cylinders,)
    finally:
        for d, _, _ in os.walk(warm):
            os.chmod(d, 0o755)
    cold = tmp_path / "cold"
    with pytest.raises(BuildCacheError, match="cannot be written") as err:
        hydrogen.build(model, cache=cold)
    assert str(cold) in str(err.value)


def test_a_cache_removed_during_the_build_is_named(tmp_path, model, monkeypatch):
    import shutil

    import hydrogen.runtime.compiler as compiler

    cache = tmp_path / "cache"
    real = compiler.run_compiler

    def remove_then_run(argv, what, timeout, cwd=None):
        shutil.rmtree(cache, ignore_errors=True)
        return real(argv, what, timeout, cwd)
    monkeypatch.setattr(compiler, "run_compiler", remove_then_run)
    with pytest.raises(BuildCacheError, match="removed during the build") as err:
        hydrogen.build(model, cache=cache)
    assert str(cache) in str(err.value)


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc, where no folder can be made")
def test_a_cache_folder_that_cannot_be_made_is_named_as_such(model, monkeypatch):
    """A cache folder under /proc was reported as removed during the build, advising to run again."""
    with pytest.raises(BuildCacheError, match=r"cache folder /proc/hydrogen-cache cannot be created") as err:
        hydrogen.build(model, cache=Path("/proc/hydrogen-cache"))
    assert "removed during the build" not in str(err.value) and "HYDROGEN_CACHE_DIR" in str(err.value)


# 13, 20 --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("controller, kw, field", [
    ("p", dict(friction="abc"), "friction"),
    ("p", dict(duration="abc"), "duration"),
    ("p", dict(seed="x"), "seed"),
    ("p", dict(gains=[0.1]), "gains"),
    ("p", dict(reference=None), "reference"),
    ("p", dict(kalman="no"), "kalman"),
    ("p", dict(t_adapt=None), "t_adapt"),
    ("adaptive-robust", dict(theta0_factor=(0, 0, 0, 0)), "theta0_factor"),
    ("adaptive-robust", dict(theta0_factor=(1, 1, 1)), "theta0_factor"),
    ("adaptive-robust", dict(gamma0_factor=(-1, 1)), "gamma0_factor"),
    ("adaptive-robust", dict(theta0_factor=(100, 1, 1, 1)), "projection bounds"),
    ("adaptive-observer", dict(gamma0_factor=(1, 1e6)), "projection bounds"),
    ("p", dict(gains={"Kleg": -0.01}), "Kleg"),
    ("p", dict(gains={"u_max": 0.0}), "u_max"),
    ("p", dict(q0_offset="far"), "q0_offset"),
])
def test_the_python_api_names_the_field(dyn, controller, kw, field):
    with pytest.raises(ScenarioError, match=field) as err:
        hydrogen.simulate("z-step", controller, dyn=dyn, **{"duration": 0.05, **kw})
    assert "(run)" not in str(err.value)  # the scenario is named, not a placeholder


def test_a_start_far_off_and_api_arguments_of_the_wrong_type(dyn, model):
    with pytest.raises(ScenarioError, match="q0_offset.*stroke"):
        hydrogen.simulate("z-step", "p", dyn=dyn, duration=0.05, q0_offset=5 * _unit(model, 2))
    with pytest.raises(ScenarioError, match="scenario"):
        hydrogen.simulate(None, "p", dyn=dyn)
    with pytest.raises(ScenarioError, match="model"):
        hydrogen.simulate("z-step", "p", model=5)
    with pytest.raises(ScenarioError, match="controller"):
        hydrogen.simulate("z-step", 3, dyn=dyn)
    with pytest.raises(ScenarioError, match="q0_offset"):
        hydrogen.stepper("z-step", "p", dyn=dyn, q0_offset=(0.0,) * (len(model.neutral_pose) + 1))


# 14 ------------------------------------------------------------------------------------------------
def test_divergence_names_the_signal_that_went_non_finite(dyn):
    with pytest.raises(SimulationError, match=r"controller state is non-finite at \['gamma[12]_hat\[0\]'") as err:
        hydrogen.simulate("z-1hz", "adaptive-robust", dyn=dyn, duration=0.5, gains={"Ko": 1e9})
    assert "entries []" not in str(err.value)
    n = len(dyn.model.neutral_pose)
    msg = _describe(np.zeros(4 * n), 1.0, None, np.array([1.0, np.nan]), np.array([np.inf, 0.0]))
    assert "command u (spool positions) is non-finite at entries [0]" in msg
    assert "controller state is non-finite at [1]" in msg and "plant state" not in msg


# 16 ------------------------------------------------------------------------------------------------
def test_error_messages_do_not_quote_huge_values():
    import tomllib

    from hydrogen.model import model_from_dict

    data = tomllib.loads(default_model_path().read_text())
    data["cylinders"][0]["from"]["point"] = [[1.0, 2.0, 3.0]] * 700_000  # 2.1 million numbers
    with pytest.raises(ModelError, match="leg1") as err:
        model_from_dict(data, "big.toml")
    assert len(str(err.value)) < 5000


# 17 ------------------------------------------------------------------------------------------------
def test_cflags_as_a_string_is_split_like_a_shell_and_nonsense_is_refused():
    from hydrogen.runtime.compiler import Toolchain

    assert Toolchain(cflags="-O2 -fPIC  -DX='a b'").cflags == ("-O2", "-fPIC", "-DX=a b")
    assert Toolchain(cflags=["-O1"]).cflags == ("-O1",)
    for bad in (5, ["-O2", 3]):
        with pytest.raises(CompilerError, match="cflags"):
            Toolchain(cflags=bad)
    with pytest.raises(CompilerError, match="timeout"):
        Toolchain(timeout=0)


# 21 ------------------------------------------------------------------------------------------------
def test_a_compiler_that_never_returns_is_timed_out(tmp_path):
    from hydrogen.runtime.compiler import Toolchain, compile_library

    fake = tmp_path / "slowcc"
    fake.write_text('#!/bin/sh\nif [ "$1" = --version ]; then echo slowcc 1.0; exit 0; fi\nexec sleep 30\n')
    fake.chmod(0o755)
    src = tmp_path / "a.c"
    src.write_text("int a(void) { return 1; }\n")
    start = time.monotonic()
    with pytest.raises(CompilerError, match="did not finish .* within 0.5 s"):
        compile_library([src], "slow", Toolchain(cc=str(fake), timeout=0.5), cache=tmp_path / "cache")
    assert time.monotonic() - start < 10


def test_a_compiler_that_hangs_on_the_extension_or_an_fmu_is_timed_out(tmp_path):
    """Every compiler call has the timeout: the CPython extension's and the FMU's too."""
    from hydrogen.fmu import _compile
    from hydrogen.runtime.compiler import Toolchain
    from hydrogen.runtime.extension import build_extension

    fake = tmp_path / "slowcc"
    fake.write_text('#!/bin/sh\nif [ "$1" = --version ]; then echo slowcc 1.0; exit 0; fi\nexec sleep 30\n')
    fake.chmod(0o755)
    tc = Toolchain(cc=str(fake), timeout=0.5)
    start = time.monotonic()
    with pytest.raises(CompilerError, match=r"(?s)did not finish .* within 0.5 s and was stopped.*HYDROGEN_CC_TIMEOUT"):
        build_extension({"model_name": "slow", "functions": []}, tc, cache=tmp_path / "cache")
    with pytest.raises(CompilerError, match=r"(?s)did not finish .* within 0.5 s and was stopped.*HYDROGEN_CC_TIMEOUT"):
        _compile({"a.c": b"int a(void) { return 1; }\n"}, ["a.c"], "slow", tc)
    assert time.monotonic() - start < 20


def test_a_held_lock_is_reported_and_given_up_on(tmp_path, capfd):
    target = tmp_path / "folder"
    code = textwrap.dedent(f"""
        import sys, time
        from hydrogen.fileio import locked
        with locked({str(target)!r}):
            print("held", flush=True)
            time.sleep(20)
    """)
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(Path(hydrogen.__file__).parents[1])})
    try:
        assert holder.stdout.readline().strip() == "held"
        start = time.monotonic()
        with pytest.raises(BuildCacheError, match="gave up waiting 1.5 s") as err:
            with locked(target, timeout=1.5):
                pass
        assert 1.4 < time.monotonic() - start < 8
        assert f"PID {holder.pid}" in str(err.value)
        assert f"waiting for the build lock on {target} (held by PID {holder.pid}" in capfd.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    with locked(target, timeout=5):  # free again once the holder is gone
        pass
    assert [p.name for p in tmp_path.iterdir()] == [".folder.lock"]


# Also: stale staging and build folders -------------------------------------------------------------
def test_stale_staging_and_build_folders_are_removed_on_the_next_run(tmp_path):
    from hydrogen.runtime.compiler import Toolchain, build_key, compile_library

    target = tmp_path / "gen"
    stale = tmp_path / ".gen.new-killed"
    stale.mkdir()
    (stale / "half.c").write_text("/* half written */")
    staging = tmp_path / ".gen.new-now"
    staging.mkdir()
    (staging / "manifest.json").write_text("{}")
    with locked(target):
        replace_dir(staging, target)
    assert not stale.exists() and (target / "manifest.json").exists()

    src = tmp_path / "a.c"
    src.write_text("int a(void) { return 1; }\n")
    tc = Toolchain(cflags=("-O0", "-fPIC", "-std=c99"))
    cache = tmp_path / "cache"
    build_dir = cache / "build" / build_key([src], tc)
    (build_dir / "tmpkilled").mkdir(parents=True)
    compile_library([src], "tiny", tc, cache=cache)
    assert not (build_dir / "tmpkilled").exists()


# Packaging: the wheel layout is found ---------------------------------------------------------------
def test_resources_prefer_the_copy_inside_the_package(tmp_path, monkeypatch):
    import hydrogen.resources as resources

    pkg = tmp_path / "site" / "hydrogen"
    (pkg / "_templates").mkdir(parents=True)
    monkeypatch.setattr(resources, "_PACKAGE", pkg)
    assert resources.templates_dir() == pkg / "_templates"
    assert resources.committed_generated_dir() == tmp_path / "site" / "generated"  # none shipped: checkout's


# Every subcommand: bad arguments give exit status 2, one message, no traceback, before any work -----
_BAD = [
    ["generate", "--out", "{file}"],
    ["generate", "--out", "{dir_with_file}"],
    ["generate", "--model", "{missing}"],
    ["simulate", "--duration", "-1"],
    ["simulate", "--duration", "1e7"],
    ["simulate", "--duration", "nan"],
    ["simulate", "--duration", "1e-9"],  # shorter than a control period: was a run reporting 0 %
    ["simulate", "--log", "{tmp}/l.csv", "--log-seed", "-3"],  # was a traceback after the run
    ["simulate", "--plot", "{tmp}/p.xyz"],
    ["simulate", "--json", "{file}/m.json"],
    ["simulate", "--json", "/proc/hydrogen-test.json"],
    ["simulate", "--scenario", "bogus"],
    ["figures", "--out", "{file}"],
    ["bench", "--only", "bogus"],
    ["bench", "--json", "{tmp}"],
    ["export", "--out", "{file}"],
    ["export", "--out", "{dir_with_file}"],
    ["export", "--out", "{tmp}/e", "--duration", "-1"],
    ["tune-p", "--workers", "-1"],
    ["tune-p", "--n", "-3"],
    ["tune-p", "--n", "0"],  # was the documented grid, silently
    ["tune-p", "--n", "1", "--min", "0.01", "--max", "0.02"],  # was the grid's first point alone
    ["tune-p", "--min", "nan"],
    ["tune-p", "--min", "0"],
    ["tune-p", "--min", "0.2", "--max", "0.1"],
    ["tune", "--controller", "bogus"],
    ["tune", "--controller", "p", "--model", "{missing}"],
    ["margins", "--workers", "0"],
    ["margins", "--controller", "bogus"],
]


def test_every_subcommand_refuses_bad_arguments_with_status_2(tmp_path):
    a_file = tmp_path / "file"
    a_file.write_text("keep")
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep").write_text("keep")
    fill = {"file": a_file, "dir_with_file": full, "missing": tmp_path / "missing.toml", "tmp": tmp_path}
    env = {**os.environ, "PYTHONPATH": str(Path(hydrogen.__file__).parents[1]),
           "HYDROGEN_CACHE_DIR": str(tmp_path / "cache")}  # a cold cache: nothing may build before refusing
    procs = []
    for args in _BAD:
        argv = [sys.executable, "-m", "hydrogen", *(a.format(**fill) for a in args)]
        procs.append((args, subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                             env=env, cwd=tmp_path)))
    for args, proc in procs:
        out, _ = proc.communicate(timeout=120)
        assert proc.returncode == 2, (args, out)
        assert "Traceback" not in out, (args, out)
        assert "error" in out, (args, out)
    assert {c for c, *_ in _BAD} == {"generate", "simulate", "figures", "bench", "export", "tune-p", "tune",
                                       "margins"}
    assert a_file.read_text() == "keep" and (full / "keep").read_text() == "keep"
    assert not (tmp_path / "cache" / "build").exists()  # refused before anything was compiled


# Tuning on a robot without a rig scenario; sweeps whose workers cannot start or die ----------------
def _model_without_rig(tmp_path):
    """The Stewart platform with its [rig] table and rig scenarios removed (paper-sim kept)."""
    text = default_model_path().read_text()
    head, rest = text.split("\n[rig]\n")
    paper = "[scenarios.paper-sim]" + rest.split("[scenarios.paper-sim]")[1].split("\n[scenarios.")[0]
    path = tmp_path / "norig.toml"
    path.write_text(head + "\n" + paper + "\n")
    assert "paper-sim" in load_model(path).scenarios and not load_model(path).scenarios.get("rig")
    return path


def test_tune_and_margins_without_a_rig_scenario_say_what_to_add(tmp_path, capsys):
    from hydrogen.simulation import tuning

    path = _model_without_rig(tmp_path)
    wanted = ("has none; its scenarios: paper-sim (no rig = true). Add to the description a table "
              "[scenarios.<name>] with rig = true and reference.sines = [[coordinate, amplitude, Hz], ...]")
    for argv in (["margins"], ["tune", "--controller", "backstepping"], ["tune-p"]):
        assert cli.main([*argv, "--model", str(path), "--quiet"]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and wanted in err[0] and "add [rig] with at least duration, control_rate" in err[0]
    for call in (lambda: tuning.margins(model=path), lambda: tuning.tune_p(model=path),
                 lambda: tuning.tune("adaptive-robust", model=path)):
        with pytest.raises(ScenarioError, match=r"Add to the description a table \[scenarios.<name>\]"):
            call()


def test_absurd_worker_counts_are_refused(capsys):
    too_many = 4 * (os.cpu_count() or 1) + 1
    assert cli.main(["tune-p", "--workers", str(too_many), "--quiet"]) == 2
    assert f"--workers) {too_many} for {os.cpu_count()} core(s): at most" in capsys.readouterr().err
    with pytest.raises(ScenarioError, match="at most"):
        hydrogen.sweep([{}], max_workers=too_many)


_FAILING_FORK = """
import errno, os, sys
real, started = os.fork, []
def fork():  # the process limit reached after {limit} worker(s)
    if len(started) >= {limit}:
        raise BlockingIOError(errno.EAGAIN, "Resource temporarily unavailable")
    started.append(1)
    return real()
os.fork = fork
from hydrogen.cli import main
sys.exit(main(sys.argv[1:]))
"""

_DYING_WORKER = """
import os, sys
import hydrogen
import hydrogen.simulation.sweep as sweep_module
def die(job):  # a worker killed mid-run (out of memory, a crash in compiled code)
    os._exit(9)
sweep_module._run_chunk = die
try:
    hydrogen.sweep([{{}}, {{}}, {{}}], max_workers=2)
except hydrogen.WorkerError as exc:
    print("WorkerError:", exc)
    sys.exit(3)
"""


@pytest.mark.parametrize("limit", [0, 1])
def test_workers_that_cannot_start_give_a_clear_error_and_the_command_returns(tmp_path, dyn, cache, limit):
    script = tmp_path / "fork.py"
    script.write_text(_FAILING_FORK.format(limit=limit))
    env = {**os.environ, "PYTHONPATH": str(Path(hydrogen.__file__).parents[1]), "HYDROGEN_CACHE_DIR": str(cache)}
    start = time.monotonic()
    proc = subprocess.run([sys.executable, str(script), "tune-p", "--workers", "2", "--n", "2", "--quiet"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "could not start 2 worker processes (BlockingIOError" in proc.stderr and "fewer workers" in proc.stderr
    assert "diverged" not in proc.stdout + proc.stderr and "Traceback" not in proc.stderr
    assert time.monotonic() - start < 60


def test_a_worker_that_dies_is_a_clear_error_not_a_diverged_run(tmp_path, dyn, cache):
    script = tmp_path / "die.py"
    script.write_text(_DYING_WORKER.format())
    env = {**os.environ, "PYTHONPATH": str(Path(hydrogen.__file__).parents[1]), "HYDROGEN_CACHE_DIR": str(cache)}
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=120)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "a worker process died abruptly while run 1 of 3 was pending" in proc.stdout


def test_a_broken_executor_is_a_worker_error():
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    class Broken:
        def submit(self, fn, *args):
            f = Future()
            f.set_exception(BrokenProcessPool("a child process terminated abruptly"))
            return f

    with pytest.raises(hydrogen.WorkerError, match="died abruptly while run 1 of 2"):
        hydrogen.sweep([{}, {}], executor=Broken())

    class Refusing:
        def submit(self, fn, *args):
            raise OSError(11, "Resource temporarily unavailable")

    with pytest.raises(hydrogen.WorkerError, match="could not start the worker processes"):
        hydrogen.sweep([{}], executor=Refusing())


# description files: regular files only, of bounded size ----------------------------------------------
def _special_files(tmp_path):
    """A FIFO (opening it for reading would wait for a writer), a device that never ends, a sparse
    file above the size limit (no disk used) and a folder, each with what the refusal says."""
    from hydrogen.model import MAX_DESCRIPTION_BYTES
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    big = tmp_path / "big.toml"
    with open(big, "wb") as fh:
        fh.truncate(MAX_DESCRIPTION_BYTES + 1)
    return [(fifo, "is not a regular file (a FIFO)"), (Path("/dev/zero"), "is not a regular file (a character device)"),
            (big, f"is {MAX_DESCRIPTION_BYTES + 1} bytes, larger than the {MAX_DESCRIPTION_BYTES} bytes"),
            (tmp_path, "is a folder, not a model file")]


def test_a_model_that_is_not_a_regular_file_is_refused_on_the_cli(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(Path(hydrogen.__file__).parents[1]),
           "HYDROGEN_CACHE_DIR": str(tmp_path / "cache")}
    for path, why in _special_files(tmp_path):
        proc = subprocess.Popen([sys.executable, "-m", "hydrogen", "simulate", "--model", str(path)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        try:
            out, _ = proc.communicate(timeout=60)  # a FIFO read would block: a regression fails, not hangs
        finally:
            proc.kill()
        assert proc.returncode == 2, out
        assert f"{path}: {why}" in out and "Traceback" not in out, out


def test_a_urdf_that_is_not_a_regular_file_is_refused(tmp_path):
    toml = hydrogen.model.model_path("excavator_arm").read_text()
    model = tmp_path / "arm.toml"
    for path, why in _special_files(tmp_path):
        if path == tmp_path:
            why = "is a folder, not a URDF file"
        model.write_text(toml.replace('urdf = "excavator_arm.urdf"', f'urdf = "{path}"'))
        with ThreadPoolExecutor(1) as pool:  # a blocked open would fail the wait, not hang the test
            future = pool.submit(load_model, model)
            try:
                with pytest.raises(ModelError) as err:
                    future.result(timeout=30)
            finally:
                if not future.done():  # unblock the reader: open the FIFO's writing end
                    os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        assert str(err.value).startswith(f"{model}: urdf: {path}: {why}"), str(err.value)


def test_supply_noise_on_a_constant_supply_is_refused_not_ignored(dyn):
    """noise_ps measures a [supply] state; a robot on a constant supply has none to measure."""
    with pytest.raises(ScenarioError, match=r"scenario 'z-1hz': noise_ps adds noise to a measured supply pressure, "
                                            r"but .* has a constant supply .*got 100000.0"):
        simulate(dyn, "z-1hz", "p", duration=0.01, noise_ps=1e5)


def test_supply_feedback_off_on_a_constant_supply_is_refused_not_ignored(dyn):
    """supply_feedback false holds the controllers' supply pressure at the nominal one; a robot on a
    constant supply reads nothing else, so turning it off would change nothing silently."""
    with pytest.raises(ScenarioError, match=r"scenario 'z-1hz': supply_feedback feeds the controllers the nominal "
                                            r"supply pressure .* but .* has a constant supply .*got False"):
        simulate(dyn, "z-1hz", "p", duration=0.01, supply_feedback=False)
    with pytest.raises(ScenarioError, match=r"supply_feedback must be True or False, got 'no'"):
        simulate(dyn, "z-1hz", "p", duration=0.01, supply_feedback="no")
