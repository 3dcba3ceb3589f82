"""The run's logs, declared once (hydrogen/loop_logs.py): the C loop's log struct and write_log, the
Python engine's writer, the widths and the result are read off the table; what a log holds is what
its source is (checked against the kinematics); and a log added as one row of the table (in a copy of
the package, nothing else edited) is written by both engines and reaches the result."""
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.layout import loop_context, log_rows, model_summary
from hydrogen.loop_logs import LOGS, RESERVED, SIGNAL, STATE

from conftest import run_in_a_copy

ROOT = Path(__file__).resolve().parents[1]


def test_the_log_struct_and_write_log_are_the_table(robot_model):
    """Every row (and each plant output) is a field of the loop header's log struct, in the table's order,
    and the committed C loop writes each from its source."""
    ctx = loop_context({"model": model_summary(robot_model)})
    names = [name for name, _, _ in ctx["logs"]]
    assert names[:len(LOGS)] == [r.name for r in LOGS]
    assert names[len(LOGS):] == [p["name"] for p in model_summary(robot_model)["plant"] if p["output"]]
    folder = ROOT / "generated" / robot_model.name
    header = (folder / f"{robot_model.name}_loop.h").read_text()
    loop = (folder / f"{robot_model.name}_loop.c").read_text()
    for r in log_rows(model_summary(robot_model)):
        assert f"double* {r['name']};" in header
        assert f"if (log->{r['name']}" in loop
        if r["kind"] == SIGNAL:
            assert f"s->{r['field']}," in loop


def test_the_signals_a_signal_log_reads_exist_in_both_engines():
    """A signal log's source is a field of the C loop's signals and of the Python engine's."""
    from hydrogen.layout import LOOP_SIGNALS
    from hydrogen.simulation.simulator import _Signals
    for r in LOGS:
        if r.source[0] == SIGNAL:
            assert r.source[1] in {f[0] for f in LOOP_SIGNALS}, r.name
            assert r.source[1] in _Signals.__slots__, r.name


def test_no_plant_output_may_take_a_logs_name():
    from hydrogen.plant import RESERVED_OUTPUTS
    assert RESERVED_OUTPUTS == RESERVED and {"q", "f", "ldot", "xc"} <= set(RESERVED)


def test_the_result_carries_every_log(dyn):
    """Each row becomes its result field or ``signals[name]`` (the controller state: ``states``), as
    wide as its log; a one-column log is a vector."""
    res = hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, duration=0.02)
    k = len(res.t)
    assert k > 0 and np.array_equal(res.t, np.arange(k) * (1.0 / res.scenario.control_rate))  # k h, as the loop
    for r in LOGS:
        if r.source[0] == STATE:
            continue
        value = getattr(res, r.result) if r.result else res.signals[r.name]
        assert value.shape[0] == k and np.all(np.isfinite(value)), r.name
    assert set(res.signals) == {r.name for r in LOGS if not r.result and r.source[0] != STATE}


@pytest.mark.parametrize("engine", ["c", "python"])
def test_the_rates_and_velocities_logged_are_the_kinematics(dyn, engine):
    """Without noise, the ideal rate sensor's ``ldot`` is the true lengths' rate (central differences
    of the logged lengths, to O(h^2)), and ``qdot_meas`` solves JL(q) qdot = ldot at the measured pose."""
    res = hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, duration=0.2, noise_l=0.0, noise_p=0.0,
                           engine=engine)
    h = 1.0 / res.scenario.control_rate
    ldot, qdot = res.signals["ldot"], res.signals["qdot_meas"]
    central = (res.leg_lengths[2:] - res.leg_lengths[:-2]) / (2 * h)
    scale = np.max(np.abs(ldot))
    assert scale > 1e-3  # m/s: the legs move
    assert np.max(np.abs(central - ldot[1:-1])) < 2e-3 * scale
    for k in range(0, len(res.t), 17):
        J = np.asarray(dyn.leg_jacobian(res.q[k]))  # the measured pose is the true one without noise
        assert np.allclose(J @ qdot[k], ldot[k], rtol=1e-8, atol=1e-10 * scale)


def test_both_engines_log_the_same(dyn):
    """The new logs equal on the C loop and the Python engine, with noise and the Kalman filter."""
    runs = [hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, duration=0.05, engine=e) for e in ("c", "python")]
    for name in runs[0].signals:
        a, b = runs[0].signals[name], runs[1].signals[name]
        assert a.shape == b.shape and np.allclose(a, b, rtol=1e-9, atol=1e-12), name


ROW = '''
#: a log added by one row: the measured pressures
LOGS = (*LOGS, LogRow("pc_meas", ("NPC",), "Pa", "measured pressure states", (SIGNAL, "pc_meas")))
RESERVED = tuple(row.name for row in LOGS)
'''

SCRIPT = r'''
import json, sys
from pathlib import Path
import numpy as np
import hydrogen
lines = []
dyn = hydrogen.build("excavator_arm", cache=Path(sys.argv[1]), progress=lines.append)
runs = [hydrogen.simulate("arm-sim", "backstepping", dyn=dyn, duration=0.05, noise_p=5e4, engine=e)
        for e in ("c", "python")]
a, b = (r.signals["pc_meas"] for r in runs)
print(json.dumps({"signals": sorted(runs[0].signals), "shape": list(a.shape), "rows": len(runs[0].t),
                  "engines": float(np.max(np.abs(a - b))),
                  "noise": float(np.std(a - runs[0].pressures)), "noise_p": runs[0].scenario.noise_p,
                  "progress": [f"{e.stage}: {e.detail}" for e in lines]}))
'''


def test_a_log_added_as_one_row_is_written_by_both_engines(cache, tmp_path):
    """In a copy of the package beside its committed code, one row appended to the table (nothing else
    edited): the build renders the loop drivers alone, both engines log the signal equally, and the
    result carries it (the measured pressures: the true ones plus the scenario's noise)."""
    table = (ROOT / "hydrogen" / "loop_logs.py").read_text()
    out = run_in_a_copy(cache, tmp_path, {"hydrogen/loop_logs.py": table + ROW}, SCRIPT, ["{cache}"],
                        parts=("hydrogen", "templates", "generated"))
    assert "pc_meas" in out["signals"] and out["shape"] == [out["rows"], 6]
    assert out["engines"] < 1e-6  # Pa, of pressures of 1e7
    assert 0.5 * out["noise_p"] < out["noise"] < 1.5 * out["noise_p"]
    progress = " ".join(out["progress"])
    assert "rendering the loop drivers" in progress and "deriving" not in progress, progress


def test_a_log_of_a_signal_the_robot_lacks_is_no_log(monkeypatch):
    """A row of a signal some robots lack (the supply pressure's reading without a pump, the encoders'
    without encoders) is a log only where the robot has it; a row of a signal or plant part the loop
    has not got is refused when the layout is read."""
    from hydrogen import layout
    from hydrogen.loop_logs import LogRow, PLANT
    extra = (LogRow("ps_meas", ("NPS",), "Pa", "measured supply pressure", (SIGNAL, "ps_meas")),
             LogRow("q_enc", ("NQ",), "rad", "the encoders' reading", (SIGNAL, "q_enc")))
    monkeypatch.setattr(layout, "LOGS", LOGS + extra)
    for name, has in (("ubc_stewart", False), ("excavator_arm", True)):
        names = [r["name"] for r in log_rows(model_summary(hydrogen.load_model(name)))]
        assert ("ps_meas" in names, "q_enc" in names) == (has, has), name
    monkeypatch.setattr(layout, "LOGS", LOGS + (LogRow("qq", ("NQ",), "m", "a typo", (PLANT, "qdott")),))
    with pytest.raises(ImportError, match="'qq'.*the plant part 'qdott', which the loop has not got"):
        log_rows(model_summary(hydrogen.load_model("ubc_stewart")))


@pytest.mark.parametrize("controller", ["p", "adaptive-robust"])
def test_the_run_size_check_counts_the_logs_a_run_allocates(controller):
    """The memory check's doubles per period are the noise row, the workspace check and every log."""
    from hydrogen.simulation.checks import run_doubles_per_period
    from hydrogen.controllers import controller as controller_module
    from hydrogen.simulation.simulator import log_widths
    from hydrogen.sensors import noise_width
    from hydrogen.layout import robot_sizes
    for name in ("ubc_stewart", "excavator_arm"):
        model = hydrogen.load_model(name)
        n_xc = sum(size for _, size in controller_module(controller).state_layout(model))
        widths = sum(w for _, w in log_widths(model, n_xc))
        noise = noise_width(robot_sizes(model_summary(model)), model.joint_encoders)
        assert run_doubles_per_period(model, controller, True) == noise + model.n + model.n_cylinders + widths


def test_a_log_of_the_loops_state_reaches_the_result(dyn, monkeypatch):
    """A row reading a field of the loop's state (the last measured pose) without a result field of its
    own is in ``signals`` (the Python engine: the C loop's write_log is rendered from the same table)."""
    from hydrogen import layout
    from hydrogen.loop_logs import LogRow
    from hydrogen.simulation import simulator
    row = LogRow("pose_measured", ("NQ",), "m or rad", "the last measured pose", (STATE, "q_meas"))
    monkeypatch.setattr(layout, "LOGS", LOGS + (row,))
    monkeypatch.setattr(simulator, "LOGS", LOGS + (row,))
    res = hydrogen.simulate("paper-sim", "backstepping", dyn=dyn, duration=0.02, engine="python")
    pose = res.signals["pose_measured"]
    assert pose.shape == res.q.shape and np.max(np.abs(pose - res.q)) < 1e-3  # m, rad: noise and quantisation
