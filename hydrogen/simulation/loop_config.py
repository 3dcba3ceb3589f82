"""The closed loop's configuration values for one run, from the rows of :data:`hydrogen.layout.LOOP_CONFIG`.

Each row names its source: ``scenario.<field>`` is the scenario's field as it is; ``run.<name>`` is
one of the values :data:`DERIVED` computes here from the run (model, scenario, controller, control
period, the estimator's design). The runtime's loop (:class:`hydrogen.runtime.loop.LoopRunner`) and the exported
params.h (:func:`hydrogen.export.export_context`) both take :func:`config_values`, so a value is
computed once for both. Arrays are never empty (C has no zero-length arrays): an absent reference term
or controller state is one row of zeros, as its count says.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .. import references
from ..estimators import ESTIMATORS, estimator, switch_field
from ..plant import initial_state, plant_layout, sensor_numbers, supply
from ..layout import FK_MAX_COND, FK_MAX_ITER, FK_TOL, LOOP_CONFIG, PLANT_INPUTS, delay_split


def _chambers(model):
    """The chamber pressures' part of ``model``'s plant state (its bounds)."""
    return {part.name: part for part in plant_layout(model)}["pc"]

__all__ = ["Run", "DERIVED", "config_values", "FK_TOL", "FK_MAX_ITER"]


@dataclass(frozen=True)
class Run:
    """What a run's configuration is derived from: the compiled dynamics ``dyn`` (its model), the
    scenario ``sc``, the controller runtime ``ctrl``, the control period ``h`` (s) and the estimator
    ``estimate`` (:class:`hydrogen.estimators.Estimate`: its name and design, or None: ideal rate sensors)."""
    dyn: object
    sc: object
    ctrl: object
    h: float
    estimate: object = None

    @functools.cached_property
    def plant_inputs(self) -> dict:
        """Each plant input's numbers for the run (:func:`hydrogen.plant.input_values`), worked out once."""
        from ..plant import input_values
        return input_values(self.sc, self.dyn.model)


def _plant_input(name):
    """A plant input's numbers for the run, flat: its block's rule, held to its declared ranges
    (:func:`hydrogen.plant.input_values`)."""
    return lambda r: r.plant_inputs[name].ravel()


def _per_actuator(key):
    """A per-actuator rig setting, flat: :func:`hydrogen.simulation.scenarios.actuator_settings`."""
    from .scenarios import actuator_settings
    return lambda r: actuator_settings(r.sc, r.dyn.model)[key].ravel()


def _estimator_values() -> dict:
    """Each estimator's switch (1 where the run uses it) and numbers (its design's; zeros where the run
    does not use it: the C loop does not read them)."""
    out = {}
    for name in ESTIMATORS:
        mine = lambda r, n=name: r.estimate is not None and r.estimate.name == n  # noqa: E731
        out[switch_field(name)] = lambda r, mine=mine: int(mine(r))
        for f in estimator(name).CONFIG:
            out[f.name] = (lambda r, mine=mine, f=f: r.estimate.config()[f.name] if mine(r) else np.zeros(f.size))
    return out


def _sensor_numbers(kind: str):
    """Each rig part's sensor's ``kind`` ("resolution", "bias": :func:`hydrogen.plant.sensor_numbers`),
    the sensed outputs' entries in order, flat (one unread 0 where no output is sensed)."""
    def value(run) -> np.ndarray:
        values = list(sensor_numbers(plant_layout(run.dyn.model), run.sc, kind).values())
        return np.concatenate(values) if values else np.zeros(1)
    return value


def _bounds(run, i):
    b = np.asarray(run.ctrl.bounds[i], float)
    b = np.where(np.isfinite(b), b, -1e300 if i == 0 else 1e300)  # the C loop's "unbounded"
    return b if b.size else np.zeros(1)


def _slots(run):
    return list(run.ctrl.slots)  # wired by the controller runtime (hydrogen.diagram.wire)


def _at(block):
    """Offset of the controller's state block ``block`` in xc (-1: it has none: the predictor then
    uses the controller's initial parameters)."""
    return lambda r: r.ctrl.offset(block)


#: Each ``run.<name>`` source: how its value follows from the run.
DERIVED = {
    "h": lambda r: float(r.h),
    "delay_periods": lambda r: delay_split(r.sc.delay, r.h)[0],
    "delay_fraction": lambda r: delay_split(r.sc.delay, r.h)[1],
    "theta": lambda r: np.asarray(r.dyn.model.theta, float),
    "gamma1": lambda r: np.asarray(r.dyn.model.gamma[0], float),
    "gamma2": lambda r: np.asarray(r.dyn.model.gamma[1], float),
    **{name: _plant_input(name) for name in PLANT_INPUTS},  # each block's input of numbers (friction, valve)
    "quantization_l": _per_actuator("quantization_l"),
    "sensor_resolution": _sensor_numbers("resolution"),
    "sensor_bias": _sensor_numbers("bias"),
    **_estimator_values(),  # each estimator's switch and numbers (hydrogen.estimators)
    # the reference's fields, each kind's (hydrogen.references): its own values, the others' idle ones
    **{name: (lambda r, k=name: references.config_values(r.sc.reference)[k])
       for name, _, _ in references.config_fields()[1]},
    "slot": _slots,
    "n_xc": lambda r: int(r.ctrl.xc.size),
    "xc_lo": lambda r: _bounds(r, 0),
    "xc_hi": lambda r: _bounds(r, 1),
    "xc_euler": lambda r: int(r.sc.estimator_update == "euler"),
    "bound_stages": lambda r: int(r.sc.pressure_bounds == "stage"),
    "predict": lambda r: int(r.sc.predicts()),
    "pred_theta": lambda r: np.asarray(r.ctrl.theta0, float),
    # the predictor's start where it measures nothing: every part at its declared initial value
    "pred_x0": lambda r: initial_state(plant_layout(r.dyn.model), r.sc),
    "pred_gamma1": lambda r: np.asarray(r.ctrl.gamma0[0], float),
    "pred_gamma2": lambda r: np.asarray(r.ctrl.gamma0[1], float),
    "pred_theta_at": _at("theta_hat"),
    "pred_gamma1_at": _at("gamma1_hat"),
    "pred_gamma2_at": _at("gamma2_hat"),
    # the plant's own bounds (its layout's: a kind's [0, P_s], up to the supply's ceiling where the
    # supply is a state), the Python stages' clip too
    "pressure_low": lambda r: np.array(_chambers(r.dyn.model).lower, float),
    "pressure_high": lambda r: np.array(_chambers(r.dyn.model).upper, float),
    "numbers": lambda r: np.zeros(1) if r.dyn.numbers is None else np.asarray(r.dyn.numbers, float),
    "supply_feedback": lambda r: int(bool(r.sc.supply_feedback)),
    "ps_nominal": lambda r: supply.nominal(r.dyn.model),
    "fk_tol": lambda r: FK_TOL,
    "fk_max_iter": lambda r: FK_MAX_ITER,
    "fk_max_cond": lambda r: FK_MAX_COND,
}


def _value(source: str, run: Run):
    kind, _, name = source.partition(".")
    if kind == "scenario":
        value = getattr(run.sc, name)
        return np.asarray(value, float) if isinstance(value, (tuple, list)) else value
    if kind == "run" and name in DERIVED:
        return DERIVED[name](run)
    raise ValueError(f"hydrogen.layout.LOOP_CONFIG: unknown source '{source}' "
                     "(scenario.<field> or run.<name> of hydrogen.simulation.loop_config.DERIVED)")


def config_values(run: Run) -> dict:
    """Every configuration field that has a source, by field name: numbers (``double``, ``long long``)
    or float arrays (``const double*``, ``double[<n>]``) or a list of ints (``slots``)."""
    return {name: _value(src, run) for _, fields in LOOP_CONFIG for name, _, _, src in fields if src}
