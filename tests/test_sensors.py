"""The sensors' noise row (hydrogen/sensors.py): its channels' columns for every robot shape, each
drawn where its setting is on and nowhere else, read at the same columns by the C loop and the
Python engine."""
import numpy as np
import pytest

import hydrogen
from hydrogen.sensors import NOISE, noise_columns, noise_width
from hydrogen.simulation.simulator import plan_run, simulate

SIZES = {"NL": 3, "NPC": 6, "NQ": 4, "NPS": 1}


def test_the_channels_follow_each_other_in_their_declared_order():
    assert [ch.name for ch in NOISE] == ["l", "pc", "q", "ps"]
    assert noise_columns(SIZES, encoders=True) == {"l": (0, 3), "pc": (3, 6), "q": (9, 4), "ps": (13, 1)}
    assert noise_width(SIZES, encoders=True) == 14


def test_a_robot_without_encoders_or_a_supply_state_has_no_columns_for_them():
    assert noise_columns({**SIZES, "NPS": 0}, encoders=False) == {"l": (0, 3), "pc": (3, 6)}
    assert noise_columns(SIZES, encoders=False) == {"l": (0, 3), "pc": (3, 6), "ps": (9, 1)}


@pytest.fixture(scope="module")
def arm(cache):
    """The excavator arm: joint encoders and a pump, so every channel has columns."""
    return hydrogen.build(hydrogen.load_model("excavator_arm"), cache=cache)


QUIET = {"noise_l": 0.0, "noise_p": 0.0, "noise_q": 0.0, "noise_ps": 0.0, "quantization_l": 0.0, "actuators": {}}


@pytest.mark.parametrize("channel", [ch for ch in NOISE])
def test_each_channel_is_drawn_in_its_own_columns_only(arm, channel):
    from hydrogen.layout import robot_sizes
    columns = noise_columns(robot_sizes(arm.library.manifest["model"]), arm.model.joint_encoders)
    plan = plan_run(arm, "arm-dig", "p", 0.05, False, {**QUIET, channel.setting: 1e-3})
    table = plan.noise(3)
    start, count = columns[channel.name]
    assert np.all(table[:, start:start + count] != 0)
    assert not np.any(np.delete(table, range(start, start + count), axis=1))


def test_both_engines_read_the_noise_at_the_same_columns(arm):
    noisy = {**QUIET, "noise_l": 2e-5, "noise_p": 2e4, "noise_q": 1e-4, "noise_ps": 5e4}
    c, py = (simulate(arm, "arm-dig", "p", duration=0.05, engine=e, seed=7, **noisy) for e in ("c", "python"))
    assert np.max(np.abs(c.q - py.q)) < 1e-12 and np.max(np.abs(c.pressures - py.pressures)) < 1e-3
    quiet = simulate(arm, "arm-dig", "p", duration=0.05, seed=7, **QUIET)
    assert np.max(np.abs(c.pressures - quiet.pressures)) > 0  # the noise reached the loop
