"""The hydraulic motor (hydrogen/actuators/motor.py): a kind added as one module. A two-link arm whose
elbow turns without limit on a motor (a continuous joint) and whose shoulder is a four-way cylinder
loads, generates, builds and runs closed loop with every controller, past a full turn; its physics
checks are tests/test_actuators.py's (on tests/data/actuators/motor.toml)."""
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.simulation.simulator import simulate
from hydrogen.actuators import KINDS, actuator
from hydrogen.controllers import CONTROLLERS
from hydrogen.errors import HydrogenError

#: The controllers that use the model (the P baselines only bound the error).
MODEL_BASED = ("backstepping", "adaptive-robust", "adaptive-observer")
ARM = Path(__file__).parent / "data" / "four_way_arm.toml"
#: The arm's elbow on a motor: no angle range (the joint has no limits: continuous).
MOTOR_ELBOW = """[[cylinders]]
name = "elbow_motor"
kind = "motor"
joint = "elbow"
displacement = 2.0e-5              # D_m, m^3/rad: 200 N m at 10 MPa, 2.5x the forearm's weight torque
volume_A = 2.0e-4                  # m^3: line and motor case, side A (0.2 L)
volume_B = 2.0e-4
"""
#: The elbow turns more than a full turn (7 rad from its start) while the shoulder swings.
TURN = """
[scenarios.motor-turn]
label = "motor-turn: the elbow past a full turn"
duration = 3.4
control_rate = 1000.0
substeps = 2
t_adapt = 0.5
metric_start = 1.0
reference.sines = [["shoulder", 0.10, 0.30], ["elbow", 7.0, 0.08]]
"""


def motor_arm_text() -> str:
    text = ARM.read_text()
    start = text.index('[[cylinders]]\nname = "elbow_cylinder"')
    end = text.index("[adaptation]")
    text = text[:start] + MOTOR_ELBOW + "\n" + text[end:]
    # the motor's torque loop in N m/rad (no default for a torque loop, as for the rotary vane)
    text = text.replace("[gains.common]\n", "[gains.common]\nGtau_inv = [1.0e4, 317.0]\n", 1)
    return text.replace('name = "four_way_arm"', 'name = "motor_arm"', 1) + TURN


@pytest.fixture(scope="module")
def arm_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("motor") / "motor_arm.toml"
    path.write_text(motor_arm_text())
    return path


@pytest.fixture(scope="module")
def arm(arm_path, cache):
    return hydrogen.build(hydrogen.load_model(arm_path), cache=cache)


def test_the_motor_is_a_registered_kind_of_unlimited_travel():
    mod = actuator("motor")
    assert "motor" in KINDS and mod.MOTION == "revolute" and not mod.TRAVEL.limited
    assert mod.TRAVEL.unit == "rad" and [s.unit for s in mod.SENSORS][0] == "rad"
    assert mod.COUPLING_GAIN is None


def test_the_arm_loads_with_no_angle_range(arm_path):
    m = hydrogen.load_model(arm_path)
    c = m.cylinders[1]
    assert (c.kind, c.joint, c.stroke_min, c.stroke_max) == ("motor", "elbow", -math.inf, math.inf)
    assert c.table["volume_A"] == 2e-4 and c.table["displacement"] == 2e-5
    assert m.number_ranges()["elbow_motor.volume_B"] == (1e-9, 100.0)


def test_the_motors_torque_and_spring_rate():
    """τ = D_m (p_A − p_B); f0 = −θ̇ D_m² (1/V_A + 1/V_B) at every angle (constant volumes), and its
    potential's rate is f0 past any number of turns."""
    mod = actuator("motor")
    P = mod.parameters(dict(displacement=2e-5, volume_A=2e-4, volume_B=3e-4, supply_pressure=1e7, flow_gain=1e-4,
                            bulk_modulus=1e9))
    assert mod.Numeric.force((6e6, 2e6), P) == pytest.approx(2e-5 * 4e6)
    k = 2e-5 ** 2 * (1 / 2e-4 + 1 / 3e-4)
    for theta in (-20.0, 0.0, 7.0, 100.0):
        assert mod.Numeric.f0(theta, 1.5, (5e6, 5e6), P) == pytest.approx(-1.5 * k)
        h = 1e-4
        rate = (mod.Numeric.f0_potential(theta + h * 1.5, P) - mod.Numeric.f0_potential(theta - h * 1.5, P)) / (2 * h)
        assert rate == pytest.approx(-1.5 * k)


@pytest.mark.parametrize("old,new,words", [
    ("volume_A = 2.0e-4", "volume_A = -2.0e-4", ["[[cylinders]] 'elbow_motor' volume_A", "must be > 0", "-0.0002"]),
    ("volume_B = 2.0e-4", "volume_B = 5.0e3", ["[[cylinders]] 'elbow_motor' volume_B", "5000 m^3",
                                               "plausible range [1e-09, 100] m^3", "hydrogen.actuators.motor"]),
    ("volume_B = 2.0e-4\n", "", ["'elbow_motor'", "missing key 'volume_B'"]),
    ('joint = "elbow"\n', 'joint = "elbow"\nangle = [-3.0, 3.0]\n', ["'elbow_motor' (kind motor)",
                                                                   "unknown key 'angle'"]),
])
def test_a_bad_motor_is_refused_with_a_clear_message(tmp_path, old, new, words):
    text = motor_arm_text()
    assert old in text
    path = tmp_path / "arm.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    for w in [str(path), *words]:
        assert w in str(err.value), (w, str(err.value))


def _applies(arm, name):
    """Whether ``name`` runs on the arm: a controller that does not refuses with a HydrogenError."""
    try:
        simulate(arm, "motor-turn", name, duration=0.01)
    except HydrogenError as exc:
        return str(exc)
    return None


@pytest.mark.parametrize("controller", list(CONTROLLERS))
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_every_controller_turns_the_motor_past_a_full_turn(arm, controller, seed):
    """Closed loop on the arm with sensor noise of three seeds: the elbow turns more than 2π from its
    start, tracking stays bounded, every pressure inside its bounds, nothing NaN."""
    why = _applies(arm, controller)
    if why is not None:
        pytest.skip(f"{controller} does not apply: {why}")
    res = simulate(arm, "motor-turn", controller, seed=seed, noise_q=1e-5)
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.pressures))
    elbow = res.q[:, 1]
    assert elbow.max() - elbow[0] > 2 * math.pi
    err = np.abs(res.q - res.q_d)[res.t >= 1.0].max(axis=0)
    # every loop bounded; the model-based ones track within 1 % of each amplitude (P: about 5 % on the elbow)
    assert np.all(err < (0.01 if controller in MODEL_BASED else 0.5) * res.amplitude), (err, res.amplitude)
    from hydrogen.pressures import bounds
    lo, hi = bounds(arm.model)
    assert np.all(res.pressures >= lo - 1.0) and np.all(res.pressures <= hi + 1.0)


def test_the_arm_generates_and_its_fmu_names_the_angle_in_rad(arm, tmp_path):
    from fmpy import read_model_description

    from hydrogen.fmu import export_fmu
    path = export_fmu(tmp_path / "arm.fmu", "plant", "motor-turn", dyn=arm, controller="p", duration=0.1)
    assert zipfile.is_zipfile(path)
    var = {v.name: v for v in read_model_description(str(path)).modelVariables}
    assert (var["l.elbow_motor"].unit, var["ldot.elbow_motor"].unit) == ("rad", "rad/s")
    assert var["l.elbow_motor"].description == "angle of actuator elbow_motor"
    assert var["l.shoulder_cylinder"].unit == "m"
