"""The plant's blocks (hydrogen/plant/): found by themselves, composed by the names of the signals
they hand each other (hydrogen/symbolic/plant.py), their inputs of numbers read off their
declarations by the loop, the Python engine, the FMU and the description. The proof: a rig part
added as one module (a counterbalance spring along each cylinder, and a seal temperature with a
state, written into a copy of the package, nothing else edited) loads, generates, builds and runs
on both engines on a robot with a pump, and its force and rate are the ones its law says."""
import json
import os
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest

from hydrogen import plant
from hydrogen.symbolic.plant import PlantWiringError, _output_order

ROOT = Path(__file__).resolve().parents[1]


SHIPPED = ("mechanics", "chambers", "friction", "valve", "supply")


def test_the_blocks_are_found_in_their_declared_order():
    assert plant.BLOCKS[:len(SHIPPED)] == SHIPPED  # a block added later comes after them
    # the plant's inputs of numbers follow the blocks' order: plant_rhs's arguments after gamma2
    assert [i.name for i in plant.plant_inputs({"seal_friction": True})][:2] == ["friction", "valve"]
    assert [i.width for i in plant.plant_inputs({})][:2] == [3, 5]  # [F_c, b, v_s] without seal friction


def test_a_manifest_records_each_inputs_parameters(robot_model):
    from hydrogen.layout import model_summary
    summary = model_summary(robot_model)
    assert summary["plant_inputs"]["valve"] == ["lag", "omega", "zeta", "overlap", "full_opening"]
    # the loop's layout takes the widths from the record, whatever structure decided them
    assert ([i.width for i in plant.plant_inputs(summary)] ==
            [i.width for i in plant.plant_inputs(robot_model)])


def test_a_manifest_written_before_the_records_renders_the_same_loop(robot_model):
    """A manifest from before the plant inputs and outputs were recorded (a user's cache): the loop's
    layout falls back to the blocks' rules on it and renders the same drivers."""
    import copy

    from hydrogen.layout import loop_context, model_summary
    from hydrogen.templating import render
    from hydrogen.codegen.generate import DRIVERS, TEMPLATES
    now = {"model": model_summary(robot_model)}
    old = copy.deepcopy(now)
    del old["model"]["plant_inputs"]
    shipped = {st.name for b in SHIPPED for st in plant.block(b).STATES}
    for part in old["model"]["plant"]:
        if part["name"] in shipped:  # a manifest before the records knew only the shipped blocks
            del part["output"]
    for template, _ in DRIVERS:
        assert render(template, loop_context(old), TEMPLATES) == render(template, loop_context(now), TEMPLATES)


def test_every_module_the_loops_layout_reads_shapes_a_hash():
    """An edit of what the loop drivers are rendered from stales the generated folder: every module of
    the package the layout imports is hashed (its file, or its folder) with the drivers or the functions."""
    import ast

    import hydrogen.layout
    from hydrogen.codegen.generate import DERIVATION_DIRS, DERIVATION_FILES, DRIVER_DIRS, DRIVER_FILES
    tree = ast.parse(Path(hydrogen.layout.__file__).read_text())
    imported = {node.module.split(".")[0] for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.level == 1
                 and not node.module for alias in node.names}
    assert imported  # the layout does import the package's modules
    missing = sorted(m for m in imported if f"{m}.py" not in (*DERIVATION_FILES, *DRIVER_FILES)
                     and m not in (*DERIVATION_DIRS, *DRIVER_DIRS))
    assert not missing, f"in no hash: {missing}"


def test_a_number_outside_its_declared_range_is_refused_naming_it(plain_stewart):
    model = plain_stewart  # the rig's valve on every leg (no datasheet valve)
    from dataclasses import replace

    from hydrogen.errors import ScenarioError
    from hydrogen.simulation.scenarios import scenario
    sc = replace(scenario("paper-sim", model), valve_bandwidth_hz=80.0, valve_damping=0.0)  # unchecked
    name = model.cylinders[0].name
    with pytest.raises(ScenarioError, match=rf"'paper-sim': valve\.{name}\.zeta = 0\.0 must be finite and > 0\.0"):
        plant.input_values(sc, model)


def _fake(name, reads=(), writes=(), adds=()):
    sym = types.SimpleNamespace(READS=reads, WRITES=writes, ADDS=adds)
    return types.SimpleNamespace(__name__=f"hydrogen.plant.{name}", Symbolic=sym)


def test_the_outputs_run_after_what_they_read():
    a, b, c = _fake("a", reads=("y",)), _fake("b", reads=("x",), writes=("y",)), _fake("c", writes=("x",))
    assert [m.__name__[-1] for m in _output_order([a, b, c], set())] == ["c", "b", "a"]
    # a sum is read once every block adding to it has run
    s, t, u = _fake("s", reads=("f",)), _fake("t", adds=("f",)), _fake("u", reads=("g",), adds=("f",))
    v = _fake("v", writes=("g",))
    assert [m.__name__[-1] for m in _output_order([s, t, u, v], set())] == ["t", "v", "u", "s"]


@pytest.mark.parametrize("mods, words", [
    ([_fake("a", reads=("nowhere",))], "plant block 'a' reads the signal 'nowhere', which no block writes"),
    ([_fake("a", reads=("y",), writes=("x",)), _fake("b", reads=("x",), writes=("y",))],
     "in a cycle: 'a' reads 'y'; 'b' reads 'x'"),
])
def test_an_unwired_or_cyclic_plant_is_refused(mods, words):
    with pytest.raises(PlantWiringError, match=words.replace("(", r"\(").replace(")", r"\)")):
        _output_order(mods, set())


def _composition():
    import sympy as sp

    from hydrogen.symbolic.plant import Composition
    c = Composition(None, {"f": "sum_f"})
    c.block = "b"
    return c, sp.symbols("x y")


def test_a_sum_is_one_intermediate_of_every_term_added():
    c, (x, y) = _composition()
    c.add("f", [x])
    c.add("f", [-y])
    (sym,) = c["f"]
    assert c.intermediates[-1][1][0] == x - y and c.signals["f"][0] == sym


@pytest.mark.parametrize("act, words", [
    (lambda c, x: (c.add("f", [x]), c["f"], c.add("f", [x])), "adds to 'f' after it was read: add to it in "
     "Symbolic.outputs"),
    (lambda c, x: (setattr(c, "adds", set()), c.add("f", [x])), "adds to 'f', which its Symbolic.ADDS does not"),
    (lambda c, x: (c.states.append("s"), c.provide("s", [x, x]), c.rate("s", [x])), "gives 1 rate\\(s\\) of its state 's', which has 2 "
     "entries"),
    (lambda c, x: c.provide("f", [x]), "writes the signal 'f', a sum the blocks add to"),
    (lambda c, x: (c.provide("s", x), c.provide("s", x)), "writes the signal 's', written already"),
    (lambda c, x: c.add("g", [x]), "adds to 'g', which no block declares a sum"),
    (lambda c, x: (c.states.append("s"), c.provide("s", [x]), c.rate("s", [x]), c.rate("s", [x])),
     "gives the rate of 's', given already"),
    (lambda c, x: c.rate("typo", [x]), "gives a rate of 'typo', which is no state of the plant"),
    (lambda c, x: (c.provide("s", x), setattr(c, "reads", set()), c["s"]), "reads the signal 's' in its outputs, "
     "which its Symbolic.READS does not declare"),
])
def test_a_wiring_mistake_in_a_block_is_refused_naming_it(act, words):
    c, (x, _) = _composition()
    with pytest.raises(PlantWiringError, match=f"plant block 'b' {words}"):
        act(c, x)


def test_two_blocks_naming_one_symbol_are_refused_naming_both(monkeypatch):
    """SymPy takes two symbols of one name for one: a block whose input reuses another's symbol names
    would silently feed both from one input. The composition refuses it, naming both blocks."""
    import hydrogen
    from hydrogen.symbolic.plant import plant_rhs

    model = hydrogen.load_model("excavator_arm")
    friction = plant.block("friction").Symbolic.input
    monkeypatch.setattr(plant.block("valve").Symbolic, "input", staticmethod(lambda m: friction(m)))
    with pytest.raises(PlantWiringError, match=r"plant block 'valve' \(its input 'valve'\) names a symbol '.+' that "
                                               r"plant block 'friction' \(its input 'friction'\) names too"):
        plant_rhs(model)


#: A rig part as a developer adds one: this module alone, dropped into hydrogen/plant/.
SPRING = '''\
"""A counterbalance spring along each cylinder (a gas spring beside it, as on cranes and
excavator booms): force -k (l - l_0) along the cylinder, N, at its length l (m)."""
from __future__ import annotations

import numpy as np

from ..setting import setting
from . import PlantParameter

#: After the shipped blocks (a number no real block is likely to take: the test's own).
POSITION = 9060
STATES = ()
INPUT = "spring"
PARAMETERS = (
    PlantParameter("rate", lambda t: f"{t.force_unit}/{t.unit}", "spring rate (k)", per_actuator=True),
    PlantParameter("free_length", lambda t: t.unit, "length where the spring is relaxed (l_0)",
                   per_actuator=True),
)
SCENARIO_SETTINGS = {
    "spring_rate": setting(0.0, "N/m", "every cylinder's counterbalance spring rate (0: none)", ">=0"),
    "spring_length": setting(0.0, "m", "its free length", ">=0"),
}


def check_own(sc, name, value):
    from ..errors import ScenarioError
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
        raise ScenarioError(f"scenario '{sc.name}': actuators.{name}.spring must be a rate >= 0 N/m, got {value!r}")
    return False  # checked here


#: A cylinder's own spring rate: actuators.<name>.spring in a scenario.
ACTUATOR_SETTINGS = {"spring": check_own}


def input_parameters(structure):
    return PARAMETERS


def values(sc, model):
    return np.array([(sc.actuators.get(c.name, {}).get("spring", sc.spring_rate), sc.spring_length)
                     for c in model.cylinders], float)


class Symbolic:
    READS = ("l", INPUT)
    ADDS = ("leg_force",)

    @staticmethod
    def input(model):
        import sympy as sp
        return sp.Matrix([s for i in range(model.n_cylinders)
                          for s in sp.symbols(f"k_spring_{i} l_spring_{i}", real=True)])

    @staticmethod
    def outputs(c):
        k, l = c[INPUT], c["l"]
        c.add("leg_force", [-k[2 * i] * (l[i] - k[2 * i + 1]) for i in range(c.model.n_cylinders)])

    @staticmethod
    def derivatives(c):
        pass
'''

#: A rig part with a state: each seal's temperature T (K), heated by its friction's power and cooled to
#: the ambient, dT/dt = (|F_fric l̇| - h (T - T_amb)) / C_th; it starts at a scenario's setting and is an
#: output.
SEAL_HEAT = '''\
"""Each actuator's seal temperature (K): heated by its friction, cooled to the ambient."""
from __future__ import annotations

import numpy as np

from ..setting import setting
from . import PlantParameter, PlantState

POSITION = 9070
STATES = (PlantState("seal_temp", "m", "K", "seal temperature", lower=0.0, initial="seal_start", output=True),)
INPUT = "seal_heat"
PARAMETERS = (
    PlantParameter("transfer", "W/K", "heat transfer to the ambient (h)", per_actuator=True, lower=0.0),
    PlantParameter("capacity", "J/K", "heat capacity (C_th)", per_actuator=True, ideal=1.0, lower=0.0, strict=True),
    PlantParameter("ambient", "K", "ambient temperature", per_actuator=True, ideal=293.15, lower=0.0, strict=True),
)
SCENARIO_SETTINGS = {
    "seal_transfer": setting(1.0, "W/K", "each seal's heat transfer to the ambient", ">=0"),
    "seal_capacity": setting(50.0, "J/K", "each seal's heat capacity", ">=0"),
    "seal_start": setting(293.15, "K", "each seal's temperature where a run starts", ">=0", entries=True),
}


def input_parameters(structure):
    return PARAMETERS


def values(sc, model):
    return np.array([(sc.seal_transfer, sc.seal_capacity, 293.15)] * model.n_cylinders, float)


class Symbolic:
    @staticmethod
    def states(model):
        import sympy as sp
        return {"seal_temp": sp.Matrix(sp.symbols(f"seal_temp_0:{model.n_cylinders}", real=True))}

    @staticmethod
    def input(model):
        import sympy as sp
        return sp.Matrix([s for i in range(model.n_cylinders)
                          for s in sp.symbols(f"h_seal_{i} c_seal_{i} t_amb_{i}", real=True)])

    @staticmethod
    def derivatives(c):
        import sympy as sp
        T, f, v, p = c["seal_temp"], c["friction_force"], c["ldot"], c[INPUT]
        c.rate("seal_temp", sp.Matrix([(sp.Abs(f[i] * v[i]) - p[3 * i] * (T[i] - p[3 * i + 2])) / p[3 * i + 1]
                                       for i in range(c.model.n_cylinders)]))
'''

#: Run in the copy: the block is found, the description takes its settings, the arm builds, both
#: engines agree with the spring on, the plant's rate moves by the spring's law, the FMU names it.
SCRIPT = '''\
import json, sys
from pathlib import Path
import numpy as np
import hydrogen
import hydrogen.errors
from hydrogen.plant import BLOCKS, initial_state, plant_inputs, plant_layout, slot
from hydrogen.simulation.simulator import simulate

out = {"blocks": list(BLOCKS)}
model = hydrogen.load_model(sys.argv[1])
out["inputs"] = [i.name for i in plant_inputs(model)]
import hydrogen.codegen.generate as gen
from hydrogen.runtime.build import generated_dir_for
derived, real = [], gen.derive
def watched(model, numbers, controllers=None, **k):
    derived.append([list(model.controllers if controllers is None else controllers), k.get("core", True)])
    return real(model, numbers, controllers, **k)
gen.derive = watched
dyn = hydrogen.build(model, cache=Path(sys.argv[2]))  # the folder generated before the parts were added
gen.derive = real
out["derived"] = derived
import tempfile
with tempfile.TemporaryDirectory() as tmp:  # what a whole generation writes
    gen.render(model, Path(tmp))
    folder = generated_dir_for(model, cache=Path(sys.argv[2]))
    out["whole_differs"] = sorted(p.name for p in Path(tmp).iterdir() if p.read_bytes() != (folder / p.name).read_bytes())
f = dyn.functions
out["plant_rhs"] = list(f["plant_rhs"].in_names)
runs = {e: simulate(dyn, "spring-sim", "backstepping", engine=e) for e in ("c", "python")}
off = simulate(dyn, "spring-sim", "backstepping", spring_rate=0.0)
out["engines"] = float(np.max(np.abs(runs["c"].q - runs["python"].q)))
out["spring_moves"] = float(np.max(np.abs(runs["c"].pressures - off.pressures)))
own = simulate(dyn, "spring-sim", "backstepping", actuators={"elbow_cylinder": {"spring": 0.0}})
out["own"] = [float(np.max(np.abs(own.pressures - r.pressures))) for r in (runs["c"], off)]
try:
    simulate(dyn, "spring-sim", "backstepping", actuators={"elbow_cylinder": {"spring": -1.0}})
except hydrogen.errors.HydrogenError as exc:
    out["own_error"] = str(exc)
temps = {e: r.plant["seal_temp"] for e, r in runs.items()}
out["temps"] = [float(np.max(np.abs(temps["c"] - temps["python"]))), temps["c"][0].tolist(), temps["c"][-1].tolist()]
runs["c"].save_log(Path(sys.argv[2]) / "run.csv")
out["csv"] = (Path(sys.argv[2]) / "run.csv").read_text().splitlines()[2].split(",")
# the plant's rate with the spring against without: dq̈ = D^-1 JL^T (-k (l - l0))
q = np.array(model.neutral_pose, float) + [0.05, -0.1]
n, m = model.n, model.n_cylinders
layout = plant_layout(model)  # q, qdot, p_A and p_B, spool, spool rate, ps, seal_temp
out["layout"] = [part.name for part in layout]
x = initial_state(layout, q=q, qdot=[0.1, -0.2], pc=np.full(2 * m, 5e6), seal_temp=[310.0, 280.0])
# every plant input by name: the blocks' ideal numbers, the spring's own
given = {"x": x, "u": np.zeros(m), "theta": model.theta, "gamma1": model.gamma[0], "gamma2": model.gamma[1],
         **{i.name: np.tile(i.ideal, m) for i in plant_inputs(model)}}
names = [k for k in f["plant_rhs"].in_names if k != "numbers"]
# the run starts at rest: its pressures hold the robot against gravity and the springs
from hydrogen.plant import input_values
from hydrogen.simulation.simulator import equilibrium_pressures, plan_run
plan = plan_run(dyn, "spring-sim", "backstepping", None, False, {})
run_inputs = {k: v.ravel() for k, v in input_values(plan.sc, model).items()}
def qdd_at(x0):
    args = {**given, "x": x0, **run_inputs}
    return np.asarray(f["plant_rhs"](*[args[a] for a in names]), float).ravel()[n:2 * n]
gravity_only = initial_state(layout, plan.sc, q=plan.q0, pc=equilibrium_pressures(dyn, plan.q0, model.theta))
out["rest"] = [float(np.max(np.abs(qdd_at(plan.x0)))), float(np.max(np.abs(qdd_at(gravity_only))))]
k, l0 = 2.0e4, 0.5
spring = np.tile([k, l0], m)
with_spring = np.asarray(f["plant_rhs"](*[spring if a == "spring" else given[a] for a in names]), float).ravel()
without = np.asarray(f["plant_rhs"](*[given[a] for a in names]), float).ravel()  # the spring's ideal: none
D = np.asarray(f["mass_matrix"](q, model.theta), float)
JL = np.asarray(f["leg_jacobian"](q), float)
l = np.asarray(f["leg_lengths"](q), float).ravel()
expected = np.linalg.solve(D, JL.T @ (-k * (l - l0)))
out["qdd_change"] = (with_spring[n:2 * n] - without[n:2 * n]).tolist()
out["qdd_expected"] = expected.tolist()
out["rest_unchanged"] = float(np.max(np.abs(np.delete(with_spring - without, range(n, 2 * n)))))
# the seal's heating at the blocks' ideal numbers but the friction and heat given here
fr, heat = np.tile([50.0, 200.0, 1e-3], m), np.tile([1.0, 50.0, 293.15], m)
rate = np.asarray(f["plant_rhs"](*[fr if a == "friction" else heat if a == "seal_heat" else given[a] for a in names]),
                  float).ravel()[slot(layout, "seal_temp").slice]
ldot = JL @ np.array([0.1, -0.2])
force = 50.0 * np.tanh(ldot / 1e-3) + 200.0 * ldot
out["heat"] = [rate.tolist(), ((np.abs(force * ldot) - 1.0 * (np.array([310.0, 280.0]) - 293.15)) / 50.0).tolist()]
from fmpy import read_model_description
from hydrogen.fmu import export_fmu
# the closed loop's FMU compiles the loop's configuration with the spring's numbers (params.h)
export_fmu(Path(sys.argv[2]) / "loop.fmu", "closed-loop", "spring-sim", dyn=dyn, controller="backstepping", duration=0.05)
path = export_fmu(Path(sys.argv[2]) / "arm.fmu", "plant", "spring-sim", dyn=dyn, controller="backstepping",
                  duration=0.05)
var = {v.name: v for v in read_model_description(str(path)).modelVariables}
rate = var["spring.shoulder_cylinder.rate"]
out["fmu"] = [rate.unit, float(rate.start), var["spring.elbow_cylinder.free_length"].unit]
temp, start = var["seal_temp.shoulder_cylinder"], var["seal_temp_start.elbow_cylinder"]
out["fmu_state"] = [temp.causality, temp.unit, start.causality, start.unit, float(start.start)]
# a start per actuator: each entry checked at load time, their count when the run starts
text = Path(sys.argv[1]).read_text()
refused = {}
for label, value in (("negative", "[280.0, -1.0]"), ("count", "[280.0, 285.0, 290.0]"), ("one", "[280.0]")):
    bad = Path(sys.argv[2]) / f"{label}.toml"
    bad.write_text(text.replace("seal_start = [280.0, 285.0]", f"seal_start = {value}"))
    try:
        simulate(hydrogen.build(hydrogen.load_model(bad), cache=Path(sys.argv[2])), "spring-sim", "backstepping",
                 duration=0.01)
    except hydrogen.errors.HydrogenError as exc:
        refused[label] = str(exc)
out["refused"] = refused
print(json.dumps(out))
'''

SCENARIO = """
[scenarios.spring-sim]
label = "spring-sim: the arm on its counterbalance springs"
duration = 0.5
control_rate = 1000.0
substeps = 2
t_adapt = 0.5
spring_rate = 20000.0
spring_length = 0.5
friction = [50.0, 200.0, 1e-3]
seal_start = [280.0, 285.0]
reference.sines = [["shoulder", 0.10, 1.0], ["elbow", -0.10, 1.5]]
"""


#: Run in the copy before the parts are added: the arm's folder generated in the cache.
BEFORE = """\
import sys
from pathlib import Path
import hydrogen
from hydrogen.codegen.generate import generate
from hydrogen.runtime.build import generated_dir_for
model = hydrogen.load_model(sys.argv[1])
generate(model, generated_dir_for(model, cache=Path(sys.argv[2])))
"""


@pytest.fixture(scope="module")
def spring_run(tmp_path_factory):
    """The package copied, the arm generated, then the spring's and the seal's modules added (nothing
    else), and the script's findings."""
    root = tmp_path_factory.mktemp("spring")
    ignore = shutil.ignore_patterns("__pycache__", "*.so", "_templates")
    shutil.copytree(ROOT / "hydrogen", root / "hydrogen", ignore=ignore)
    shutil.copytree(ROOT / "templates", root / "templates")
    text = (ROOT / "tests" / "data" / "four_way_arm.toml").read_text()
    text = text.replace('name = "four_way_arm"', 'name = "spring_arm"\ncontrollers = ["backstepping"]', 1)
    from test_supply import PUMP_TABLE  # a pump with an accumulator: the supply pressure is a state
    (root / "bare_arm.toml").write_text(text + PUMP_TABLE)  # its scenario takes the parts' settings
    (root / "before.py").write_text(BEFORE)
    env = {**os.environ, "PYTHONPATH": str(root)}
    proc = subprocess.run([sys.executable, str(root / "before.py"), str(root / "bare_arm.toml"), str(root / "cache")],
                          cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (root / "hydrogen" / "plant" / "spring.py").write_text(SPRING)
    (root / "hydrogen" / "plant" / "seal_heat.py").write_text(SEAL_HEAT)
    (root / "spring_arm.toml").write_text(text + SCENARIO + PUMP_TABLE)
    (root / "run.py").write_text(SCRIPT)
    proc = subprocess.run([sys.executable, str(root / "run.py"), str(root / "spring_arm.toml"), str(root / "cache")],
                          cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_rig_part_added_as_one_module_is_found_and_wired(spring_run):
    blocks, inputs = spring_run["blocks"], spring_run["inputs"]
    assert blocks[:len(SHIPPED)] == list(SHIPPED) and blocks.index("spring") < blocks.index("seal_heat")
    assert inputs[:2] == ["friction", "valve"] and inputs.index("spring") < inputs.index("seal_heat")
    names = spring_run["plant_rhs"]  # the generated plant takes it, after the shipped blocks' inputs
    assert names[:7] == ["x", "u", "theta", "gamma1", "gamma2", "friction", "valve"]
    assert names.index("spring") < names.index("seal_heat")


def test_adding_a_rig_part_derives_the_plant_alone_and_writes_a_whole_generations_code(spring_run):
    """The arm's folder generated before the parts were added: its build derives the plant's function
    alone (no rigid body, no controller again), and the folder reads as a whole generation's."""
    assert spring_run["derived"] == [[[], ["plant"]]]
    assert spring_run["whole_differs"] == []


def test_the_added_part_runs_on_both_engines_and_changes_the_run(spring_run):
    assert spring_run["engines"] < 1e-9
    assert spring_run["spring_moves"] > 1e3  # Pa: the pressures carry the spring's force


def test_the_added_part_takes_its_own_setting_per_actuator_and_checks_it(spring_run):
    assert all(d > 1e3 for d in spring_run["own"])  # the elbow's own spring: unlike both others
    assert spring_run["own_error"] == "scenario 'spring-sim': actuators.elbow_cylinder.spring must be a rate >= 0 N/m, got -1.0"


def test_a_run_starts_at_rest_against_the_added_parts_force(spring_run):
    held, gravity_only = spring_run["rest"]
    assert gravity_only > 1.0  # rad/s²: the springs would jolt the arm from pressures against gravity alone
    assert held < 1e-9


def test_the_added_part_adds_its_law_to_the_plant(spring_run):
    change, expected = spring_run["qdd_change"], spring_run["qdd_expected"]
    assert max(abs(e) for e in expected) > 1.0  # the spring matters at this pose
    assert change == pytest.approx(expected, rel=1e-9, abs=1e-9)
    assert spring_run["rest_unchanged"] == 0.0  # the pressures' and spool's rates do not see it


def test_the_fmu_declares_the_added_parts_numbers_with_their_units(spring_run):
    assert spring_run["fmu"] == ["N/m", 20000.0, "m"]


def test_a_rig_part_with_a_state_joins_x_after_the_supply_and_starts_as_declared(spring_run):
    layout = spring_run["layout"]
    assert layout[:6] == ["q", "qdot", "pc", "spool", "spool_rate", "ps"] and "seal_temp" in layout
    c_minus_python, first, last = spring_run["temps"]
    assert c_minus_python < 1e-9
    assert first == [280.0, 285.0]  # its declared initial value (a scenario's, per actuator), logged before the plant moves
    assert all(t > 280.0 + 1e-3 for t in last)  # the ambient and the friction's power heat it


def test_a_rig_parts_rate_is_its_law_on_the_other_blocks_signals(spring_run):
    rate, expected = spring_run["heat"]
    assert rate == pytest.approx(expected, rel=1e-12)


def test_a_rig_parts_state_is_an_output_of_the_log_and_the_fmu(spring_run):
    assert {"seal_temp0", "seal_temp1", "ps0"} <= set(spring_run["csv"])
    assert spring_run["fmu_state"] == ["output", "K", "parameter", "K", 285.0]  # the elbow's start


def test_a_start_per_actuator_is_checked_entry_by_entry_and_counted(spring_run):
    refused = spring_run["refused"]
    assert "seal_start" in refused["negative"] and ">= 0, or a list of such, one per entry (K), got [280.0, -1.0]" in refused["negative"]
    for label in ("count", "one"):  # a list gives every entry: never broadcast
        assert "seal_start" in refused[label] and "must be one number or 2" in refused[label]


def test_a_sensor_is_declared_on_an_output_with_a_setting_of_its_block():
    """A state's sensor noise (PlantState.noise) is refused on a state that is no output, and naming a
    setting its block does not declare, each with its own words; so is a resolution without a sensor or
    of a setting the block does not declare."""
    import types

    from hydrogen.plant import PlantState, _check_sensors
    from hydrogen.setting import setting
    own = {"temp_noise": setting(0.0, "K", "the sensor's noise", ">=0")}
    inner = types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", noise="temp_noise"),), SCENARIO_SETTINGS=own)
    with pytest.raises(ImportError, match="plant block 'heat' gives its state 'temp' a sensor's noise 'temp_noise', "
                                          "but the state is no output"):
        _check_sensors("heat", inner)
    unknown = types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", output=True, noise="typo"),),
                                    SCENARIO_SETTINGS=own)
    with pytest.raises(ImportError, match="the sensor's noise setting 'typo', which its SCENARIO_SETTINGS does not"):
        _check_sensors("heat", unknown)
    _check_sensors("heat", types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", output=True,
                                                                    noise="temp_noise"),), SCENARIO_SETTINGS=own))
    # a resolution rounds a sensor's reading: it needs the sensor, and a setting of the block's
    own = {**own, "temp_res": setting(0.0, "K", "the sensor's resolution", ">=0")}
    bare = types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", output=True, resolution="temp_res"),),
                                 SCENARIO_SETTINGS=own)
    with pytest.raises(ImportError, match="a sensor's resolution 'temp_res', but no sensor"):
        _check_sensors("heat", bare)
    typo = types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", output=True, noise="temp_noise",
                                                    resolution="typo"),), SCENARIO_SETTINGS=own)
    with pytest.raises(ImportError, match="the sensor's resolution setting 'typo', which its SCENARIO_SETTINGS"):
        _check_sensors("heat", typo)
    offset = types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", output=True, bias="temp_res"),),
                                   SCENARIO_SETTINGS=own)
    with pytest.raises(ImportError, match="a sensor's bias 'temp_res', but no sensor"):
        _check_sensors("heat", offset)
    _check_sensors("heat", types.SimpleNamespace(STATES=(PlantState("temp", "m", "K", "t", output=True, noise="temp_noise",
                                                                    resolution="temp_res"),), SCENARIO_SETTINGS=own))


def test_an_output_may_not_take_a_loop_ports_name(robot_model):
    """A plant output named as one of the loop's ports (other than the supply pressure, which is its
    measurement) could not be read by a controller: refused naming it."""
    from hydrogen.layout import model_summary, plant_ports
    summary = model_summary(robot_model)
    summary["plant"] = [*summary["plant"], {"name": "adapt", "size": "m", "start": 0, "entries": 1, "output": True}]
    with pytest.raises(ImportError, match="declares the output 'adapt', the name of one of the loop's ports"):
        plant_ports(summary)


def test_a_blocks_law_that_fails_on_a_robot_is_refused_naming_it(monkeypatch):
    """A block's own law that fails on a robot (it reads a parameter that robot's actuator kind lacks) is
    a PlantWiringError naming the block, the robot and the error (a clear line from the CLI)."""
    import hydrogen
    from hydrogen.symbolic.plant import plant_rhs

    model = hydrogen.load_model("ubc_stewart")
    real = plant.block("friction").Symbolic.outputs

    def reads_a_tank(c):
        real(c)
        c["laws"]["tank_pressure"]  # a mistake of its own code on this robot (laws: one per actuator)

    monkeypatch.setattr(plant.block("friction").Symbolic, "outputs", staticmethod(reads_a_tank))
    with pytest.raises(PlantWiringError, match=r"plant block 'friction': its Symbolic.outputs failed on robot "
                                               r"'ubc_stewart': (KeyError|TypeError|IndexError)"):
        plant_rhs(model)


@pytest.mark.parametrize("value", ["abc", float("nan"), float("inf"), True, [1.0, float("nan")], [1.0, 2.0, 3.0]])
def test_a_sensors_numbers_are_finite_reals_of_its_size(value):
    """A sensor's bias or resolution (hydrogen.plant.sensor_numbers) from a setting declared without a
    check reaches the loop as given: anything but one finite number or one per entry is refused naming
    the setting and the sensor, never a NaN reading."""
    import types

    from hydrogen.errors import ScenarioError
    from hydrogen.plant import Slot, sensor_numbers

    part = Slot("temp", "heat", "m", 0, 2, ("K", "K"), (0.0, 0.0), (1e9, 1e9), ("a", "b"), "t", (0.0, 0.0), True,
                None, "temp_noise", "", "temp_bias")
    ok = sensor_numbers([part], types.SimpleNamespace(name="s", temp_bias=[1.0, -2.0]), "bias")
    assert ok["temp"].tolist() == [1.0, -2.0]
    with pytest.raises(ScenarioError, match=r"temp_bias = .*the bias of the plant's temp sensor \(heat\), must be "
                                            r"one finite number or 2"):
        sensor_numbers([part], types.SimpleNamespace(name="s", temp_bias=value), "bias")
