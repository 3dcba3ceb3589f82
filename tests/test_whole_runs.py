"""Whole runs of every shipped scenario equal the recorded ones, to rounding.

``tests/data/whole_runs.json`` holds, for every shipped robot, scenario and controller (and, for a
controller with the composite adaptation, its full variant too), samples of the run's trajectories
recorded from an earlier version. A change that moves code around (the layers, the block contract)
must leave every run as it was; a change meant to alter results re-records the file and says why in
its commit:

    python tests/test_whole_runs.py --record

The runs are the C loop's with the scenario's own noise seed; the samples are evenly spaced rows of
the series, so a difference anywhere in the run shows in the rows after it.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data" / "whole_runs.json"
#: Rows sampled from each series (and the last row).
SAMPLES = 12
#: The series compared, by SimulationResult attribute (``supply_pressure`` where the supply is a state).
SERIES = ("q", "pressures", "u", "leg_lengths_measured", "theta_hat", "gamma1_hat", "gamma2_hat", "supply_pressure")
#: The composite adaptation's rate the full-variant runs set (1/s); 0 (the defaults) runs the lean one.
FULL_VARIANT = {"rate_ls_gamma": 1.0, "rate_ls_theta": 1.0}
RTOL = 1e-7


def cases():
    """(robot, scenario, controller, variant) of every recorded run, from the data file: a
    controller added later has no recorded run and needs none."""
    if not DATA.is_file():
        return []
    return [tuple(k.split("|")) for k in json.loads(DATA.read_text())["runs"]]


def run(robot: str, scenario: str, controller: str, variant: str) -> dict:
    """The samples of one run: {series: rows}."""
    from hydrogen.runtime.build import default_dynamics
    from hydrogen.simulation.control import gain_names
    from hydrogen.simulation.simulator import simulate

    dyn = default_dynamics(robot, None, controller)
    gains = None
    if variant == "full":
        names = gain_names(controller, dyn.model)
        gains = {k: v for k, v in FULL_VARIANT.items() if k in names}
    res = simulate(dyn, scenario, controller, gains=gains)
    rows = np.unique(np.linspace(0, len(res.t) - 1, SAMPLES).astype(int))
    return {s: np.asarray(getattr(res, s), float)[rows].tolist() for s in SERIES
            if getattr(res, s) is not None} | {"t": res.t[rows].tolist()}


def variants(controller: str, model) -> tuple:
    """"default", and "full" for a controller whose composite rates run its full variant."""
    from hydrogen.simulation.control import gain_names
    return ("default", "full") if set(FULL_VARIANT) & gain_names(controller, model) else ("default",)


def shipped_runs():
    """(robot, scenario, controller, variant) of every run recorded: each scenario with each controller
    (and variant), and each scenario variant (``<scenario>.<variant>``) with the first controller."""
    import hydrogen
    from hydrogen.simulation.scenarios import VARIANT_SEPARATOR, scenario_names, variant_names

    for robot in hydrogen.models():
        model = hydrogen.load_model(robot)
        for scenario in scenario_names(model):
            for controller in model.controllers:
                for variant in variants(controller, model):
                    yield robot, scenario, controller, variant
            for named in variant_names(model):
                yield robot, f"{scenario}{VARIANT_SEPARATOR}{named}", model.controllers[0], "default"


def record() -> None:
    from hydrogen.fileio import atomic_write

    runs = {}
    for case in shipped_runs():
        runs["|".join(case)] = run(*case)
        print(*case, flush=True)
    atomic_write(DATA, json.dumps({"samples": SAMPLES, "runs": runs}, sort_keys=True, separators=(",", ":")) + "\n")


@pytest.mark.slow
@pytest.mark.parametrize("robot,scenario,controller,variant", cases(), ids="|".join)
def test_a_whole_run_equals_the_recorded_one(robot, scenario, controller, variant):
    recorded = json.loads(DATA.read_text())["runs"]["|".join((robot, scenario, controller, variant))]
    now = run(robot, scenario, controller, variant)
    assert set(now) == set(recorded)
    for series, rows in recorded.items():
        want, got = np.asarray(rows, float), np.asarray(now[series], float)
        scale = max(float(np.max(np.abs(want), initial=0.0)), 1e-300)
        np.testing.assert_allclose(got, want, rtol=RTOL, atol=RTOL * scale, err_msg=series)


def test_every_shipped_scenario_is_recorded():
    """Each shipped scenario and variant with every controller recorded (a new controller, not
    recorded, is not required; a scenario the data misses is)."""
    held = set(cases())
    recorded = {c for _, _, c, _ in held}
    missing = [case for case in shipped_runs() if case[2] in recorded and case not in held]
    assert not missing


if __name__ == "__main__" and sys.argv[1:] == ["--record"]:
    record()
