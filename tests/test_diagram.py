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
