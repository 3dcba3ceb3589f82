"""hydrogen.fmu: FMI 2.0 co-simulation FMUs of the plant, a controller and the closed loop, checked with fmpy."""
import ctypes
import hashlib
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import extract, read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, defaultCallbacks  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

from hydrogen.errors import FmuError, HydrogenError, OutputPathError  # noqa: E402
from hydrogen.fmu import FMI_HEADERS, PARTS, _number_variable, export_fmu, fmi_headers_dir  # noqa: E402
from hydrogen.simulation.simulator import simulate  # noqa: E402
from hydrogen.actuators import actuator  # noqa: E402
from hydrogen.pressures import bounds as pressure_bounds  # noqa: E402
from hydrogen.simulation.scenarios import actuator_settings  # noqa: E402
from controller_inputs import PAPER_LAWS  # noqa: E402
from reference import singular_pose  # noqa: E402


def _pressure_variables(model, suffix=""):
    """``<state><suffix>.<cylinder>`` of every chamber pressure, in the pressure vector's order (the
    state names from each cylinder's actuator kind: pc for a three-way cylinder, pA and pB for a
    four-way one)."""
    return [f"{s.name}{suffix}.{c.name}" for c in model.cylinders for s in actuator(c.kind).STATES]


pytestmark = pytest.mark.skipif(shutil.which("cc") is None and "CC" not in os.environ, reason="needs a C compiler")

#: Per robot: a scenario and a controller that together cover both sensor paths (Kalman filter and
#: forward kinematics; ideal rate sensor and joint encoders) and an adapting controller.
CASES = {"ubc_stewart": ("z-1hz", "p"), "excavator_arm": ("arm-sim", "adaptive-robust")}
DURATION = 0.3


def _case(dyn):
    from hydrogen.simulation.scenarios import default_scenario_name
    return CASES.get(dyn.model.name, (default_scenario_name(dyn.model), "adaptive-robust"))


def _reference_run(dyn, scenario, controller, duration=DURATION, **overrides):
    kw = {"noise_l": 0.0, "noise_p": 0.0, **overrides}
    if dyn.model.joint_encoders:
        kw["noise_q"] = 0.0
    return simulate(dyn, scenario, controller, duration=duration, **kw)


@pytest.fixture(scope="module")
def fmus(robot_dyn, shared_fmu):
    """The three parts of one robot's case, exported once per run (shared by the workers)."""
    scenario, controller = _case(robot_dyn)
    paths = {part: shared_fmu(robot_dyn, part, scenario, controller, duration=DURATION) for part in PARTS}
    return robot_dyn, scenario, controller, paths


class Slave:
    """An FMU2Slave with its variables by name; log messages collected."""

    def __init__(self, path, name, stop_time=None):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.var = {v.name: v for v in self.md.modelVariables}
        self.h = float(self.md.defaultExperiment.stepSize)
        self.messages = []

        def log(env, instance, status, category, message):
            self.messages.append(message.decode())

        self._logger = fmi2CallbackLoggerTYPE(log)
        cb = fmi2CallbackFunctions()
        cb.logger = self._logger
        cb.allocateMemory = defaultCallbacks.allocateMemory
        cb.freeMemory = defaultCallbacks.freeMemory
        self._cb = cb
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(str(path)),
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=cb)
        self.fmu.setupExperiment(startTime=0.0, stopTime=stop_time)
        self.fmu.enterInitializationMode()

    def names(self, prefix):
        return [n for n in self.vr if n.startswith(prefix)]

    def get(self, names):
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def set(self, names, values):
        self.fmu.setReal([self.vr[n] for n in names], [float(v) for v in values])

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def _cosimulate(plant_path, controller_path, n, controller=None, reference=None):
    """The master loop: per period, the plant's outputs at t into the controller (inputs matched by name),
    a controller step, its u into the plant, a plant step. ``controller`` (a Python function of the plant
    outputs and t) replaces the controller FMU; ``reference(t)`` feeds the q_d inputs. Returns q (n, nq)."""
    plant = Slave(plant_path, "plant")
    coords = [n_[2:] for n_ in plant.names("q.")]
    q_names, u_names = [f"q.{c}" for c in coords], plant.names("u.")
    plant.fmu.exitInitializationMode()
    ctl = None
    if controller_path is not None:
        ctl = Slave(controller_path, "controller")
        wires = [n_ for n_, v in ctl.var.items() if v.causality == "input" and n_ in plant.vr]
        ref_names = [[f"{b}.{c}" for c in coords] for b in ("q_d", "q_d_dot", "q_d_ddot", "q_d_dddot")]
        ref_names = [r for r in ref_names if r[0] in ctl.vr]
        if reference is not None:
            ctl.fmu.setBoolean([ctl.vr["use_builtin_reference"]], [False])
        ctl.set(wires, plant.get(wires))
        ctl.fmu.exitInitializationMode()
    q = np.empty((n, len(coords)))
    h = plant.h
    for k in range(n):
        t = k * h
        q[k] = plant.get(q_names)
        if ctl is not None:
            ctl.set(wires, plant.get(wires))
            if reference is not None:
                for names, values in zip(ref_names, reference(t)):
                    ctl.set(names, values)
            ctl.fmu.doStep(t, h)
            u = ctl.get(u_names)
        else:
            u = controller({n_: plant.get([n_])[0] for n_ in plant.names(("l.", "q."))}, t)
        plant.set(u_names, u)
        plant.fmu.doStep(t, h)
    plant.close()
    if ctl is not None:
        ctl.close()
    return q


def test_each_part_validates(fmus):
    for part, path in fmus[3].items():
        assert validate_fmu(str(path)) == [], part


def test_closed_loop_fmu_reproduces_simulate(fmus):
    dyn, scenario, controller, paths = fmus
    res = _reference_run(dyn, scenario, controller)
    coords, cyls = dyn.model.coordinate_names, [c.name for c in dyn.model.cylinders]
    theta = [f"theta_hat.{t}" for t in dyn.model.theta_names]
    out = simulate_fmu(str(paths["closed-loop"]), output=[f"q.{c}" for c in coords] + [f"q_d.{c}" for c in coords]
                       + [f"u.{c}" for c in cyls] + theta)
    assert len(out) == len(res.t)
    np.testing.assert_allclose(out["time"], res.t, rtol=0, atol=1e-12)
    q = np.column_stack([out[f"q.{c}"] for c in coords])
    np.testing.assert_allclose(q, res.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.column_stack([out[f"q_d.{c}"] for c in coords]), res.q_d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.column_stack([out[f"u.{c}"] for c in cyls]), res.u, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.column_stack([out[t] for t in theta]), res.theta_hat, rtol=1e-12)
    assert np.abs(res.q - res.q_d).max() > 1e-5  # the robot moves: not trivially equal


def test_plant_and_controller_fmus_reproduce_the_closed_loop(fmus):
    dyn, scenario, controller, paths = fmus
    # between parts the master's step order is the timing: the parts carry no computation delay
    res = _reference_run(dyn, scenario, controller, delay=0.0)
    q = _cosimulate(paths["plant"], paths["controller"], len(res.t))
    np.testing.assert_allclose(q, res.q, rtol=0, atol=1e-9)


def test_controller_fmu_follows_an_external_reference(fmus):
    """q_d and its derivatives as inputs (use_builtin_reference = false), fed with the scenario's own
    reference computed in Python: the same run, to the rounding of sin and cos."""
    dyn, scenario, controller, paths = fmus
    res = _reference_run(dyn, scenario, controller, delay=0.0)  # parts: no computation delay
    from hydrogen.simulation.scenarios import scenario as named_scenario
    sc = named_scenario(scenario, dyn.model)
    q = _cosimulate(paths["plant"], paths["controller"], len(res.t), reference=sc.reference)
    np.testing.assert_allclose(q, res.q, rtol=0, atol=1e-9)


def test_a_python_p_controller_drives_the_plant_fmu(dyn, shared_fmu):
    """The README's example: a user's P controller on the cylinder lengths, in Python, drives the plant
    FMU; written like hydrogen's own P controller, it reproduces hydrogen.simulate(..., "p")."""
    from hydrogen.simulation.scenarios import scenario as named_scenario

    plant = shared_fmu(dyn, "plant", "z-1hz", "p", duration=DURATION)  # the plant part ignores the controller
    from hydrogen.simulation.simulator import prepare_run

    sc = named_scenario("z-1hz", dyn.model)
    values = prepare_run(dyn, sc, "p", None, DURATION, True, {}).ctrl.values  # hydrogen's own P gains
    K, u_max = np.asarray(values["Kleg"], float), float(values["u_max"][0])
    cyls = [c.name for c in dyn.model.cylinders]

    def p_controller(y, t):
        l_d = dyn.leg_lengths(sc.reference(t)[0])
        l = np.array([y[f"l.{c}"] for c in cyls])
        return np.clip(K * (l_d - l), -u_max, u_max)

    # the Python master applies each command at once, on exact lengths: no delay, no quantisation
    res = _reference_run(dyn, "z-1hz", "p", delay=0.0, quantization_l=0.0)
    q = _cosimulate(plant, None, len(res.t), controller=p_controller)
    np.testing.assert_allclose(q, res.q, rtol=0, atol=1e-9)
    assert np.abs(q - res.q_d).max() > 1e-5


def test_step_must_be_whole_periods(fmus):
    dyn, scenario, controller, paths = fmus
    plant = Slave(paths["plant"], "plant")
    plant.fmu.exitInitializationMode()
    h = plant.h
    with pytest.raises(FMICallException):
        plant.fmu.doStep(0.0, 1.5 * h)
    assert any("not a whole number of control periods" in m for m in plant.messages), plant.messages
    q0 = plant.get(plant.names("q."))
    plant.fmu.doStep(0.0, 3 * h)  # nothing was done by the refused step; three periods at once are fine
    q3 = plant.get(plant.names("q."))
    with pytest.raises(FMICallException):
        plant.fmu.doStep(0.0, h)  # not the FMU's time
    assert any("is not this FMU's time" in m for m in plant.messages)
    with pytest.raises(FMICallException):  # parameters are fixed after initialization
        plant.set([plant.names("theta.")[0]], [1.0])
    assert any("is fixed" in m for m in plant.messages)
    plant.close()
    # the same three periods one at a time
    again = Slave(paths["plant"], "again")
    again.fmu.exitInitializationMode()
    for k in range(3):
        again.fmu.doStep(k * h, h)
    np.testing.assert_array_equal(again.get(again.names("q.")), q3)
    again.close()
    assert np.all(np.isfinite(q0))


def test_model_description(fmus):
    dyn, scenario, controller, paths = fmus
    model = dyn.model
    coords, cyls = list(model.coordinate_names), [c.name for c in model.cylinders]
    from hydrogen.simulation.scenarios import scenario as named_scenario
    sc = named_scenario(scenario, model)
    for part, path in paths.items():
        md = read_model_description(str(path))
        assert md.fmiVersion == "2.0" and md.coSimulation is not None and md.modelExchange is None
        assert float(md.defaultExperiment.stepSize) == 1.0 / sc.control_rate
        units = {u.name for u in md.unitDefinitions}
        assert {"m", "Pa"} <= units
        by = {v.name: v for v in md.modelVariables}
        for v in md.modelVariables:
            assert v.description
            if v.causality in ("input", "parameter"):
                assert v.start is not None
                assert v.variability == ("continuous" if v.causality == "input" else "fixed")
        assert all(by[f"u.{c}"].unit == "m" for c in cyls)
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            ident = md.coSimulation.modelIdentifier
            assert {"modelDescription.xml", f"binaries/linux64/{ident}.so", "documentation/index.html",
                    f"sources/{model.name}_loop.c", "sources/fmu.c", "sources/params.h"} <= names
            for h in FMI_HEADERS:  # taken from fmpy's installed copy, byte for byte
                assert zf.read(f"sources/{h}") == (fmi_headers_dir() / h).read_bytes()
            for name, digest in dyn.library.manifest["files"].items():
                if f"sources/{name}" in names:
                    assert hashlib.sha256(zf.read(f"sources/{name}")).hexdigest() == digest
        if part != "plant":  # every block of the controller's state, as it declares it, with its unit
            from hydrogen.controllers import controller as controller_module
            blocks = controller_module(controller).state_layout(model)
            for b in blocks:
                for nm, unit in zip(b.entry_names(model), b.units(model)):
                    v = by[f"{b.name}{nm}" if nm.startswith("[") else f"{b.name}.{nm}"]
                    assert v.causality == "output" and v.unit == unit and b.role in v.description
            assert blocks or controller == "p"
        if part == "plant":
            assert {f"q.{c}" for c in coords} | {f"l.{c}" for c in cyls} | set(_pressure_variables(model)) <= set(by)
            assert by[f"q_start.{coords[0]}"].causality == "parameter"
            q0 = sc.reference(0.0)[0] + np.asarray(sc.q0_offset, float)
            assert [float(by[f"q_start.{c}"].start) for c in coords] == q0.tolist()
            assert [by[f"q.{c}"].unit for c in coords] == list(model.coordinate_units)
            assert by[f"theta.{model.theta_names[0]}"].causality == "parameter"
            assert by[f"u.{cyls[0]}"].causality == "input"
        elif part == "controller":
            assert by["use_builtin_reference"].type == "Boolean"
            assert by[f"l.{cyls[0]}"].causality == "input" and by[f"u.{cyls[0]}"].causality == "output"
            assert f"theta_hat.{model.theta_names[0]}" in by and f"gamma1_hat.{cyls[0]}" in by
            assert (f"q.{coords[0]}" in by) == bool(model.joint_encoders)
        else:  # the closed loop: no input; its parameters are the description's numbers alone
            assert not [v for v in md.modelVariables if v.causality == "input"]
            params = [v.name for v in md.modelVariables if v.causality == "parameter"]
            assert len(params) == len(dyn.library.manifest["numbers"])
            assert all(n.startswith("numbers.") for n in params)


def test_export_is_deterministic(dyn, tmp_path, shared_fmu):
    """Two exports with the same arguments are byte-identical (the first is the run's shared one,
    possibly written by another worker process)."""
    a = shared_fmu(dyn, "plant", "z-1hz", "p", duration=DURATION)
    earlier = tmp_path / "b.fmu"  # an earlier export of hydrogen's at the path: replaced whole, as a new file
    shutil.copyfile(a, earlier)
    inode = earlier.stat().st_ino
    b = export_fmu(earlier, "plant", "z-1hz", "p", dyn=dyn, duration=DURATION)
    assert a != b and a.read_bytes() == b.read_bytes() and b.stat().st_ino != inode


def test_a_second_export_compiles_only_its_own_glue(dyn, tmp_path, monkeypatch):
    """The generated sources an export shares with the robot's other exports are compiled once into
    the object store of the cache the dynamics were built in: another export of the same robot
    compiles its glue (and the controller it adds) only, the glue is never stored, and the FMU is the
    same as one compiled whole."""
    from test_compiler import _compiled, _logging_cc

    from hydrogen.runtime.compiler import Toolchain

    store = tmp_path / "cache" / "objects"
    monkeypatch.setattr(dyn.library, "cache_root", tmp_path / "cache")  # the store of the build's cache
    cc, log = _logging_cc(tmp_path)
    tc = Toolchain(cc=cc)
    export_fmu(tmp_path / "plant.fmu", "plant", "z-1hz", "p", dyn=dyn, duration=DURATION, toolchain=tc)
    first = _compiled(log)
    assert "fmu.c" in first and f"{dyn.model.name}_plant_rhs.c" in first
    stored = sorted(store.glob("*.o"))
    assert len(stored) == len(first) - 1  # every source but the glue (new with every export's settings)
    log.unlink()
    again = export_fmu(tmp_path / "again.fmu", "plant", "z-2hz", "p", dyn=dyn, duration=DURATION, toolchain=tc)
    assert _compiled(log) == ["fmu.c"] and sorted(store.glob("*.o")) == stored
    log.unlink()
    loop = export_fmu(tmp_path / "loop.fmu", "closed-loop", "z-1hz", "p", dyn=dyn, duration=DURATION, toolchain=tc)
    assert sorted(_compiled(log)) == sorted(["fmu.c", f"{dyn.model.name}_ctrl_p.c"])
    # the same bytes as an export that compiles everything (no store: a read-only cache)
    monkeypatch.setattr("hydrogen.runtime.compiler.object_store", lambda root=None: None)
    whole = export_fmu(tmp_path / "whole.fmu", "plant", "z-2hz", "p", dyn=dyn, duration=DURATION)
    assert again.read_bytes() == whole.read_bytes()
    assert loop.exists()


def test_a_compile_error_names_the_source_as_the_fmu_holds_it(dyn, tmp_path):
    """A source that does not compile is named sources/<file> (where the FMU keeps it), never by the
    scratch folder the export compiled in and removed."""
    from hydrogen.errors import CompilerError
    from hydrogen.runtime.compiler import DEFAULT_CFLAGS, Toolchain

    bad = Toolchain(cflags=(*DEFAULT_CFLAGS, "-Dfmi2Instantiate=@"))  # breaks the glue's definition
    with pytest.raises(CompilerError) as err:
        export_fmu(tmp_path / "bad.fmu", "plant", "z-1hz", "p", dyn=dyn, duration=DURATION, toolchain=bad)
    text = str(err.value)
    assert "sources/fmu.c" in text and "hydrogen-fmu-" not in text
    assert not (tmp_path / "bad.fmu").exists()


def test_bad_input_is_refused_before_any_work(dyn, tmp_path):
    with pytest.raises(FmuError, match="unknown FMU part 'sensor'"):
        export_fmu(tmp_path / "x.fmu", "sensor", "z-1hz", dyn=dyn)
    existing = tmp_path / "old.fmu"
    existing.write_bytes(b"keep me")
    with pytest.raises(OutputPathError, match="already exists"):
        export_fmu(existing, "plant", "z-1hz", dyn=dyn)
    assert existing.read_bytes() == b"keep me"
    other = tmp_path / "other.fmu"  # another tool's FMU is never replaced
    with zipfile.ZipFile(other, "w") as zf:
        zf.writestr("modelDescription.xml", '<fmiModelDescription fmiVersion="2.0" generationTool="OtherTool 1.0"/>')
    kept = other.read_bytes()
    with pytest.raises(OutputPathError, match="already exists and is no FMU hydrogen wrote"):
        export_fmu(other, "plant", "z-1hz", dyn=dyn)
    assert other.read_bytes() == kept
    # a damaged archive (its compressed data overwritten) is no FMU hydrogen wrote, never a zlib traceback
    damaged = tmp_path / "damaged.fmu"
    with zipfile.ZipFile(damaged, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("modelDescription.xml", '<fmiModelDescription generationTool="hydrogen 0"/>' + "x" * 20000)
    data = bytearray(damaged.read_bytes())
    data[60:90] = b"\xff" * 30
    damaged.write_bytes(bytes(data))
    with pytest.raises(OutputPathError, match="is no FMU hydrogen wrote"):
        export_fmu(damaged, "plant", "z-1hz", dyn=dyn)
    # a link is never followed, even to an FMU of hydrogen's; a folder is named as one
    ours = tmp_path / "ours.fmu"
    with zipfile.ZipFile(ours, "w") as zf:
        zf.writestr("modelDescription.xml", '<fmiModelDescription generationTool="hydrogen 0"/>')
    (tmp_path / "link.fmu").symlink_to(ours)
    with pytest.raises(OutputPathError, match="a link is never followed"):
        export_fmu(tmp_path / "link.fmu", "plant", "z-1hz", dyn=dyn)
    (tmp_path / "folder.fmu").mkdir()
    with pytest.raises(OutputPathError, match="is a folder"):
        export_fmu(tmp_path / "folder.fmu", "plant", "z-1hz", dyn=dyn)
    assert ours.read_bytes() and (tmp_path / "folder.fmu").is_dir()
    with pytest.raises(FmuError, match="not a whole number of control periods"):
        export_fmu(tmp_path / "y.fmu", "plant", "z-1hz", dyn=dyn, step=0.0015)
    assert not (tmp_path / "x.fmu").exists() and not (tmp_path / "y.fmu").exists()
    assert issubclass(FmuError, HydrogenError)


@pytest.mark.parametrize("args, message", [
    (["--part", "sensor"], "unknown FMU part 'sensor'"),
    (["--part", "plant", "--step", "0.0015"], "not a whole number of control periods"),
    (["--part", "plant", "--out-exists"], "already exists"),
    ([], "--format fmu needs --part"),
])
def test_cli_errors_are_one_line_with_status_2(tmp_path, args, message, dyn):
    # dyn: the robot built in the session cache first, so the command finds it and never waits for another
    # worker's build of it (the wait is a line of its own on stderr: "hydrogen: waiting for the build lock")
    out = tmp_path / "a.fmu"
    if "--out-exists" in args:
        args = [a for a in args if a != "--out-exists"]
        out.write_bytes(b"")
    proc = subprocess.run([sys.executable, "-m", "hydrogen.cli", "export", "--format", "fmu", "--scenario", "z-1hz",
                           "--out", str(out), *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_missing_fmpy_is_one_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "fmpy", None)
    with pytest.raises(FmuError, match=r"hydrogen\[fmu\]"):
        fmi_headers_dir()


def test_the_binary_exports_only_fmi_symbols(fmus):
    """Two FMUs of the same model in one process must not see each other's generated functions."""
    path = fmus[3]["controller"]
    md = read_model_description(str(path))
    lib = Path(extract(str(path))) / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("needs nm")
    syms = subprocess.run([nm, "-D", "--defined-only", str(lib)], capture_output=True, text=True).stdout.split()
    exported = {s for s in syms if s.startswith(("fmi2", fmus[0].model.name))}
    assert exported and all(s.startswith("fmi2") for s in exported)
    ctypes.CDLL(str(lib)).fmi2GetVersion  # loads


def test_a_lean_controller_offers_no_composite_rate_as_a_parameter(dyn, tmp_path):
    """The lean variant has the composite terms folded out: setting their gains would change
    nothing, so the FMU does not offer them (the manifest lists the inputs a function does not read);
    with a rate set, the full controller runs and offers them."""
    def params(label, gains):
        path = export_fmu(tmp_path / f"{label}.fmu", "controller", "z-1hz", "adaptive-robust", dyn=dyn,
                          duration=DURATION, gains=gains)
        return {v.name for v in read_model_description(str(path)).modelVariables if v.causality == "parameter"}
    lean, full = params("lean", PAPER_LAWS), params("full", {**PAPER_LAWS, "rate_ls_theta": 20.0})
    assert "Ktau[1]" in lean and "Ktau[1]" in full
    composite = {"rate_ls_theta", "rate_ls_gamma", "P0_theta", "P0_gamma", "lambda_f_theta", "period"}
    assert not composite & lean
    assert composite <= full


def test_parameters_declare_their_range_from_the_model(fmus):
    """min/max of every parameter come from the model and the scenario's rules: the true theta and
    gamma inside the projection bounds, control pressures in [0, p_s], gains >= 0 (> 0 for limits)."""
    dyn, scenario, controller, paths = fmus
    model = dyn.model
    cyls = [c.name for c in model.cylinders]
    plant = {v.name: v for v in read_model_description(str(paths["plant"])).modelVariables}
    for t, a, b in zip(model.theta_names, model.theta_min, model.theta_max):
        v = plant[f"theta.{t}"]
        assert (float(v.min), float(v.max)) == (a, b)
    for c in cyls:
        assert (float(plant[f"gamma1.{c}"].min), float(plant[f"gamma1.{c}"].max)) == (model.gamma1_min,
                                                                                      model.gamma1_max)
    # each chamber pressure's initial value within its kind's bounds ([0, P_s] for p_c, [P_t, P_s] for p_A, p_B;
    # up to the supply's ceiling, the relief's, where the supply is a state)
    from hydrogen.plant import plant_layout, supply
    pc = {sl.name: sl for sl in plant_layout(model)}["pc"]  # the plant's bounds: the kind's, to the supply's ceiling
    lo, hi = np.array(pc.lower), np.array(pc.upper)
    assert np.array_equal(lo, pressure_bounds(model)[0])
    for j, name in enumerate(_pressure_variables(model, "_start")):
        assert (float(plant[name].min), float(plant[name].max)) == (lo[j], hi[j])
        own = model.cylinders[[c.name for c in model.cylinders].index(name.split(".", 1)[1])].supply_pressure
        assert hi[j] == (supply.ceiling(model) or own) and hi[j] >= own
    for c in cyls:  # one friction triple per actuator, in its own unit
        assert float(plant[f"friction.{c}.smooth_speed"].min) > 0 and float(plant[f"friction.{c}.coulomb"].min) == 0
    ctl = {v.name: v for v in read_model_description(str(paths["controller"])).modelVariables}
    params = [v for v in ctl.values() if v.causality == "parameter" and v.type == "Real"]
    # the description's numbers have the description's ranges, a position's below 0 (checked below)
    assert params and all(v.min is not None and float(v.min) >= 0 for v in params
                          if not v.name.startswith(("theta_min", "theta_max", "numbers.")))
    assert float(ctl["u_max"].min) > 0
    for v in list(plant.values()) + params:  # every start value inside its range
        if v.start is not None and v.type == "Real":
            assert v.min is None or float(v.min) <= float(v.start), v.name
            assert v.max is None or float(v.start) <= float(v.max), v.name


def _refused(slave, names, values, message):
    with pytest.raises(FMICallException):
        slave.set(names, values)
    assert any(message in m and names[-1] in m for m in slave.messages), slave.messages


def test_impossible_parameters_and_inputs_are_refused_and_change_nothing(fmus):
    dyn, scenario, controller, paths = fmus
    model = dyn.model
    plant = Slave(paths["plant"], "plant")
    theta = plant.names("theta.")[0]
    lo = float(plant.var[theta].min)
    start = plant.get([theta])[0]
    _refused(plant, [theta], [lo - abs(lo) - 1.0], "is out of range: it must be >=")  # e.g. a negative mass
    _refused(plant, [theta], [float("nan")], "is not a finite number")
    _refused(plant, [f"friction.{model.cylinders[0].name}.smooth_speed"], [0.0], "must be > 0")
    assert plant.get([theta])[0] == start
    u = plant.names("u.")
    _refused(plant, u, [0.0] * (len(u) - 1) + [float("inf")], "is not a finite number")
    assert np.all(plant.get(u) == 0.0)  # the call was refused whole: not even the finite entries were set
    plant.fmu.exitInitializationMode()
    _refused(plant, u[:1], [float("nan")], "is not a finite number")
    plant.fmu.doStep(0.0, plant.h)
    q = plant.get(plant.names("q."))
    plant.close()
    clean = Slave(paths["plant"], "clean")
    clean.fmu.exitInitializationMode()
    clean.fmu.doStep(0.0, clean.h)
    np.testing.assert_array_equal(q, clean.get(clean.names("q.")))
    clean.close()

    # the controller: a NaN gain or measurement is refused; the command is computed from the last good values
    ctl = Slave(paths["controller"], "controller")
    gain = next(v.name for v in ctl.var.values() if v.causality == "parameter" and v.type == "Real")
    _refused(ctl, [gain], [float("nan")], "is not a finite number")
    _refused(ctl, [gain], [-1.0], "is out of range")
    ctl.fmu.exitInitializationMode()
    lengths = ctl.names("l.")
    _refused(ctl, lengths[:1], [float("nan")], "is not a finite number")
    ctl.fmu.doStep(0.0, ctl.h)
    u_ctl = ctl.get(ctl.names("u."))
    ctl.close()
    ref = Slave(paths["controller"], "reference")
    ref.fmu.exitInitializationMode()
    ref.fmu.doStep(0.0, ref.h)
    np.testing.assert_array_equal(u_ctl, ref.get(ref.names("u.")))
    assert np.all(np.isfinite(u_ctl))
    ref.close()


def test_a_start_pose_outside_the_strokes_is_refused_at_initialisation(fmus):
    dyn, scenario, controller, paths = fmus
    model = dyn.model
    plant = Slave(paths["plant"], "plant")
    names = plant.names("q_start.")
    q0 = plant.get(names)
    for d in (0.5, 1.0, 2.0, 3.0):  # some move of the first coordinate takes a cylinder outside its stroke
        q = q0 + d * np.eye(len(q0))[0]
        legs = np.asarray(dyn.leg_lengths(q))
        if np.any((legs < model.leg_min) | (legs > model.leg_max)):
            break
    else:
        pytest.skip("no start pose outside the strokes found along the first coordinate")
    plant.set(names, q)
    with pytest.raises(FMICallException):
        plant.fmu.exitInitializationMode()
    assert any("q_start puts l." in m and (" m, outside its stroke [" in m or " rad, outside its angle range [" in m)
               for m in plant.messages), plant.messages
    plant.fmu.freeInstance()


_VECTOR = re.compile(r"\[([^\]]*)\]")


def _same_failure(fmu_words, python_words):
    """The FMU's failure words are hydrogen's: the same text around the vectors, which hold the same
    numbers (C prints them to 8 digits, numpy its own way)."""
    assert _VECTOR.sub("[]", fmu_words) == _VECTOR.sub("[]", python_words)
    for got, want in zip(_VECTOR.findall(fmu_words), _VECTOR.findall(python_words), strict=True):
        want = np.array(want.split(), float)
        np.testing.assert_allclose(np.array(got.split(), float), want, rtol=1e-7, atol=1e-7 * np.abs(want).max())


def _failed_step(path, inputs):
    """The log message of the first step of a controller FMU given ``inputs`` ({name: value}): it must fail."""
    ctl = Slave(path, "controller")
    ctl.fmu.exitInitializationMode()
    ctl.set(list(inputs), list(inputs.values()))
    with pytest.raises(FMICallException):
        ctl.fmu.doStep(0.0, ctl.h)
    ctl.fmu.freeInstance()
    prefix = "fmi2DoStep: control period 0 (t = 0 s): "
    assert len(ctl.messages) == 1 and ctl.messages[0].startswith(prefix), ctl.messages
    return ctl.messages[0][len(prefix):]


def test_a_forward_kinematics_failure_names_its_outcome_and_time(dyn, shared_fmu):
    """Cylinder lengths no pose fits stop the controller FMU (the closed loop's glue alike) with
    hydrogen's words for the outcome, the control period and its time: JL singular with its condition
    number, or not converged with its residual; the pose and lengths of Dynamics.forward_kinematics
    from the same start."""
    from hydrogen.errors import KinematicsError
    from hydrogen.simulation.simulator import prepare_run

    scenario, controller = CASES["ubc_stewart"]
    path = shared_fmu(dyn, "controller", scenario, controller, duration=DURATION)
    p = prepare_run(dyn, scenario, controller, None, DURATION, True, {})
    q0, l0 = p.q0, dyn.leg_lengths(p.q0)  # the FMU's warm start
    step = actuator_settings(p.sc, dyn.model)["quantization_l"]  # lengths on the encoders' grid: read as given
    rng = np.random.default_rng(0)
    found = {}
    for _ in range(2000):  # lengths far enough off the start to make both outcomes
        l = l0 + 0.3 * rng.standard_normal(len(l0))
        l = np.where(step > 0, np.round(l / np.where(step > 0, step, 1.0)) * step, l)
        try:
            dyn.forward_kinematics(l, q0=q0)
        except KinematicsError as exc:
            found.setdefault("did not converge" in str(exc), (l, str(exc)))
        if len(found) == 2:
            break
    assert set(found) == {True, False}
    cyls = [f"l.{c.name}" for c in dyn.model.cylinders]
    for l, said in found.values():
        words = _failed_step(path, dict(zip(cyls, l)))
        assert ("residual " in words) == ("did not converge" in said)
        assert ("condition number " in words) == ("JL is singular" in said)
        _same_failure(words, said)


def test_a_singular_jl_at_the_encoders_pose_stops_the_fmu_as_the_velocity_estimate(arm_dyn, shared_fmu):
    """With joint encoders a singular JL at the measured pose is the velocity estimate's failure, in
    hydrogen's words (the loop's), not forward kinematics'."""
    from hydrogen.dynamics import VELOCITY_SINGULAR, fk_failure

    scenario, controller = CASES["excavator_arm"]
    path = shared_fmu(arm_dyn, "controller", scenario, controller, duration=DURATION)
    q = singular_pose(arm_dyn)
    l = arm_dyn.leg_lengths(q)
    model = arm_dyn.model
    inputs = {**{f"q.{c}": v for c, v in zip(model.coordinate_names, q)},
              **{f"l.{c.name}": v for c, v in zip(model.cylinders, l)}}
    words = _failed_step(path, inputs)
    assert words.startswith("velocity estimate: JL is singular at the measured pose q = [")
    _same_failure(words, fk_failure(VELOCITY_SINGULAR, (0.0, np.inf, 0.0), q, l, 0))


def test_a_step_past_the_stop_time_is_refused(fmus):
    dyn, scenario, controller, paths = fmus
    for part in ("plant", "controller"):
        h = float(read_model_description(str(paths[part])).defaultExperiment.stepSize)
        s = Slave(paths[part], part, stop_time=3 * h)
        s.fmu.exitInitializationMode()
        s.fmu.doStep(0.0, 2 * h)
        with pytest.raises(FMICallException):
            s.fmu.doStep(2 * h, 2 * h)
        assert any("ends after the stop time" in m for m in s.messages), s.messages
        s.fmu.doStep(2 * h, h)  # nothing was done by the refused step; up to the stop time is fine
        s.close()


def test_the_description_numbers_are_parameters_and_an_edit_equals_the_edited_description(cache, tmp_path,
                                                                                              shared_fmu):
    """From a build with the description's numbers as inputs, every number is an FMU parameter named
    after it (numbers.<name>, arrays 1-based); the FMU at the start values reproduces simulate, and
    the FMU with gravity and a pin point set as parameters reproduces simulate of the edited
    description (which loads the same library: no regeneration). The edit keeps the start state
    (its holding pressures are not parameters): a dead volume."""
    import hydrogen
    from test_constants import _edited_arm

    arm = hydrogen.load_model("excavator_arm")
    dyn = hydrogen.build(arm, numbers="inputs", cache=cache)
    scenario, controller = CASES["excavator_arm"]
    path = shared_fmu(dyn, "closed-loop", scenario, controller, duration=DURATION)
    md = read_model_description(str(path))
    params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
    names = dyn.library.manifest["numbers"]
    assert f"numbers.{names[0]}" in params and "numbers.gravity" in params
    assert "numbers.boom_cylinder.from[1]" in params  # from[0]: FMI's arrays count from 1
    assert params["numbers.boom_cylinder.from[1]"].description == \
        "the description's number boom_cylinder.from[0] (SI; FMI index from 1)"  # the two indices told apart
    assert len([n for n in params if n.startswith("numbers.")]) == len(names)
    assert float(params["numbers.gravity"].start) == arm.gravity
    coords = arm.coordinate_names
    out = [f"q.{c}" for c in coords]

    def q_of(result):
        return np.column_stack([result[o] for o in out])

    np.testing.assert_allclose(q_of(simulate_fmu(str(path), output=out)),
                               _reference_run(dyn, scenario, controller).q, rtol=0, atol=1e-9)
    edit = {"numbers.boom_cylinder.dead_volume_A": 3.5e-3}
    edited = _edited_arm(tmp_path, {"toml": [("dead_volume_A = 2.7e-3 ", "dead_volume_A = 3.5e-3 ")]})
    assert all(edited.numbers()[k[len("numbers."):]] == v for k, v in edit.items())
    served = hydrogen.build(edited, numbers="inputs", cache=cache)
    assert served.library.path == dyn.library.path
    want = _reference_run(served, scenario, controller).q
    got = q_of(simulate_fmu(str(path), output=out, start_values=edit))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    assert np.abs(want - _reference_run(dyn, scenario, controller).q).max() > 1e-6  # the edit matters


@pytest.fixture(scope="module")
def arm_dyn(cache):
    """The excavator arm built with the description's numbers as inputs (they are FMU parameters)."""
    import hydrogen
    return hydrogen.build(hydrogen.load_model("excavator_arm"), numbers="inputs", cache=cache)


@pytest.mark.parametrize("update", ["semi-implicit", "euler"])
def test_closed_loop_estimates_at_t_are_simulates_row_at_t_after_adaptation_starts(arm_dyn, shared_fmu, update):
    """theta_hat at t = k h is simulate's row k, the estimate the command at t used (after the update
    from the measurement at t, for the semi-implicit update), checked after adaptation has started
    (arm-sim adapts from 0.5 s), where the estimate changes every period."""
    scenario, controller = CASES["excavator_arm"]
    kw = {} if update == "semi-implicit" else {"estimator_update": update}
    path = shared_fmu(arm_dyn, "closed-loop", scenario, controller, duration=0.7, **kw)
    res = _reference_run(arm_dyn, scenario, controller, duration=0.7, **kw)
    theta = [f"theta_hat.{t}" for t in arm_dyn.model.theta_names]
    out = simulate_fmu(str(path), output=theta)
    np.testing.assert_allclose(out["time"], res.t, rtol=0, atol=1e-12)
    got = np.column_stack([out[t] for t in theta])
    rows = np.searchsorted(res.t, [0.52, 0.55, 0.6, 0.65, 0.7])
    np.testing.assert_allclose(got[rows], res.theta_hat[rows], rtol=1e-12, atol=0)
    # the rows differ from their neighbours there: an off-by-one would fail
    assert np.all(np.abs(res.theta_hat[rows] - res.theta_hat[rows - 1]).max(axis=1) > 1e-9)
    np.testing.assert_allclose(got, res.theta_hat, rtol=1e-12, atol=0)


def _numbers_slave(arm_dyn, shared_fmu, name):
    scenario, controller = CASES["excavator_arm"]
    return Slave(shared_fmu(arm_dyn, "closed-loop", scenario, controller, duration=DURATION), name)


def test_the_description_numbers_declare_the_descriptions_ranges(arm_dyn, shared_fmu):
    """Each numbers.<name> parameter has min and max: the description's own range (the loader's
    QUANTITIES, or what they imply for a derived number), and its start value inside it."""
    model = arm_dyn.model
    ranges = model.number_ranges()
    s = _numbers_slave(arm_dyn, shared_fmu, "ranges")
    by = {n[len("numbers."):]: v for n, v in s.var.items() if n.startswith("numbers.")}
    assert float(by["boom.mass"].min) == 1e-6 and float(by["boom.mass"].max) == 1e6
    assert (float(by["gravity"].min), float(by["gravity"].max)) == ranges["gravity"] == (0.0, 30.0)
    assert float(by["boom_cylinder.cap_area"].min) > 0 and float(by["boom_cylinder.bulk_modulus"].min) > 0
    assert float(by["boom.Ixx"].min) > 0 and float(by["boom.mcx"].min) < 0  # about the origin: derived ranges
    names = arm_dyn.library.manifest["numbers"]
    assert len(by) == len(names)
    for name in names:
        lo, hi = ranges[name]
        v = s.var[_number_variable(name)]  # an array's entry as FMI counts, from 1
        assert (v.min is None) == (lo is None) and (v.max is None) == (hi is None), name
        assert lo is None or float(v.min) == lo, name
        assert hi is None or float(v.max) == hi, name
        assert (lo is None or lo <= float(v.start)) and (hi is None or float(v.start) <= hi), name
    s.fmu.freeInstance()


@pytest.mark.parametrize("number, value, words", [
    ("boom.mass", -3.0, ["numbers.boom.mass = -3", ">= 1e-06", "[1e-06, 1000000]"]),
    ("boom_cylinder.cap_area", 0.0, ["numbers.boom_cylinder.cap_area = 0", "[1e-08, 10]"]),
    ("boom_cylinder.bulk_modulus", -1.4e9, ["numbers.boom_cylinder.bulk_modulus", "[10000000, 1e+10]"]),
    ("gravity", float("nan"), ["numbers.gravity", "not a finite number"]),
])
def test_a_number_outside_its_range_is_refused_naming_it(arm_dyn, shared_fmu, number, value, words):
    s = _numbers_slave(arm_dyn, shared_fmu, "refuse")
    name = f"numbers.{number}"
    start = s.get([name])[0]
    with pytest.raises(FMICallException):
        s.set([name], [value])
    assert any(all(w in m for w in words) for m in s.messages), s.messages
    assert s.get([name])[0] == start  # nothing was set
    s.fmu.freeInstance()


def test_an_annulus_larger_than_the_cap_is_refused_at_initialisation(arm_dyn, shared_fmu):
    """Each area inside its range, but the annulus larger than the cap: fmi2ExitInitializationMode
    refuses it, naming both parameters; the loader's own rule (hydrogen.model.CYLINDER_ORDER)."""
    s = _numbers_slave(arm_dyn, shared_fmu, "order")
    cap, annulus = "numbers.boom_cylinder.cap_area", "numbers.boom_cylinder.annulus_area"
    s.set([annulus], [2 * s.get([cap])[0]])  # in its own range: accepted when set
    with pytest.raises(FMICallException):
        s.fmu.exitInitializationMode()
    assert any(annulus in m and cap in m and "must be <=" in m for m in s.messages), s.messages
    s.fmu.freeInstance()


def test_names_with_a_dash_are_quoted_fmu_names(tmp_path, cache, shared_fmu):
    """A '-' in a link's or cylinder's name: the FMU's variables quote that part of the structured
    name (numbers.'boom-cylinder'.cap_area), the FMU validates and runs, and its refusals name them."""
    import hydrogen
    from test_export import dashed_arm

    dyn = hydrogen.build(dashed_arm(tmp_path), numbers="inputs", cache=cache)
    scenario, controller = CASES["excavator_arm"]
    path = shared_fmu(dyn, "closed-loop", scenario, controller, duration=DURATION)
    assert validate_fmu(str(path)) == []
    s = Slave(path, "dash")
    assert {"numbers.'boom-cylinder'.cap_area", "numbers.'boom-link'.mass", "u.'boom-cylinder'"} <= set(s.vr)
    with pytest.raises(FMICallException):
        s.set(["numbers.'boom-link'.mass"], [-1.0])
    assert any("numbers.'boom-link'.mass = -1 is out of range" in m for m in s.messages), s.messages
    s.fmu.freeInstance()
    out = simulate_fmu(str(path), output=["q.boom"])
    np.testing.assert_allclose(out["q.boom"], _reference_run(dyn, scenario, controller).q[:, 0], rtol=0, atol=1e-9)


def test_an_unlimited_travel_range_is_written_as_infinity():
    """The plant FMU's start-pose check holds each actuator to its range: an actuator of unlimited
    travel (−∞, ∞) is written as ±INFINITY (every start angle inside), a finite end exactly."""
    from hydrogen.fmu import _c_limit
    assert (_c_limit(-np.inf), _c_limit(np.inf), _c_limit(0.45)) == ("-INFINITY", "INFINITY", "0.45")


def test_the_cranes_slew_angle_is_exported_in_rad(cache, tmp_path):
    """An actuator's travel variables take their unit and word from its kind's TRAVEL: the crane's
    rotary slew exports its angle in rad (its rate in rad/s), its cylinders their lengths in m."""
    import hydrogen
    dyn = hydrogen.build(hydrogen.load_model("loader_crane"), cache=cache)
    path = export_fmu(tmp_path / "crane.fmu", "plant", dyn=dyn, controller="adaptive-robust", duration=DURATION)
    var = {v.name: v for v in read_model_description(str(path)).modelVariables}
    for c in dyn.model.cylinders:
        unit = c.travel.unit
        assert (var[f"l.{c.name}"].unit, var[f"ldot.{c.name}"].unit) == (unit, f"{unit}/s"), c.name
    slew = next(c for c in dyn.model.cylinders if c.kind == "rotary")
    assert var[f"l.{slew.name}"].unit == "rad" and var[f"l.{slew.name}"].description == f"angle of actuator {slew.name}"
    boom = next(c for c in dyn.model.cylinders if c.kind == "four_way_cylinder")
    assert var[f"l.{boom.name}"].unit == "m" and var[f"l.{boom.name}"].description == f"length of cylinder {boom.name}"


def test_the_fmus_output_a_pumps_supply_pressure(pump_dyn, shared_fmu):
    """The supply pressure, a plant state with a pump, is an output of the plant and closed-loop FMUs:
    the closed loop's is the simulator's, period by period."""
    res = _reference_run(pump_dyn, "arm-sim", "backstepping")
    closed = shared_fmu(pump_dyn, "closed-loop", "arm-sim", "backstepping", duration=DURATION)
    out = simulate_fmu(str(closed), output=["ps"])
    np.testing.assert_allclose(out["ps"], res.supply_pressure, rtol=1e-12)
    assert np.ptp(res.supply_pressure) > 1e5  # the pump's pressure moves
    plant = {v.name: v for v in read_model_description(
        str(shared_fmu(pump_dyn, "plant", "arm-sim", "backstepping", duration=DURATION))).modelVariables}
    assert (plant["ps"].causality, plant["ps"].unit) == ("output", "Pa")


def test_the_plant_fmu_starts_from_ps_start_within_its_range(pump_dyn, shared_fmu):
    """A pump's supply pressure is a plant state: ``ps_start`` (Pa) sets where it starts, declared from
    the state's lower bound 0 to the highest the plant holds it to, the actuators' supply_pressure by
    default; a value outside is refused."""
    from hydrogen.plant.supply import ceiling

    path = shared_fmu(pump_dyn, "plant", "arm-sim", "backstepping", duration=DURATION)
    nominal = pump_dyn.model.cylinders[0].supply_pressure
    default = Slave(path, "default")
    var = default.var["ps_start"]
    assert (var.causality, var.variability, var.unit, float(var.start)) == ("parameter", "fixed", "Pa", nominal)
    assert (float(var.min), float(var.max)) == (0.0, ceiling(pump_dyn.model))
    plant = Slave(path, "plant")
    plant.set(["ps_start"], [8.0e6])
    for s in (default, plant):
        s.fmu.exitInitializationMode()
    assert default.get(["ps"])[0] == nominal and plant.get(["ps"])[0] == 8.0e6
    for s in (default, plant):
        s.fmu.doStep(0.0, s.h)
    assert abs(plant.get(["ps"])[0] - 8.0e6) < abs(plant.get(["ps"])[0] - default.get(["ps"])[0])
    for s in (default, plant):
        s.close()
    high = Slave(path, "high")
    with pytest.raises(FMICallException):
        high.set(["ps_start"], [2 * ceiling(pump_dyn.model)])
    assert any("ps_start" in m and "out of range" in m for m in high.messages), high.messages
    high.fmu.freeInstance()

