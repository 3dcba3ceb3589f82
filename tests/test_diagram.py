"""The loop's blocks and ports (hydrogen.diagram): wiring by name, refusals, and the drivers that read it."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

import hydrogen
from hydrogen import diagram
from hydrogen.layout import robot_sizes
from hydrogen.errors import ScenarioError

ROOT = Path(__file__).resolve().parent.parent
SIZES = {"NQ": 6, "NL": 6, "NPC": 6, "NPS": 0}


def test_wire_gives_each_slot_its_index_in_the_argument_table_and_minus_one_where_unread():
    inputs = [("Kleg", 6), ("l", 6), ("qd0", 6), ("numbers", 89)]
    slots = diagram.wire("controller 'p'", inputs, {"Kleg", "numbers"}, SIZES)
    assert len(slots) == len(diagram.slots(SIZES))
    assert slots[diagram.SLOTS.index("l")] == 1 and slots[diagram.SLOTS.index("qd0")] == 2
    assert all(i == -1 for name, i in zip(diagram.SLOTS, slots) if name not in ("l", "qd0"))


def test_an_input_wired_to_nothing_is_refused_naming_its_owner_and_the_input():
    with pytest.raises(ScenarioError, match=r"controller 'x': no value for its input\(s\) p_supply: wired to no "
                                            r"loop signal \(the loop's signals: q, qdot, "):
        diagram.wire("controller 'x'", [("q", 6), ("p_supply", 1)], set(), SIZES)


def test_a_signal_of_another_size_is_refused_naming_both_sizes():
    with pytest.raises(ScenarioError, match=r"controller 'x': input 'pc' has 6 entries, but the loop's signal "
                                            r"'pc' \(measured pressure states.*\) has 12 for this robot"):
        diagram.wire("controller 'x'", [("pc", 6)], set(), {**SIZES, "NPC": 12})


def test_the_controller_state_takes_its_size_from_the_controller_not_from_the_robot():
    assert diagram.wire("controller 'x'", [("xc", 146)], set(), SIZES)[diagram.SLOTS.index("xc")] == 0


def test_every_block_input_is_some_block_output_and_the_controller_reads_the_ports():
    outputs = {p.name for b in diagram.LOOP_BLOCKS for p in b.outputs}
    for block in diagram.LOOP_BLOCKS:
        missing = [p.name for p in block.inputs if p.name not in outputs]
        assert not missing, f"block {block.name}: inputs {missing} written by no block"
    (ctrl,) = [b for b in diagram.LOOP_BLOCKS if b.name == "controller"]
    assert tuple(p.name for p in ctrl.inputs) == diagram.SLOTS
    assert [b.name for b in diagram.LOOP_BLOCKS if b.continuous] == ["plant"]


def test_signals_name_every_port_the_loop_writes_but_the_controller_s_own():
    ref = [[0.0] * 6 for _ in range(4)]
    got = diagram.signals([0.0] * 6, [0.0] * 6, [0.0] * 6, [0.0] * 6, ref, True, ps=[2.1e7])
    assert set(got) | {"xc", "u_applied"} == set(diagram.SLOTS)
    assert got["adapt"] == 1.0
    assert "ps" not in diagram.signals([0.0] * 6, [0.0] * 6, [0.0] * 6, [0.0] * 6, ref, False)  # a constant supply


def test_a_port_of_a_size_the_robot_lacks_is_no_slot_and_wires_nothing():
    constant, pump = {**SIZES, "NPS": 0}, {**SIZES, "NPS": 1}
    assert "ps" not in diagram.slots(constant) and diagram.slots(pump)[-1] == "ps"
    assert diagram.slots(constant) == diagram.SLOTS[:-1]
    with pytest.raises(ScenarioError, match=r"no value for its input\(s\) ps: wired to no loop signal"):
        diagram.wire("controller 'x'", [("ps", 1)], set(), constant)
    assert diagram.wire("controller 'x'", [("q", 6), ("ps", 1)], set(), pump)[-1] == 1


@pytest.mark.parametrize("robot", ["ubc_stewart", "excavator_arm", "loader_crane"])
def test_the_loop_driver_writes_every_port_once_and_every_shipped_controller_is_wired(robot):
    folder = ROOT / "generated" / robot
    source = (folder / f"{robot}_loop.c").read_text()
    manifest = json.loads((folder / "manifest.json").read_text())
    sizes = robot_sizes(manifest["model"])
    from hydrogen.plant import supply
    # the supply pressure is a signal only of a robot whose supply is a state (the arm's and crane's pumps)
    assert ("ps" in diagram.slots(sizes)) == bool(supply.entries(hydrogen.load_model(robot)))
    for name in diagram.slots(sizes):
        assert source.count(f"{robot.upper()}_SLOT_{name.upper()},") == 1 + (name == "xc")  # the update rewrites xc
    for f in manifest["functions"]:
        if f["name"].startswith("ctrl_"):
            inputs = [(name, rows * cols) for name, rows, cols in f["inputs"]]
            constants = {name for name, _ in inputs if name not in diagram.SLOTS}
            slots = diagram.wire(f["name"], inputs, constants, sizes)
            assert slots[diagram.SLOTS.index("qd0")] >= 0, f["name"]  # every controller tracks the reference


def test_the_python_engine_has_a_step_per_block_and_the_c_loop_runs_the_blocks_in_the_diagrams_order():
    import re

    from hydrogen.simulation.simulator import PythonStages
    for block in diagram.LOOP_BLOCKS:
        assert callable(getattr(PythonStages, block.name, None)), f"no Python step for block {block.name}"
    source = (ROOT / "generated" / "ubc_stewart" / "ubc_stewart_loop.c").read_text()
    body = source[source.index("int ubc_stewart_loop_run("):]
    calls = [m for m in re.findall(r"ubc_stewart_(measure|estimate|reference|control|plant_step)\(", body)]
    stages = list(dict.fromkeys(b.c_stage for b in diagram.LOOP_BLOCKS))  # consecutive blocks share a stage
    assert calls == stages, (calls, stages)


def test_the_supply_pressure_has_one_name_for_state_port_log_and_inputs():
    """The plant state, the controllers' input port, the log column and a controller's generated input
    all take the supply pressure's name from its one declaration (hydrogen.plant.supply.PRESSURE)."""
    from hydrogen.layout import SUPPLY_LOG
    from hydrogen.plant import supply
    assert [s.name for s in supply.STATES] == [supply.PRESSURE] == [SUPPLY_LOG]
    assert supply.PRESSURE in diagram.SLOTS
    manifest = json.loads((ROOT / "generated" / "excavator_arm" / "manifest.json").read_text())  # on a pump
    ctrl = {f["name"]: f for f in manifest["functions"]}["ctrl_backstepping"]
    assert supply.PRESSURE in [name for name, _, _ in ctrl["inputs"]]


#: A controller that reads a rig part's state: the P law plus kT (T - 293.15 K) per actuator.
P_SEAL = '''\
"""P on the cylinder lengths plus a term of each seal's temperature (a rig part's state, read by name)."""
from __future__ import annotations

import numpy as np

from .spec import ControllerSpec

SPEC = ControllerSpec(name="p-seal", doc="P with a seal-temperature term (a test's).", main_gain="Kleg",
                      grid_low=0.005, main_gain_shared=True, secondary_search=False)
NAME, DOC = SPEC.name, SPEC.doc


def state_layout(model):
    return []


def default_gains(model, scale):
    return {"Kleg": 0.03 * np.ones(model.n_cylinders), "kT": np.array([1e-5]), "u_max": np.array([3.0e-3])}


def static_inputs(dyn, theta0, gamma0):
    return {}


def derive(model):
    import sympy as sp

    from ..symbolic.calculus import clip
    from ..symbolic.control_laws import ControllerParts, scalar, vector
    from ..symbolic.kinematics import leg_stages

    m = model.n_cylinders
    l, qd0, k, temp = vector("l", m), vector("qd0", model.n), vector("Kleg", m), vector("seal_temp", m)
    kT, u_max = scalar("kT"), scalar("u_max")
    ld, _, stages = leg_stages(model, qd0)
    u = sp.Matrix([clip(k[i] * (ld[i] - l[i]) + kT * (temp[i] - 293.15), -u_max, u_max) for i in range(m)])
    return ControllerParts(inputs=[("l", l), ("qd0", qd0), ("seal_temp", temp), ("Kleg", k),
                                   ("kT", sp.Matrix([kT])), ("u_max", sp.Matrix([u_max]))],
                           outputs=[("u", u)], intermediates=stages[:-1])
'''

SEAL_SCENARIO = """
[scenarios.seal-sim]
label = "seal-sim: a controller reading the seal temperature"
duration = 0.2
t_adapt = 0.5
control_rate = 1000.0
substeps = 2
friction = [50.0, 200.0, 1e-3]
seal_start = 280.0
reference.sines = [["shoulder", 0.10, 1.0], ["elbow", -0.10, 1.5]]
"""

SEAL_SCRIPT = '''\
import json, sys
from pathlib import Path
import numpy as np
import hydrogen
from hydrogen.errors import HydrogenError
from hydrogen.fmu import export_fmu
dyn = hydrogen.build(hydrogen.load_model(sys.argv[1]), cache=Path(sys.argv[2]))
out = {}
for predictor in (False, True):
    # with the predictor, the seal term alone (Kleg 0): the temperature it sees is the predicted one
    extra = {"predictor": True, "delay": 2.0e-3, "gains": {"Kleg": 0.0}} if predictor else {}
    runs = [hydrogen.simulate("seal-sim", "p-seal", dyn=dyn, engine=e, **extra) for e in ("c", "python")]
    res = runs[0]
    kleg, kT = (0.0 if predictor else 0.03), 1e-5
    ld = np.array([dyn.leg_lengths(q) for q in res.q_d])
    law = np.clip(kleg * (ld - res.leg_lengths_measured) + kT * (res.plant["seal_temp"] - 293.15), -res.u_max, res.u_max)
    out[str(predictor)] = {"engines": float(np.max(np.abs(runs[0].u - runs[1].u))),
                           "law": float(np.max(np.abs(res.u - law))),
                           "term": float(np.max(np.abs(kT * (res.plant["seal_temp"] - 293.15))))}
# a noisy sensor of the part's state (0.5 K), the loop's own sensors quiet: the command carries its noise
noisy = [hydrogen.simulate("seal-sim", "p-seal", dyn=dyn, engine=e, seal_noise=0.5, noise_l=0.0, noise_p=0.0,
                           noise_q=0.0) for e in ("c", "python")]
res = noisy[0]
ld = np.array([dyn.leg_lengths(q) for q in res.q_d])
free = 0.03 * (ld - res.leg_lengths_measured) + 1e-5 * (res.plant["seal_temp"] - 293.15)
inside = np.all(np.abs(res.u) < 0.999 * res.u_max, axis=1)
reading = res.signals["seal_temp_meas"]  # the sensor's reading, logged
law = np.clip(0.03 * (ld - res.leg_lengths_measured) + 1e-5 * (reading - 293.15), -res.u_max, res.u_max)
out["noisy"] = {"engines": float(np.max(np.abs(noisy[0].u - noisy[1].u))),
                "readings": float(np.max(np.abs(reading - noisy[1].signals["seal_temp_meas"]))),
                "std": float(np.std((res.u - free)[inside] / 1e-5)), "rows": int(inside.sum()),
                "law": float(np.max(np.abs(res.u - law))),
                "reading_std": float(np.std(reading - res.plant["seal_temp"]))}
# the sensor's resolution (0.25 K) and bias (1.3 K), no noise: the reading is the true temperature plus the
# bias on the resolution's grid, both engines
rounded = [hydrogen.simulate("seal-sim", "p-seal", dyn=dyn, engine=e, seal_res=0.25, seal_bias=1.3)
           for e in ("c", "python")]
reading, true = rounded[0].signals["seal_temp_meas"], rounded[0].plant["seal_temp"]
out["rounded"] = {"engines": float(np.max(np.abs(reading - rounded[1].signals["seal_temp_meas"]))),
                  "grid": float(np.max(np.abs(reading - 0.25 * np.floor((true + 1.3) / 0.25 + 0.5)))),
                  "moved": float(np.max(np.abs(reading - 1.3 - true)))}
# every sensor's noise off, the part's too: the exported program's and the FMUs' noise-free run
from hydrogen.simulation.scenarios import scenario
out["quiet"] = scenario("seal-sim", dyn.model).noise_free()
# the exported program (the part's sensor noisy in the scenario): its errors are noise_free()'s run's
import re, subprocess
from hydrogen.export import export
folder = export(Path(sys.argv[2]) / "program", "seal-sim", "p-seal", dyn=dyn, seal_noise=0.5, seal_res=0.25,
                seal_bias=1.3)
run = subprocess.run(["make", "-s", "run"], cwd=folder, capture_output=True, text=True, timeout=600)
printed = [float(v) for v in re.findall(r"max_error \\S+ (\\S+) ", run.stdout)]  # in the coordinate's unit
quiet = hydrogen.simulate("seal-sim", "p-seal", dyn=dyn, **{"seal_noise": 0.5, "seal_res": 0.25, "seal_bias": 1.3,
                                                          **out["quiet"]})
pct = quiet.metrics["max_error_pct"]
out["program"] = [printed, [pct[c] / 100 * a for c, a in zip(quiet.coordinates, quiet.amplitude) if pct.get(c) is not None]]
# the runtime's own call: the part's state must be given, never an earlier call's left over
from hydrogen.simulation.simulator import prepare_run
ctrl = prepare_run(dyn, "seal-sim", "p-seal", None, None, True, {}).ctrl
args = (res.q[0], np.zeros(dyn.model.n), res.pressures[0], res.leg_lengths[0], np.zeros((4, dyn.model.n)), False)
given = ctrl.command(*args, plant={"seal_temp": np.full(2, 400.0)})
v = ctrl.values  # the run's gains (the description's u_max)
expected = np.clip(v["Kleg"] * (dyn.leg_lengths(np.zeros(dyn.model.n)) - args[3]) + v["kT"][0] * (400.0 - 293.15),
                   -v["u_max"][0], v["u_max"][0])
out["given"] = float(np.max(np.abs(given - expected)))
try:
    ctrl.command(*args)
except HydrogenError as exc:
    out["not_given"] = str(exc)
# the plant FMU's seal_temp outputs into the controller FMU's inputs of that name (delay 0: the master's
# step order is the timing), against the same run without noise
# and the part's sensor at a coarse resolution (2 K, the seals starting either side of a grid line): the
# controller FMU rounds the reading it is given as the loop's measure stage does
quiet = {"delay": 0.0, "noise_l": 0.0, "noise_p": 0.0, "noise_q": 0.0, "seal_res": 2.0, "seal_bias": -0.5,
         "seal_start": [281.4, 281.6]}
folder = Path(sys.argv[2])
fmus = [export_fmu(folder / f"{part}.fmu", part, "seal-sim", "p-seal", dyn=dyn, **quiet) for part in ("plant", "controller")]
from fmpy import read_model_description
seal = [v for v in read_model_description(str(fmus[1])).modelVariables if v.name.startswith("seal_temp.")]
out["fmu_inputs"] = [[v.name, v.causality, v.unit] for v in seal]
from test_fmu import _cosimulate
res = hydrogen.simulate("seal-sim", "p-seal", dyn=dyn, **quiet)
out["cosimulated"] = float(np.max(np.abs(_cosimulate(*fmus, len(res.t)) - res.q)))
unrounded = hydrogen.simulate("seal-sim", "p-seal", dyn=dyn, **{**quiet, "seal_res": 0.0, "seal_bias": 0.0})
out["resolution_moves"] = float(np.max(np.abs(unrounded.q - res.q)))
print(json.dumps(out))
'''


def test_a_controller_reads_a_rig_parts_state_by_name(cache, tmp_path):
    """A rig part's output (a seal temperature, one module of the plant) is a port a controller reads by
    its name: in a copy of the package with the part and a controller reading it (two modules, nothing
    else edited), the command follows the controller's law on the part's logged state on both engines
    (its true value at the period's start: an ideal sensor); with a delay predictor the engines agree;
    the controller FMU takes it as inputs of its name, which the plant FMU's outputs wire to; a sensor's
    noise the part declares is in the reading the command follows."""
    from conftest import run_in_a_copy
    from test_plant_blocks import SEAL_HEAT
    # the controller's own model of the part transfers heat: a predicted temperature differs from the reading
    ideal = '"heat transfer to the ambient (h)", per_actuator=True, ideal=20.0, lower=0.0)'
    SEAL_HEAT = SEAL_HEAT.replace('"heat transfer to the ambient (h)", per_actuator=True, lower=0.0)', ideal)
    assert ideal in SEAL_HEAT
    # and a sensor of its own, its noise a setting of the part's
    SEAL_HEAT = SEAL_HEAT.replace('output=True)', 'output=True, noise="seal_noise", resolution="seal_res", '
                                  'bias="seal_bias")', 1).replace(
        '    "seal_start":', '    "seal_noise": setting(0.0, "K", "each seal temperature sensor\'s noise", ">=0"),\n'
                            '    "seal_res": setting(0.0, "K", "each seal temperature sensor\'s resolution", ">=0"),\n'
                            '    "seal_bias": setting(0.0, "K", "each seal temperature sensor\'s offset", "number"),\n'
                            '    "seal_start":', 1)
    assert 'noise="seal_noise"' in SEAL_HEAT and '"seal_noise": setting' in SEAL_HEAT and '"seal_res": setting' in SEAL_HEAT
    text = (ROOT / "tests" / "data" / "four_way_arm.toml").read_text()
    text = text.replace('name = "four_way_arm"', 'name = "seal_arm"\ncontrollers = ["p-seal"]', 1)
    files = {"hydrogen/plant/seal_heat.py": SEAL_HEAT, "hydrogen/controllers/p_seal.py": P_SEAL,
             "seal_arm.toml": text + SEAL_SCENARIO}
    out = run_in_a_copy(cache, tmp_path, files, SEAL_SCRIPT, ["seal_arm.toml", "{cache}"])
    plain, predicted = out["False"], out["True"]
    assert plain["term"] > 1e-4  # m: the seal term moves the spools (280 K against 293.15 K)
    assert plain["law"] < 1e-12 and plain["engines"] < 1e-12
    # predicted: the controller's model (the part's ideal transfer, 20 W/K on 1 J/K) warms the seal
    # over the delay; the engines agree on it
    assert predicted["engines"] < 1e-12 and predicted["law"] > 1e-6
    assert out["given"] < 1e-15  # the law at the temperature given
    assert {k: v for k, v in out["quiet"].items() if k != "actuators"} == {
        "noise_l": 0.0, "noise_p": 0.0, "noise_q": 0.0, "noise_ps": 0.0, "seal_noise": 0.0}
    printed, simulated = out["program"]
    assert len(printed) == len(simulated) > 0 and max(abs(a / b - 1) for a, b in zip(printed, simulated)) < 1e-9
    noisy = out["noisy"]  # the reading's noise (0.5 K) in the command, the same draw on both engines
    assert noisy["engines"] < 1e-12 and noisy["rows"] > 100 and 0.4 < noisy["std"] < 0.6
    # the reading is a log of the run (both engines): the command is the law at it
    assert noisy["readings"] < 1e-12 and noisy["law"] < 1e-12 and 0.4 < noisy["reading_std"] < 0.6
    assert out["not_given"] == ("controller 'p-seal' reads the plant's seal_temp: give it with the signals "
                                "(command(..., plant={name: value}), or by name in command_for's signals)")
    assert out["fmu_inputs"] == [[f"seal_temp.{c}", "input", "K"] for c in ("shoulder_cylinder", "elbow_cylinder")]
    assert out["cosimulated"] < 1e-9  # rad: the two FMUs wired by name are the closed loop
    assert out["resolution_moves"] > 1e-6  # rad: with the part's sensor's bias and resolution, which change the run
    # a bias and a resolution the part declares offset and round its sensor's reading (the exported program's
    # and the FMUs' above too)
    rounded = out["rounded"]
    assert rounded["engines"] < 1e-12 and rounded["grid"] < 1e-9 and 1e-3 < rounded["moved"] <= 0.125 + 1e-9
