"""hydrogen.export: a self-contained C99 folder that builds with make and reproduces the simulator."""
import json
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

from hydrogen.errors import OutputPathError
from hydrogen.export import EXPORT_MANIFEST, export
from hydrogen.simulation.scenarios import scenario as named_scenario
from hydrogen.simulation.simulator import simulate
from controller_inputs import PAPER_LAWS

pytestmark = pytest.mark.skipif(shutil.which("make") is None or shutil.which("cc") is None,
                                reason="needs make and cc")


def _build(folder):
    proc = subprocess.run(["make"], cwd=folder, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


def _run(folder):
    prog = json.loads((folder / EXPORT_MANIFEST).read_text())["program"]
    proc = subprocess.run([str(folder / prog)], cwd=folder, capture_output=True, text=True, timeout=600)
    out = {"max_error": {}, "error_shown": {}}
    for line in proc.stdout.splitlines():
        key, *rest = line.split()
        if key == "max_error":
            # max_error <coord> <SI value> <SI unit>  <pct> % of amplitude  <value> <mm|mrad>
            out["max_error"][rest[0]] = float(rest[1])
            out["error_shown"][rest[0]] = (rest[2], None if rest[3] == "-" else float(rest[3]),
                                           float(rest[-2]), rest[-1])
        else:
            out[key] = rest[0]
    assert proc.returncode == (0 if out.get("status") == "0" else 1), proc.stdout + proc.stderr
    return out


def _python_max_errors(dyn, scenario, controller, duration, metric_start, **overrides):
    # every noise off, each actuator's own too (the crane's slew reads its angle with its own noise)
    quiet = named_scenario(scenario, dyn.model).noise_free()
    res = simulate(dyn, scenario, controller, duration=duration, metric_start=metric_start, **quiet, **overrides)
    sel = res.t >= metric_start - 1e-12
    assert sel.any() and (~sel).any()  # the window starts inside the run
    return np.abs(res.error[sel]).max(axis=0), len(res.t)


@pytest.mark.parametrize("model_name, scenario, controller, duration, metric_start, numbers", [
    ("ubc_stewart", "z-1hz", "adaptive-robust", 1.0, 0.5, "inputs"),
    ("ubc_stewart", "z-step", "p", 1.5, 0.5, "inputs"),
    ("excavator_arm", "arm-dig", "adaptive-observer", 1.0, 0.5, "inputs"),
    ("excavator_arm", "arm-sim", "backstepping", 1.0, 0.5, "inputs"),
    ("loader_crane", "crane-load", "adaptive-robust", 1.0, 0.5, "inputs"),
    ("excavator_arm", "arm-dig", "adaptive-robust", 1.0, 0.5, "constants"),
])
def test_exported_program_matches_the_noise_free_simulation(tmp_path, cache, model_name, scenario, controller,
                                                           duration, metric_start, numbers):
    import hydrogen
    dyn = hydrogen.build(hydrogen.load_model(model_name), cache=cache, numbers=numbers)
    folder = export(tmp_path / "export", scenario, controller, duration=duration, dyn=dyn,
                    metric_start=metric_start)
    if numbers == "inputs":  # params.h: the description's numbers, one named entry a line
        params = (folder / "params.h").read_text()
        for k, name in enumerate(dyn.library.manifest["numbers"]):
            assert f"/* {k}: {name} */" in params
    got, out, build = reproduces_the_simulation(folder, dyn, scenario, controller, duration, metric_start)
    assert "-Werror" in build.stdout and "-std=c99" in build.stdout and "-lm" in build.stdout
    assert got.max() > 1e-8  # errors of a tracked reference, far above the tolerance: not trivially zero
    # the same figures as 'hydrogen simulate' prints: SI unit, % of amplitude ("-" where the reference
    # does not move the coordinate), mm or mrad
    amplitude = named_scenario(scenario, dyn.model).reference.amplitude()
    for i, c in enumerate(dyn.model.coordinate_names):
        unit, pct, shown, shown_unit = out["error_shown"][c]
        assert unit == dyn.model.coordinate_units[i]
        assert shown_unit == ("mrad" if unit == "rad" else "mm")
        assert shown == pytest.approx(1e3 * got[i], abs=1e-4)
        if amplitude[i] > 0:
            assert pct == pytest.approx(100 * got[i] / amplitude[i], abs=0.006)
        else:
            assert pct is None


def test_export_folder_contents(tmp_path, dyn):
    # the paper's gradient laws (composite weights 0): the lean variant is exported
    folder = export(tmp_path / "out", "z-1hz", "adaptive-robust", duration=0.2, dyn=dyn,
                    gains=PAPER_LAWS)
    meta = json.loads((folder / EXPORT_MANIFEST).read_text())
    names = {p.name for p in folder.iterdir()}
    m = dyn.model.name
    expected = {"main.c", "params.h", "Makefile", "CMakeLists.txt", "README.txt", EXPORT_MANIFEST}
    for f in ("leg_lengths", "leg_kinematics", "plant_rhs", "leg_force", "ctrl_adaptive_robust_lean",
              "ctrl_adaptive_robust_lean_step", "loop"):
        expected |= {f"{m}_{f}.c", f"{m}_{f}.h"}
    assert names == expected
    # sources are byte copies of what the library was compiled from
    for name, digest in dyn.library.manifest["files"].items():
        if name in names:
            assert meta["files"][name] == digest
    params = (folder / "params.h").read_text()
    sc = named_scenario("z-1hz", dyn.model)
    assert f"#define P_N_PERIODS {int(round(0.2 * sc.control_rate)) + 1}LL" in params
    for name in ("P_CTRL_Gz_inv[6]", "P_CTRL_Lambda[6]", "P_XC0[P_XC_CAP]", "P_X0[30]", "P_L0[6]",
                 "P_KF_GAIN[2]", "P_THETA[4]", "P_REF_TERMS"):
        assert name in params
    # where each declared block of the state starts in xc, with its role (and unit where declared)
    assert "#define P_XC_AT_Z 0  /* 6 entries: the robust sliding observer's velocity estimate (z), m" in params
    assert "#define P_XC_AT_THETA_HAT 6  /* " in params and "#define P_XC_AT_GAMMA_GAIN " in params
    assert "noise" in (folder / "main.c").read_text() and "make run" in (folder / "README.txt").read_text()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.new-")]  # staging cleaned up
    # the lean controller's composite gains are in params.h (every input has a value) but marked unread
    line = next(x for x in params.splitlines() if x.startswith("static const double P_CTRL_rate_ls_theta["))
    assert "not read by" in line
    assert "not read by" not in next(x for x in params.splitlines() if x.startswith("static const double P_CTRL_Lambda["))


def test_export_replaces_an_earlier_export_and_refuses_other_folders(tmp_path, dyn):
    target = tmp_path / "out"
    export(target, "z-step", "p", duration=0.1, dyn=dyn)
    # what its own Makefile builds there (make clean's list) goes with the folder
    meta = json.loads((target / EXPORT_MANIFEST).read_text())
    products = [meta["program"]] + [n[:-2] + ".o" for n in meta["files"] if n.endswith(".c")]
    for name in products:
        (target / name).write_bytes(b"built")
    export(target, "z-step", "p", duration=0.2, dyn=dyn)
    assert not [n for n in products if (target / n).exists()]
    assert json.loads((target / EXPORT_MANIFEST).read_text())["duration_s"] == 0.2
    # a file the user added, or a file edited since the export, is never deleted: refused, naming it
    (target / "notes.txt").write_text("keep me")
    with pytest.raises(OutputPathError, match=r"holds notes.txt, which hydrogen did not write .*nothing was written"):
        export(target, "z-step", "p", duration=0.3, dyn=dyn)
    assert (target / "notes.txt").read_text() == "keep me"
    assert json.loads((target / EXPORT_MANIFEST).read_text())["duration_s"] == 0.2
    (target / "notes.txt").unlink()
    (target / "build").mkdir()  # cmake -B build: the user's build tree, not hydrogen's
    with pytest.raises(OutputPathError, match="holds build, which hydrogen did not write"):
        export(target, "z-step", "p", duration=0.3, dyn=dyn)
    (target / "build").rmdir()
    with open(target / "params.h", "a") as fh:
        fh.write("/* tuned by hand */\n")
    with pytest.raises(OutputPathError, match="holds params.h, edited since hydrogen wrote it"):
        export(target, "z-step", "p", duration=0.3, dyn=dyn)
    assert (target / "params.h").read_text().endswith("/* tuned by hand */\n")
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    with pytest.raises(FileExistsError):
        export(other, "z-step", "p", duration=0.1, dyn=dyn)
    assert (other / "notes.txt").read_text() == "keep me"


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
def test_cmake_build_with_werror(tmp_path, dyn):
    folder = export(tmp_path / "export", "z-step", "p", duration=0.5, dyn=dyn)
    for argv in (["cmake", "-S", ".", "-B", "build", "-DHG_WERROR=ON"], ["cmake", "--build", "build"]):
        proc = subprocess.run(argv, cwd=folder, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    prog = json.loads((folder / EXPORT_MANIFEST).read_text())["program"]
    proc = subprocess.run([str(folder / "build" / prog)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and "status 0" in proc.stdout


def _edit_number(params: str, name: str, value: str) -> str:
    """params.h with the description's number ``name`` (one entry a line, named in a comment) set to ``value``."""
    import re
    edited, n = re.subn(rf"^(    )[^,\n]+(,  /\* \d+: {re.escape(name)} \*/)$", rf"\g<1>{value}\g<2>", params,
                        flags=re.M)
    assert n == 1, name
    return edited


@pytest.mark.parametrize("name, value, message", [
    ("boom.mass", "-3.0", "params.h: number 'boom.mass' = -3 is outside [1e-06, 1000000]"),
    ("gravity", "NAN", "params.h: number 'gravity' = nan is outside [0, 30]"),
    ("boom_cylinder.cap_area", "0.0", "params.h: number 'boom_cylinder.cap_area' = 0 is outside [1e-08, 10]"),
    ("boom_cylinder.annulus_area", "1.0", "params.h: number 'boom_cylinder.annulus_area' = 1 must be <= number "
     "'boom_cylinder.cap_area' = 0.022619 (the annulus is the cap area less the rod's section)"),
])
def test_an_edited_number_outside_its_range_is_named_and_nothing_runs(tmp_path, cache, name, value, message):
    """params.h's numbers may be edited on the target: the program checks them against the
    description's ranges and the order of a cylinder's constants (rendered from hydrogen.model) and
    names the first bad one, exiting 2 before it runs; the unedited export runs."""
    import hydrogen
    dyn = hydrogen.build(hydrogen.load_model("excavator_arm"), cache=cache, numbers="inputs")
    folder = export(tmp_path / "export", "arm-sim", "p", duration=0.05, dyn=dyn)
    params = folder / "params.h"
    params.write_text(_edit_number(params.read_text(), name, value))
    proc = subprocess.run(["make", "-s", "run"], cwd=folder, capture_output=True, text=True, timeout=600)
    assert proc.returncode != 0
    assert message in proc.stderr, proc.stderr
    assert "status" not in proc.stdout  # refused before the loop ran



def dashed_arm(folder):
    """The shipped excavator arm with a '-' in a link's name and a cylinder's (the name rule allows
    it: hydrogen.names.check_name), written into ``folder`` and loaded."""
    import re

    import hydrogen
    data = hydrogen.model.model_path("excavator_arm").parent
    toml = (data / "excavator_arm.toml").read_text()
    toml = toml.replace('name = "boom_cylinder"', 'name = "boom-cylinder"')
    toml = toml.replace('link = "boom"', 'link = "boom-link"').replace('"boom.', '"boom-link.')
    urdf = re.sub(r'(link|name)="boom"', r'\1="boom-link"', (data / "excavator_arm.urdf").read_text())
    (folder / "excavator_arm.toml").write_text(toml)
    (folder / "excavator_arm.urdf").write_text(urdf)
    model = hydrogen.load_model(folder / "excavator_arm.toml")
    assert "boom-cylinder" in [c.name for c in model.cylinders] and "boom-link.mass" in model.numbers()
    return model


def test_names_with_a_dash_export_and_run(tmp_path, cache):
    """A '-' in a link's or cylinder's name reaches only comments and strings of the exported C (the
    numbers' names in params.h), never an identifier: the export builds, runs and checks its numbers."""
    import hydrogen
    dyn = hydrogen.build(dashed_arm(tmp_path), cache=cache, numbers="inputs")
    folder = export(tmp_path / "export", "arm-sim", "p", duration=0.05, dyn=dyn)
    params = (folder / "params.h").read_text()
    assert ": boom-cylinder.cap_area */" in params and '"boom-link.mass",' in params
    _build(folder)
    assert _run(folder)["status"] == "0"
    params_h = folder / "params.h"
    params_h.write_text(_edit_number(params, "boom-link.mass", "-1.0"))
    proc = subprocess.run(["make", "-s", "run"], cwd=folder, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 2 and "number 'boom-link.mass' = -1 is outside" in proc.stderr, proc.stderr


def test_an_export_from_the_committed_folder_takes_no_lock_there(tmp_path, dyn, monkeypatch):
    """The committed generated/ is only read (its recorded hashes catch a changed file): an export
    from it locks nothing in the checkout, so builds into other caches never wait on it."""
    from contextlib import contextmanager

    import hydrogen.fileio as fileio
    from hydrogen.runtime.build import repo_generated_dir

    assert dyn.library.generated_dir == repo_generated_dir() / dyn.model.name
    real, taken = fileio.locked, []

    @contextmanager
    def recorded(path, timeout=None):
        taken.append(pathlib.Path(path))
        with real(path, timeout):
            yield
    monkeypatch.setattr(fileio, "locked", recorded)
    folder = export(tmp_path / "out", "z-1hz", "p", duration=0.1, dyn=dyn)
    assert (folder / "params.h").is_file()
    assert not [p for p in taken if p.is_relative_to(repo_generated_dir())], taken


def test_an_export_of_a_new_robot_derives_its_controller_alone(tmp_path, monkeypatch):
    import hydrogen
    import hydrogen.runtime.build as runtime_build
    from hydrogen.codegen.generate import held_controllers

    monkeypatch.setenv("HYDROGEN_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(runtime_build, "DEFAULT_DYNAMICS", {})
    arm = pathlib.Path(__file__).parent / "data" / "four_way_arm.toml"
    folder = export(tmp_path / "out", "arm-sim", "p", duration=0.05, model=str(arm))
    assert (folder / "params.h").is_file()
    (lib,) = runtime_build.DEFAULT_DYNAMICS.values()
    assert held_controllers(lib.manifest) == ("p",)


def test_an_exported_program_on_a_pump_matches_the_simulation(tmp_path, cache):
    """A robot on a pump (tests/test_supply.py's): the exported program integrates the supply state,
    its numbers are named parameters in params.h, and its errors are the simulator's."""
    import hydrogen
    from test_model import mixed_arm_text
    from test_supply import PUMP_TABLE
    path = tmp_path / "pump_arm.toml"
    path.write_text(mixed_arm_text("four_way") + PUMP_TABLE)
    dyn = hydrogen.build(hydrogen.load_model(path), cache=cache, numbers="inputs")
    folder = export(tmp_path / "export", "arm-sim", "adaptive-robust", duration=0.5, dyn=dyn, metric_start=0.25)
    params = (folder / "params.h").read_text()
    assert "supply.pump_flow */" in params and "supply.precharge_pressure */" in params
    with_feedback, _, _ = reproduces_the_simulation(folder, dyn, "arm-sim", "adaptive-robust", 0.5, 0.25)
    # the controller assuming a constant supply: the program's configuration says so, and runs as the simulator
    folder = export(tmp_path / "constant", "arm-sim", "adaptive-robust", duration=0.5, dyn=dyn, metric_start=0.25,
                    supply_feedback=False)
    params = (folder / "params.h").read_text()
    assert "#define P_SUPPLY_FEEDBACK 0LL" in params and "P_PS_NOMINAL = 10000000.0;" in params
    assumed, _, _ = reproduces_the_simulation(folder, dyn, "arm-sim", "adaptive-robust", 0.5, 0.25,
                                              supply_feedback=False)
    assert np.abs(assumed - with_feedback).max() > 1e-9


def reproduces_the_simulation(folder, dyn, scenario, controller, duration, metric_start, **overrides) -> tuple:
    """Build and run the exported program in ``folder``: it completes, over the periods of the Python
    loop's run (with the scenario ``overrides`` the export was given), with its max errors to 1e-9;
    returns them, the program's output and its build."""
    build = _build(folder)
    out = _run(folder)
    assert out["status"] == "0"
    expected, n = _python_max_errors(dyn, scenario, controller, duration, metric_start, **overrides)
    assert int(out["periods"]) == n
    got = np.array([out["max_error"][c] for c in dyn.model.coordinate_names])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-13)
    return got, out, build


@pytest.mark.parametrize("window", ["last sample", "last two samples", "after the run"])
def test_the_program_takes_the_metric_window_as_the_simulation_does(tmp_path, cache, window):
    """A window holding the run's last period alone, its last two, or none: the exported program's max
    errors are the metrics simulate reports (a window of fewer than two samples is the whole run in
    both, and simulate says so)."""
    import hydrogen
    dyn = hydrogen.build(hydrogen.load_model("ubc_stewart"), cache=cache, controllers=("p",))
    duration, quiet = 0.25, named_scenario("z-1hz", dyn.model).noise_free()
    t = simulate(dyn, "z-1hz", "p", duration=duration, **quiet).t
    metric_start = {"last sample": t[-1], "last two samples": t[-2], "after the run": 10.0}[window]
    res = simulate(dyn, "z-1hz", "p", duration=duration, metric_start=metric_start, **quiet)
    folder = export(tmp_path / "export", "z-1hz", "p", duration=duration, dyn=dyn, metric_start=metric_start)
    _build(folder)
    out = _run(folder)
    assert int(out["periods"]) == len(res.t)
    for c in dyn.model.coordinate_names:
        assert out["max_error"][c] == pytest.approx(res.metrics["max_error"][c], rel=1e-9, abs=1e-13), c
    assert ("metric_note" in res.metrics) == (window != "last two samples")


def test_the_readmes_simulate_call_reproduces_the_program_on_another_robot(tmp_path, cache):
    """The README.txt of an export names the call whose errors the program's equal: evaluated as
    written (the crane, an actuator's own setting given too), it runs the same periods and gives the
    program's max errors."""
    import re

    import hydrogen
    dyn = hydrogen.build(hydrogen.load_model("loader_crane"), cache=cache, controllers=("backstepping",))
    folder = export(tmp_path / "export", "crane-load", "backstepping", duration=0.3, dyn=dyn, metric_start=0.1,
                    actuators={"slew_motor": {"quantization_l": 2e-5}})
    call = re.search(r"^  (hydrogen\.simulate\(.*\))$", (folder / "README.txt").read_text(), re.MULTILINE)[1]
    assert "model='loader_crane'" in call and call.count("actuators=") == 1
    res = eval(call, {"hydrogen": hydrogen})  # noqa: S307 - the README's own text, written by this test
    _build(folder)
    out = _run(folder)
    assert int(out["periods"]) == len(res.t)
    for c in dyn.model.coordinate_names:
        assert out["max_error"][c] == pytest.approx(res.metrics["max_error"][c], rel=1e-9, abs=1e-13), c
