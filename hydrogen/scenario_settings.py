"""What a scenario table of a description may hold: the fields of a scenario (each setting with its
default, unit, meaning and check, declared by the part of the loop that reads it), the keys of
``[scenarios.<name>]``, ``[rig]`` and ``[variants.<name>]`` tables, the renamed fields and the separator
of ``<scenario>.<variant>``.

A part that is a module of its own declares its settings there (``SCENARIO_SETTINGS``: the plant's
integration :mod:`hydrogen.plant.integrator`, each block of the plant that has any (its friction
:mod:`hydrogen.plant.friction` and valve :mod:`hydrogen.plant.valve`, found by
:data:`hydrogen.plant.BLOCKS`), each estimator (:data:`hydrogen.estimators.ESTIMATORS`: the Kalman filter
:mod:`hydrogen.estimators.kalman`), with the general selector ``estimator``); the loop's other
parts (the run, the sensors, the computation delay, the delay predictor, the adaptation's schedule, the
controller's start) declare theirs below. :data:`PARTS` gathers them in the description table's order.

Plain data: the description's loader (:mod:`hydrogen.model`, :mod:`hydrogen.schema`) checks a
table's keys against it without the simulation, and :class:`hydrogen.simulation.scenarios.Scenario`
is these fields with a run's behaviour (checks, overrides, the delay's split).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, make_dataclass

from .estimators import ESTIMATORS, estimator as estimator_module, selector_setting
from .plant import BLOCKS as PLANT_BLOCKS, block as plant_block, integrator
from .setting import setting

__all__ = ["ScenarioFields", "PARTS", "PER_ACTUATOR", "actuator_keys", "Part", "setting", "settings", "part_of", "table_keys", "RENAMED",
           "VARIANT_SEPARATOR"]

#: The rig settings that act on one actuator's travel, given per actuator in its own unit (the kind's
#: TRAVEL: m for a cylinder, rad for a rotary vane) under ``actuators.<name>``, besides those a plant
#: block declares (:func:`hydrogen.plant.actuator_settings`: the valve's spool response). The
#: scenario's own field (in a cylinder's units) is every cylinder's default; a joint actuator's
#: friction defaults to none, and it must give the others itself where the scenario's are on (never a
#: length in m applied to an angle). An estimator's numbers are one for all (the Kalman filter's gain,
#: dimensionless and 1/s, which kalman_accel designs with the scenario's noise_l and quantization_l).
PER_ACTUATOR = ("friction", "quantization_l", "noise_l")


def actuator_keys() -> list:
    """Every key a scenario may give per actuator (``actuators.<name>.<key>``): :data:`PER_ACTUATOR`, then
    the plant blocks' own (:func:`hydrogen.plant.actuator_settings`)."""
    from .plant import actuator_settings
    return [*PER_ACTUATOR, *(k for k in actuator_settings() if k not in PER_ACTUATOR)]


#: Scenario fields that were renamed: the old name and what to write instead (named in the error).
RENAMED = {"delay_periods": "delay (the computation delay in s; one period is 1/control_rate)"}


@dataclass(frozen=True)
class Part:
    """A part of the loop and the scenario settings it reads: ``name`` (the description table's label),
    ``settings`` ({field name: :func:`setting`}, in order)."""

    name: str
    settings: dict


_RUN = {
    "duration": setting(None, "s", "length of the run", "number"),
    "control_rate": setting(None, "Hz", "control rate, zero-order hold", "number"),
    "metric_start": setting(0.0, "s", "metrics over t ≥ this (clamped to the run)", "number"),
    "q0_offset": setting((), "m, rad", "start pose offset from q_d(0), one per coordinate",
                         default_text="0 for every coordinate"),
    "seed": setting(0, "", "noise seed"),
}
_SENSORS = {
    "quantization_l": setting(0.0, "m", "cylinder-length encoder resolution (0: none)", ">=0"),
    "noise_l": setting(0.0, "m", "std of white cylinder-length noise", ">=0"),
    "noise_q": setting(0.0, "rad or m", "std of white joint-encoder noise (robots with joint encoders)", ">=0"),
    "noise_p": setting(0.0, "Pa", "std of white pressure noise", ">=0"),
    "noise_ps": setting(0.0, "Pa", "std of white noise on the measured supply pressure (a [supply] that is "
                        "not constant)", ">=0"),
}
_HOLD = {
    "delay": setting(0.0, "s", "computation delay: the command computed at t_k is applied from t_k + this (0 to "
                     "8 control periods; a fraction of a period switches the command inside the plant's "
                     "sub-steps)", "number"),
}
_PREDICTOR = {
    "predictor": setting(False, "", "delay compensation: the command is computed at the state predicted for "
                         "t_k + delay by the controller's own model (its estimates where it adapts them, "
                         "ideal valve, no friction) over the commands still in flight, and at the reference "
                         "of that time"),
    "predictor_substeps": setting(4, "", "the predictor's RK4 steps per control period (a fraction of a period "
                                  "takes its share, at least one)"),
}
_SCHEDULE = {
    "t_adapt": setting(None, "s", "adaptation switched on from this time", "number"),
}
_CONTROLLER = {
    "theta0_factor": setting((), "", "initial θ̂ = θ × factor, one per parameter",
                             default_text="1 for every parameter"),
    "gamma0_factor": setting((1.0, 1.0), "", "initial [γ̂1, γ̂2] = γ × factor"),
    "estimator_update": setting("semi-implicit", "", 'controller state update: "semi-implicit" or "euler"'),
    "supply_feedback": setting(True, "", "the controllers read the measured supply pressure in their ps "
                               "input; false: the description's supply_pressure, a controller assuming a "
                               "constant supply (a [supply] that is not constant)"),
}

#: The parts of the loop whose settings a scenario holds, in the description table's order.
PARTS = (
    Part("run", _RUN),
    Part("plant integration", integrator.SCENARIO_SETTINGS),
    # each plant block's own (hydrogen.plant.BLOCKS: friction, valve), under its name
    *(Part(name, plant_block(name).SCENARIO_SETTINGS) for name in PLANT_BLOCKS
      if getattr(plant_block(name), "SCENARIO_SETTINGS", None)),
    Part("sensors", _SENSORS),
    # the general selector, then each estimator's own (hydrogen.estimators.ESTIMATORS), under its name
    Part("estimator", {"estimator": selector_setting()}),
    *(Part(f"{name} estimator", estimator_module(name).SCENARIO_SETTINGS) for name in ESTIMATORS),
    Part("computation delay", _HOLD),
    Part("delay predictor", _PREDICTOR),
    Part("adaptation schedule", _SCHEDULE),
    Part("controller", _CONTROLLER),
)


def _assemble():
    seen = {}
    for part in PARTS:
        for name in part.settings:
            if name in seen:
                raise RuntimeError(f"scenario setting '{name}' is declared by both {seen[name]} and {part.name}")
            seen[name] = part.name
    own = [("name", str), ("reference", object)]
    declared = [(name, object, decl) for part in PARTS for name, decl in part.settings.items()]
    rest = [("actuators", dict, field(default_factory=dict)),  # actuator name -> {PER_ACTUATOR setting: value}
            ("gains", dict, field(default_factory=dict)),  # controller name -> gain overrides for this scenario
            ("label", str, field(default="")),  # caption in figures and tables
            ("paper", dict, field(default_factory=dict))]  # published max errors (%): {coordinate: [nonlinear, P]}
    return make_dataclass("ScenarioFields", own + declared + rest, frozen=True, kw_only=True,
                          namespace={"__doc__": _FIELDS_DOC, "__module__": __name__})


_FIELDS_DOC = """The fields of a scenario (:class:`hydrogen.simulation.scenarios.Scenario`), SI units, keywords
only: ``name``, ``reference``, every setting of :data:`PARTS` (the description table in the
documentation lists them), ``actuators`` (actuator name -> its own settings), ``gains`` (controller
name -> gain overrides), ``label`` (the caption in figures and tables) and ``paper`` (the published max
errors, %: {coordinate: [nonlinear, P]})."""

ScenarioFields = _assemble()


def settings() -> tuple:
    """The :class:`ScenarioFields` a description table may set (dataclass fields), part by part."""
    return tuple(f for f in fields(ScenarioFields) if "unit" in f.metadata)


def part_of(name: str) -> str:
    """The name of the part of the loop that declares scenario setting ``name`` (KeyError: none)."""
    return next(part.name for part in PARTS if name in part.settings)


def _field_names() -> tuple:
    return tuple(f.name for f in settings())


_FIELDS = _field_names()
#: Keys of a ``[scenarios.<name>]`` table besides the fields: the rig it starts from, its gains per
#: controller, its reference, caption, published errors and whether the gain searches judge it.
_TABLE_KEYS = ("rig", "gains", "reference", "label", "paper", "tuned")
#: Keys of a ``[rig]`` table besides the fields: its per-actuator settings.
_RIG_KEYS = ("actuators",)


def table_keys(rig: bool = False) -> frozenset:
    """The keys a description's ``[scenarios.<name>]`` table may hold, or its ``[rig]`` table (``rig``:
    fields only)."""
    return frozenset(_FIELDS + _RIG_KEYS if rig else _FIELDS + _RIG_KEYS + _TABLE_KEYS)


#: Joins a scenario's name to a variant's (``<scenario>.<variant>``): neither name may hold it.
VARIANT_SEPARATOR = "."
