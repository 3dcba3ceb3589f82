"""The loop's estimators (hydrogen/estimators/): found by themselves, each one module that declares its
settings, its selection, its loop state and configuration numbers, its design, its start, its numpy
update and the same update's C statements, which the C loop, the ctypes mirror, the Python engine, the
export and the FMU read. The proof: an estimator added as one module (a first-order filtered backward
difference of the measured travel, written into a copy of the package, nothing else edited) is
selected by a shipped robot's scenario, built, run on both engines (equal), gives the controller the
rates its formula says, and its bad setting is refused naming it."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen import estimators
from hydrogen.errors import HydrogenError, ScenarioError

ROOT = Path(__file__).resolve().parents[1]


def test_the_kalman_filter_is_found_and_selected_by_its_own_switch(model):
    from hydrogen.simulation.scenarios import scenario, scenario_names
    assert estimators.ESTIMATORS[:1] == ("kalman",)
    assert estimators.switches()["kalman"] == "kalman"
    for name in scenario_names(model):
        sc = scenario(name, model)  # kalman = true keeps meaning the Kalman filter
        assert estimators.selected(sc) == ("kalman" if sc.kalman else None), name


def test_the_general_selector_names_the_same_filter(model):
    from hydrogen.simulation.scenarios import scenario
    sc = scenario("paper-sim", model)
    assert estimators.selected(sc) is None  # the ideal rate sensor
    assert estimators.selected(sc.with_overrides(estimator="kalman")) == "kalman"
    # both the switch and the selector on the same estimator select it once
    assert estimators.selected(sc.with_overrides(estimator="kalman", kalman=True)) == "kalman"
    est = estimators.estimate_for(sc.with_overrides(estimator="kalman"), 1 / 512)
    np.testing.assert_array_equal(est.config()["kf_gain"],
                                  estimators.estimate_for(sc.with_overrides(kalman=True), 1 / 512).config()["kf_gain"])


@pytest.mark.parametrize("overrides, words", [
    (dict(estimator="nope"), ["estimator = 'nope' is not an estimator", '"ideal"', '"kalman"']),
    (dict(estimator=3), ["estimator = 3 is not an estimator"]),
])
def test_an_unknown_estimator_is_refused_naming_the_setting(model, overrides, words):
    from hydrogen.simulation.scenarios import scenario
    with pytest.raises(ScenarioError) as err:
        scenario("paper-sim", model).with_overrides(**overrides)
    for w in words:
        assert w in str(err.value)


def test_an_unknown_estimator_in_a_description_is_refused_naming_the_file(tmp_path):
    from hydrogen.model import model_path
    from hydrogen.simulation.scenarios import scenario
    text = model_path("excavator_arm").read_text()
    path = tmp_path / "arm.toml"
    shutil.copy(model_path("excavator_arm").with_suffix(".urdf"), tmp_path)  # the description's URDF
    path.write_text(text.replace("[scenarios.arm-sim]\n", '[scenarios.arm-sim]\nestimator = "kalmann"\n', 1))
    with pytest.raises(HydrogenError) as err:
        scenario("arm-sim", hydrogen.load_model(path))
    assert "arm.toml: [scenarios.arm-sim]" in str(err.value) and "estimator = 'kalmann'" in str(err.value)


def test_a_missing_or_clashing_declaration_is_refused_naming_the_module(tmp_path):
    """An estimator module lacking a declaration, or naming a loop field another part owns, is an
    ImportError naming it (the package copied, one module added, imported in a child process)."""
    for text, words in ((f'NAME = "half"\nPOSITION = 5\n', ["estimator 'half'", "does not declare", "DOC"]),
                        (_FILTERED.replace('STATE = LoopState("fd"', 'STATE = LoopState("kf"'),
                         ["estimator 'filtered_difference'", "'kf'", "estimator 'kalman'"]),
                        (_FILTERED.replace("POSITION = 2", "POSITION = 1"), ["same POSITION 1"])):
        root = _copy(tmp_path / f"c{len(list(tmp_path.iterdir()))}", text)
        proc = subprocess.run([sys.executable, "-c", "import hydrogen.estimators"], cwd=root, capture_output=True,
                              text=True, env={**os.environ, "PYTHONPATH": str(root)}, timeout=120)
        assert proc.returncode != 0 and "ImportError" in proc.stderr, proc.stderr[-2000:]
        for w in words:
            assert w in proc.stderr, (w, proc.stderr[-2000:])


#: The estimator added as one module: each actuator's rate as the backward difference of its measured
#: travel, (l_k - l_{k-1}) / h, through a first-order low-pass of cut-off f_c (weight 1 - exp(-2 pi f_c h)).
_FILTERED = '''\
"""A first-order filtered backward difference of each actuator's measured travel l (m or rad): the rate
(l_k - l_(k-1)) / h low-passed with the weight a = 1 - exp(-2 pi f_c h) (f_c: difference_cutoff_hz, Hz)."""
import math

import numpy as np

from ..setting import setting
from . import ConfigNumbers, LoopState

NAME = "filtered_difference"
POSITION = 2
DOC = "first-order filtered backward difference of the actuators' travel"
SCENARIO_SETTINGS = {
    "difference_cutoff_hz": setting(40.0, "Hz", "the backward difference's low-pass cut-off", ">0"),
}
STATE = LoopState("fd", (2, "NL"), "filtered difference: last measured lengths, filtered rates")
CONFIG = (ConfigNumbers("fd_weight", 1),)
CONFIG_DOC = "filtered backward difference (use_filtered_difference != 0), its low-pass weight fd_weight"


def design(sc, h):
    return 1.0 - math.exp(-2.0 * math.pi * sc.difference_cutoff_hz * h)


def config(weight):
    return {"fd_weight": [weight]}


def start(l0):
    l0 = np.asarray(l0, float)
    return np.vstack([l0, np.zeros_like(l0)])


C_START = """\\
            st->fd[i] = l0[i];
            st->fd[NL + i] = 0.0;
"""


def update(state, l_meas, weight, h):
    d = (l_meas - state[0]) / h
    return np.vstack([np.asarray(l_meas, float), state[1] + weight * (d - state[1])])


def rate(state):
    return state[1].copy()


C_COMMENT = "the backward difference, low-passed"
C_UPDATE = """\\
            double d = (s->l_meas[i] - st->fd[i]) / c->h;
            st->fd[NL + i] = st->fd[NL + i] + c->fd_weight[0] * (d - st->fd[NL + i]);
            st->fd[i] = s->l_meas[i];
            s->ldot[i] = st->fd[NL + i];
"""
'''

#: Run in the copy: the estimator is found, a shipped robot's rig scenario selects it, both engines run
#: it, the controller's rates are the formula's on the logged measured lengths, the FMU builds with it.
SCRIPT = '''\
import json, math, sys
from pathlib import Path
import numpy as np
import hydrogen
from hydrogen import estimators
from hydrogen.errors import HydrogenError
from hydrogen.simulation.simulator import PythonStages, make_runner, prepare_run, simulate

out = {"estimators": list(estimators.ESTIMATORS)}
from hydrogen.schema import description_table
out["table"] = [line for line in description_table().splitlines() if "difference_cutoff_hz" in line
                or "`estimator`" in line]
model = hydrogen.load_model("excavator_arm")
dyn = hydrogen.build(model, cache=Path(sys.argv[1]), controllers=["backstepping"])
ov = dict(kalman=False, estimator="filtered_difference", difference_cutoff_hz=30.0)
runs = {e: simulate(dyn, "arm-dig", "backstepping", duration=0.25, engine=e, **ov) for e in ("c", "python")}
kal = simulate(dyn, "arm-dig", "backstepping", duration=0.25)
out["engines"] = [float(np.max(np.abs(runs["c"].q - runs["python"].q))),
                  float(np.max(np.abs(runs["c"].u - runs["python"].u)))]
out["other_than_kalman"] = float(np.max(np.abs(runs["c"].u - kal.u)))
# the rates the controller received (the Python engine's, period by period), against the formula on the
# lengths the C run logged
p = prepare_run(dyn, "arm-dig", "backstepping", None, 0.25, True, ov)
loop = PythonStages(dyn, p.sc, p.ctrl, p.x0.copy(), p.q0, p.estimate, p.h)
ldot, qdot, q_meas = [], [], []
for k in range(p.n):
    loop.k = k
    s = loop.run_period(p.noise[k])
    ldot.append(s.ldot.copy()); qdot.append(s.qdot_meas.copy()); q_meas.append(loop.q_meas.copy())
l_meas = runs["c"].leg_lengths_measured
h, weight = p.h, 1.0 - math.exp(-2.0 * math.pi * 30.0 * p.h)
prev, v, hand = dyn.leg_lengths(p.q0), np.zeros(model.n_cylinders), []
for row in l_meas:
    v = v + weight * ((row - prev) / h - v)
    prev = row
    hand.append(v)
hand = np.array(hand)
out["rates"] = [float(np.max(np.abs(np.array(ldot) - hand))), float(np.max(np.abs(hand)))]
out["velocities"] = float(max(np.max(np.abs(np.linalg.solve(dyn.leg_jacobian(q), r) - qd))
                              for q, r, qd in zip(q_meas, hand, qdot)))
# the C loop's own state after the run: the last measured lengths and the filtered rates
runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
runner.run(p.n, p.noise)
fd = np.array(runner.state.fd[:]).reshape(2, -1)
out["c_state"] = [float(np.max(np.abs(fd[0] - l_meas[-1]))), float(np.max(np.abs(fd[1] - hand[-1])))]
out["c_config"] = [int(runner.cfg.use_filtered_difference), int(runner.cfg.use_kalman), float(runner.cfg.fd_weight[0]),
                   weight]
errors = {}
for name, bad in (("cutoff", dict(ov, difference_cutoff_hz=0.0)), ("two", dict(estimator="filtered_difference"))):
    try:
        simulate(dyn, "arm-dig", "backstepping", duration=0.05, **bad)
    except HydrogenError as exc:
        errors[name] = [type(exc).__name__, str(exc)]
import shutil
bad = Path(sys.argv[1]) / "arm.toml"
shutil.copy(hydrogen.model.model_path("excavator_arm").with_suffix(".urdf"), bad.parent)
text = hydrogen.model.model_path("excavator_arm").read_text()
bad.write_text(text.replace("[scenarios.arm-sim]\\n", "[scenarios.arm-sim]\\ndifference_cutoff_hz = -5.0\\n", 1))
try:
    hydrogen.load_model(bad)
except HydrogenError as exc:
    errors["file"] = [type(exc).__name__, str(exc)]
out["errors"] = errors
from hydrogen.fmu import export_fmu
from fmpy import simulate_fmu
path = export_fmu(Path(sys.argv[1]) / "loop.fmu", "closed-loop", "arm-dig", dyn=dyn, controller="backstepping", duration=0.05,
                  **ov)
coords = list(model.coordinate_names)
fmu = simulate_fmu(str(path), output=[f"q.{c}" for c in coords])
quiet = dict(ov, noise_l=0.0, noise_p=0.0, noise_q=0.0)
ref = simulate(dyn, "arm-dig", "backstepping", duration=0.05, **quiet)
q = np.column_stack([fmu[f"q.{c}"] for c in coords])
out["fmu"] = [int(len(fmu)), int(len(ref.t)), float(np.max(np.abs(q - ref.q)))]
# the exported program: its params.h, main.c and build files carry the estimator's numbers and start
import subprocess
from hydrogen.export import export
folder = export(Path(sys.argv[1]) / "prog", "arm-dig", "backstepping", duration=0.05, dyn=dyn, **ov)
made = subprocess.run(["make"], cwd=folder, capture_output=True, text=True)
ran = subprocess.run([str(folder / json.loads((folder / "export.json").read_text())["program"])],
                     capture_output=True, text=True) if made.returncode == 0 else None
cmake = subprocess.run(["cmake", "-S", ".", "-B", "build"], cwd=folder, capture_output=True, text=True) \
    if shutil.which("cmake") else None
out["export"] = {"make": [made.returncode, made.stderr[-800:]], "run": None if ran is None else [ran.returncode, ran.stdout[-300:]],
                 "cmake": None if cmake is None else [cmake.returncode, cmake.stderr[-800:]],
                 "params": (folder / "params.h").read_text()}
print(json.dumps(out))
'''


def _copy(root: Path, module: str) -> Path:
    """hydrogen and its templates copied under ``root``, with ``module`` added as an estimator."""
    ignore = shutil.ignore_patterns("__pycache__", "*.so", "_templates")
    shutil.copytree(ROOT / "hydrogen", root / "hydrogen", ignore=ignore)
    shutil.copytree(ROOT / "templates", root / "templates")
    (root / "hydrogen" / "estimators" / "filtered_difference.py").write_text(module)
    return root


@pytest.fixture(scope="module")
def difference_run(tmp_path_factory):
    """The package copied with the filtered difference's module added (nothing else), and the
    script's findings."""
    root = _copy(tmp_path_factory.mktemp("difference"), _FILTERED)
    (root / "run.py").write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": str(root)}
    env.pop("HYDROGEN_CACHE_DIR", None)
    proc = subprocess.run([sys.executable, str(root / "run.py"), str(root / "cache")], cwd=root, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_an_estimator_added_as_one_module_is_found_and_selectable(difference_run):
    found = difference_run["estimators"]  # the shipped filter first; a developer's own may sit between
    assert found[0] == "kalman" and "filtered_difference" in found
    rows = "\n".join(difference_run["table"])  # the description table follows the declarations
    assert '"filtered_difference" (first-order filtered backward difference' in rows
    assert "| `difference_cutoff_hz` | Hz | 40.0 | *filtered_difference estimator*:" in rows


def test_the_added_estimator_runs_on_both_engines_alike(difference_run):
    dq, du = difference_run["engines"]
    assert dq < 1e-10 and du < 1e-10
    assert difference_run["other_than_kalman"] > 1e-6  # it is another estimator than the rig's filter


def test_the_controller_receives_the_formulas_rates(difference_run):
    """The rates are the low-passed backward difference of the logged measured lengths, and the
    velocities JL⁻¹ of them at the measured pose."""
    err, size = difference_run["rates"]
    assert size > 1e-4 and err <= 1e-12 * max(size, 1.0)
    assert difference_run["velocities"] < 1e-9
    last_l, last_rate = difference_run["c_state"]  # the C loop's state holds the same numbers
    assert last_l == 0.0 and last_rate <= 1e-12 * max(size, 1.0)
    on, kalman, weight, expected = difference_run["c_config"]
    assert (on, kalman) == (1, 0) and weight == expected


def test_the_added_estimators_bad_setting_is_refused_naming_it(difference_run):
    errors = difference_run["errors"]
    kind, text = errors["cutoff"]
    assert kind == "ScenarioError" and "difference_cutoff_hz must be finite and > 0" in text, text
    kind, text = errors["two"]  # the rig's kalman = true and the general selector
    assert kind == "ScenarioError" and "kalman = true" in text and 'estimator = "filtered_difference"' in text
    assert "select two estimators" in text and "write kalman = false" in text, text
    kind, text = errors["file"]  # the description's own value, at load time, naming the file and the key
    assert kind == "ModelError" and "arm.toml" in text and "difference_cutoff_hz" in text and "> 0" in text, text


def test_the_added_estimator_runs_in_the_fmu(difference_run):
    rows, expected, err = difference_run["fmu"]
    assert rows == expected > 10 and err < 1e-9


def test_the_added_estimator_runs_in_the_exported_program(difference_run):
    """The exported C program builds with its Makefile (warnings as errors), runs, and its CMake project
    configures; params.h carries the estimator's switch and numbers."""
    got = difference_run["export"]
    assert got["make"][0] == 0, got["make"][1]
    assert got["run"][0] == 0 and "status 0" in got["run"][1], got["run"]
    if got["cmake"] is not None:
        assert got["cmake"][0] == 0, got["cmake"][1]
    assert "P_USE_FILTERED_DIFFERENCE" in got["params"] and "P_USE_KALMAN" in got["params"]
