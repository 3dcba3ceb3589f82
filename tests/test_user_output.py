"""What a new user reads: no internal tracker numbers, per-coordinate units, estimates only of
controllers that adapt, a default scenario of the model's own, and progress on the long steps."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_no_output_names_an_internal_tracker_item():
    """Messages, templates, tests and benchmarks say what a thing is, never 'issue N'."""
    pattern = re.compile(r"issues? ?#?[0-9]", re.IGNORECASE)
    hits = []
    for folder in ("hydrogen", "tests", "benchmarks", "templates"):
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix not in (".py", ".j2", ".c", ".h", ".toml", ".txt", ".md") or not path.is_file():
                continue
            for no, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                if pattern.search(line) and path.name != Path(__file__).name:
                    hits.append(f"{path.relative_to(ROOT)}:{no}: {line.strip()}")
    assert not hits, "\n".join(hits)


# --- the simulate summary ----------------------------------------------------------------------

def test_error_lines_give_each_coordinate_its_unit_and_keep_the_columns_aligned():
    from hydrogen.summary import error_lines
    lines = error_lines(("x", "psi", "boom_angle_long"), ("m", "rad", "rad"),
                        {"x": 0.0012, "psi": 0.0345, "boom_angle_long": 0.5},
                        {"x": 2.5, "psi": None, "boom_angle_long": 123.456})
    assert lines[0].endswith(" mm") and lines[1].endswith(" mrad") and lines[2].endswith(" mrad")
    assert "1.2000 mm" in lines[0] and "34.5000 mrad" in lines[1] and "2.50 %" in lines[0]
    assert "(mm or mrad)" not in "".join(lines)
    # a coordinate the reference does not move: "-" in the % column, every column where it is elsewhere
    assert " - " in lines[1] and "%" not in lines[1]
    assert len({len(line) - len(line.split()[-1]) for line in lines}) == 1  # values end in one column
    assert len({line.index("%") for line in (lines[0], lines[2])}) == 1
    assert lines[1].index("-") == lines[0].index("%")


def _simulate_cli(capsys, *argv):
    from hydrogen.cli import main
    assert main(["simulate", "--duration", "0.05", *argv]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("controller, adapts", [("p", False), ("backstepping", False),
                                                ("adaptive-robust", True), ("adaptive-observer", True)])
def test_summary_reports_estimates_only_for_controllers_that_adapt(capsys, controller, adapts):
    out = _simulate_cli(capsys, "--controller", controller)
    assert ("theta_hat final" in out) == adapts and ("gamma_hat final" in out) == adapts
    assert "(mm or mrad)" not in out and " mm" in out and " mrad" in out


def test_a_run_that_saturates_its_valves_says_so_per_actuator(capsys, monkeypatch):
    """A valve at u_max in more than SATURATION of the periods: one summary line per actuator with what
    to change (the controller's own command gains), the fractions in res.metrics; a run that does
    not saturate gets no line."""
    import hydrogen
    from hydrogen.simulation.simulator import SATURATION
    from hydrogen.summary import saturation_lines

    tiny = {"u_max": [2e-4]}  # m of spool: a tenth of the stroke's need on z-1hz
    res = hydrogen.simulate("z-1hz", "p", duration=0.3, gains=tiny)
    by = res.metrics["u_saturation_frac_by_actuator"]
    assert list(by) == [c.name for c in hydrogen.load_model().cylinders]
    assert min(by.values()) > 0.3 and res.metrics["u_saturation_frac"] == pytest.approx(np.mean(list(by.values())))
    lines = saturation_lines(res)
    assert len(lines) == len(by) and lines[0] == (
        f"valve of leg1 saturated {100 * by['leg1']:.1f} % of the time (|u| at u_max = 0.2 mm, more than "
        f"{100 * SATURATION:g} %): lower the gains (Kleg), slow the reference, or raise u_max / a larger valve")
    res = hydrogen.simulate("z-1hz", "adaptive-robust", duration=0.3, gains=tiny)
    assert "lower the gains (Lambda, Kd, Ktau)" in saturation_lines(res)[0]
    out = _simulate_cli(capsys, "--scenario", "z-1hz", "--controller", "p")
    assert "saturated" not in out
    real = hydrogen.simulate
    # 1 um of spool: saturated within the CLI's 0.05 s
    monkeypatch.setattr(hydrogen, "simulate", lambda *a, **k: real(*a, gains={"u_max": [1e-6]}, **k))
    out = _simulate_cli(capsys, "--scenario", "z-1hz", "--controller", "p")
    assert out.count("% of the time (|u| at u_max") == len(by) and "valve of leg6 saturated" in out


def test_estimated_blocks_come_from_the_controllers_declared_state():
    import hydrogen
    from hydrogen.controllers import controller
    model = hydrogen.load_model()
    for name, expected in (("p", ()), ("adaptive-robust", ("theta_hat", "gamma1_hat", "gamma2_hat"))):
        res = hydrogen.simulate("z-1hz", name, duration=0.02)
        blocks = [b for b, _ in controller(name).state_layout(model)]
        assert res.estimated == expected == tuple(b for b in expected if b in blocks)


def test_commands_default_to_the_models_own_first_scenario(capsys, tmp_path):
    import hydrogen
    from hydrogen.cli import build_parser
    from hydrogen.simulation.scenarios import default_scenario_name, scenario_names
    for name in hydrogen.models():
        model = hydrogen.load_model(name)
        assert default_scenario_name(model) == scenario_names(model)[0]
    assert default_scenario_name(hydrogen.load_model("excavator_arm")) == "arm-sim"
    assert build_parser().parse_args(["export", "--out", "x"]).scenario is None
    out = _simulate_cli(capsys, "--model", "excavator_arm", "--controller", "p")
    if out.startswith("built in "):  # this run's first use of p on the arm compiled its library
        out = out.split("\n", 1)[1]
    assert out.startswith("scenario arm-sim, controller p")


def test_export_defaults_to_the_models_first_scenario(tmp_path):
    import json

    from hydrogen.export import EXPORT_MANIFEST, export
    folder = export(tmp_path / "arm", controller="p", model="excavator_arm", duration=0.05)
    meta = json.loads((folder / EXPORT_MANIFEST).read_text())
    assert meta["scenario"] == "arm-sim"


# --- progress of the long steps ----------------------------------------------------------------

def test_a_library_already_built_reports_loaded_and_prints_nothing(capsys):
    import hydrogen
    from hydrogen.progress import BuildEvent
    hydrogen.build(hydrogen.load_model())  # built (or found) first
    events = []
    hydrogen.build(hydrogen.load_model(), progress=events.append)
    assert [e.stage for e in events] == ["loaded"]
    assert isinstance(events[0], BuildEvent) and events[0].model == "ubc_stewart" and events[0].elapsed_s >= 0
    capsys.readouterr()
    _simulate_cli(capsys, "--controller", "p")
    err = capsys.readouterr().err
    assert "hydrogen:" not in err and "built in" not in err


def test_generation_reports_its_stages_on_stderr(tmp_path, capsys):
    from hydrogen.cli import main
    out = tmp_path / "gen"
    assert main(["generate", "--model", "excavator_arm", "--out", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err == ""  # --quiet: no progress at all
    assert main(["generate", "--model", "excavator_arm", "--out", str(out), "--force"]) == 0
    lines = [x for x in capsys.readouterr().err.splitlines() if x.startswith("hydrogen:")]
    assert lines[0].startswith("hydrogen: generating excavator_arm: deriving the model") and lines[0].endswith("...")
    assert re.fullmatch(r"hydrogen: generated excavator_arm: \d+ functions, [\d.]+ [kM]B of C, [\d.]+ s", lines[1])
    n = len(__import__("json").loads((out / "manifest.json").read_text())["functions"])
    assert f" {n} functions" in lines[1]
    # current: nothing to do, nothing said
    assert main(["generate", "--model", "excavator_arm", "--out", str(out)]) == 0
    assert "hydrogen:" not in capsys.readouterr().err


def test_build_reports_compilation_around_the_compiler_call(tmp_path, monkeypatch):
    """A private empty cache: the compile step is reported (the compiler itself is stood in by the
    shared cache's build of the same sources, so the test takes no minute of compiling)."""
    import hydrogen
    import hydrogen.runtime.build as hb
    from hydrogen.runtime.compiler import cache_root

    model = hydrogen.load_model()
    hydrogen.build(model)  # the shared cache holds the library
    real = hb.compile_libraries
    calls = []

    def compile_from_shared_cache(libraries, toolchain=None, cache=None, **kw):
        calls.append([len(sources) for sources, _ in libraries])
        return real(libraries, toolchain, cache=cache_root(), **kw)

    monkeypatch.setattr(hb, "compile_libraries", compile_from_shared_cache)
    events = []
    dyn = hydrogen.build(model, cache=tmp_path / "cache", backend="ctypes", progress=events.append)
    stages = [e.stage for e in events]
    assert stages == ["compiling", "compiled", "built"] and calls
    assert re.fullmatch(r"\d+ files, [\d.]+ [kM]B of C", events[0].detail) and events[0].elapsed_s == 0
    assert events[-1].detail == "compiled" and events[-1].elapsed_s >= events[1].elapsed_s >= 0
    assert dyn.library.path.name == events[1].detail
    with pytest.raises(TypeError, match="progress must be a callable"):
        hydrogen.build(model, progress="yes")


def test_print_event_one_line_per_stage():
    import io

    from hydrogen.progress import BuildEvent, print_event
    buf = io.StringIO()
    for stage, detail, t in (("compiling", "30 files, 1.9 MB of C", 0.0), ("compiled", "libx.so", 38.04),
                             ("loaded", "already built", 0.01), ("built", "generated + compiled", 41.2)):
        print_event(BuildEvent(stage, "ubc_stewart", detail, t), file=buf)
    assert buf.getvalue().splitlines() == [
        "hydrogen: compiling ubc_stewart: 30 files, 1.9 MB of C ...",
        "hydrogen: compiled ubc_stewart: libx.so, 38.0 s",
        "hydrogen: built ubc_stewart: generated + compiled, 41.2 s"]


def test_simulate_summary_gives_the_build_time_apart_from_the_run(capsys, monkeypatch):
    import hydrogen
    from hydrogen.progress import BuildEvent
    real = hydrogen.build

    def build_reporting(model, progress=None, **kw):
        dyn = real(model, **kw)
        progress(BuildEvent("built", model.name, "generated + compiled", 41.2))
        return dyn

    monkeypatch.setattr(hydrogen, "build", build_reporting)
    out = _simulate_cli(capsys, "--controller", "p")
    lines = out.splitlines()
    assert lines[0] == "built in 41.2 s (generated + compiled)"
    assert lines[1].startswith("scenario paper-sim, controller p: 0.05 s simulated in ")


def test_simulate_and_stepper_pass_progress_to_their_build(monkeypatch):
    import hydrogen
    import hydrogen.runtime.build as runtime_build
    for make in (lambda cb: hydrogen.simulate("z-1hz", "p", duration=0.01, progress=cb),
                 lambda cb: hydrogen.stepper("z-1hz", "p", progress=cb)):
        monkeypatch.setattr(runtime_build, "DEFAULT_DYNAMICS", {})  # this process has built nothing yet
        events = []
        make(events.append)
        assert [e.stage for e in events] in (["loaded"], ["compiling", "compiled", "built"],
                                             ["generating", "generated", "compiling", "compiled", "built"])


def test_figures_without_matplotlib_get_one_clear_message(monkeypatch, capsys, tmp_path):
    import builtins

    from hydrogen.cli import main
    real_import = builtins.__import__

    def no_matplotlib(name, *a, **kw):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError("No module named 'matplotlib'")
        return real_import(name, *a, **kw)

    monkeypatch.setattr(builtins, "__import__", no_matplotlib)
    assert main(["simulate", "--duration", "0.05", "--controller", "p", "--plot", str(tmp_path / "e.png")]) == 2
    err = capsys.readouterr().err
    assert "--plot (a figure file) needs matplotlib" in err and "hydrogen[plot]" in err and "Traceback" not in err


def _adapting_run(theta0, theta1, excitation):
    from types import SimpleNamespace

    true = np.array([250.0, 45.0])
    return SimpleNamespace(
        estimated=("theta_hat",), theta_names=("platform.mass", "platform.Ixx"), theta_true=true,
        theta_hat=np.array([true * theta0, true * theta1]), gamma_true=np.ones((2, 1)),
        metrics={"excitation": {"theta": excitation, "theta_least_excited": {"platform.Ixx": 1.0}}})


def test_a_run_whose_estimates_converge_gets_no_note():
    from hydrogen.summary import excitation_lines

    assert excitation_lines(_adapting_run(1.2, 1.01, 0.05)) == []


@pytest.mark.parametrize("end, excitation, words", [
    (1.19, 1e-6, "barely excites theta .* least excited: platform.Ixx"),
    (1.19, 0.05, "adaptation is slow: raise rate_theta"),
    (1.4, 0.05, "moved away from the true values"),
])
def test_a_run_whose_estimates_do_not_converge_says_which_and_what_to_do(end, excitation, words):
    import re

    from hydrogen.summary import excitation_lines

    lines = excitation_lines(_adapting_run(1.2, end, excitation))
    assert len(lines) == 1 and "platform.mass +20.0 %" in lines[0] and re.search(words, lines[0]), lines


def test_tune_prints_gains_toml_reads_back_exactly_to_six_digits():
    """The [gains.<controller>] block `hydrogen tune` prints: a 4e-9 adaptation rate stays 4e-9 (it
    once printed as 0.0), and every number reads back as a float."""
    import tomllib

    from hydrogen.cli import _toml_number

    for v in (4e-9, 11.892071, 30, [15000.0, 2.5e-10], 1e20):
        back = tomllib.loads(f"a = {_toml_number(v)}")["a"]
        want = [float(f"{x:.6g}") for x in v] if isinstance(v, list) else float(f"{v:.6g}")
        assert back == want and all(isinstance(x, float) for x in (back if isinstance(back, list) else [back]))
