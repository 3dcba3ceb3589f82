"""What a scenario table of a description may hold, declared once: the fields of a scenario (each
with its default, unit, meaning and check), the keys of ``[scenarios.<name>]``, ``[rig]`` and
``[variants.<name>]`` tables, the renamed fields and the separator of ``<scenario>.<variant>``.

Plain data: the description's loader (:mod:`hydrogen.model`, :mod:`hydrogen.schema`) checks a
table's keys against it without the simulation, and :class:`hydrogen.simulation.scenarios.Scenario`
is these fields with a run's behaviour (checks, overrides, the delay's split).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

__all__ = ["ScenarioFields", "setting", "settings", "table_keys", "RENAMED", "VARIANT_SEPARATOR"]

#: Scenario fields that were renamed: the old name and what to write instead (named in the error).
RENAMED = {"delay_periods": "delay (the computation delay in s; one period is 1/control_rate)"}


def setting(default, unit: str, meaning: str, check: str | None = None, default_text: str | None = None):
    """A scenario field that a description's ``[scenarios.<name>]`` or ``[rig]`` table may set, declared
    once: its default (None: required), unit and meaning (the description table's row, rendered by
    :func:`hydrogen.schema.description_table`) and its check: ``"number"`` a finite number, ``">=0"``
    also not negative (None: checked by
    :meth:`hydrogen.simulation.scenarios.Scenario.validated` itself)."""
    meta = {"unit": unit, "meaning": meaning, "check": check, "default_text": default_text}
    return field(metadata=meta) if default is None else field(default=default, metadata=meta)


def settings() -> tuple:
    """The :class:`ScenarioFields` a description table may set, in declaration order (dataclass fields)."""
    return tuple(f for f in fields(ScenarioFields) if "unit" in f.metadata)


@dataclass(frozen=True)
class ScenarioFields:
    """The fields of a scenario (:class:`hydrogen.simulation.scenarios.Scenario`). Units SI.

    Each field a description may set is declared below with its default, unit, meaning and check
    (:func:`setting`; the description table in the documentation lists them)."""

    name: str
    reference: object
    duration: float = setting(None, "s", "length of the run", "number")
    control_rate: float = setting(None, "Hz", "control rate, zero-order hold", "number")
    substeps: int = setting(None, "", "RK4 plant steps per control period")
    t_adapt: float = setting(None, "s", "adaptation switched on from this time", "number")
    friction: tuple = setting((0.0, 0.0, 1e-3), "N, N s/m, m/s", "per cylinder: Coulomb, viscous, tanh smoothing speed")
    valve_lag: float = setting(0.0, "s", "first-order valve lag (0: none); exclusive with valve_bandwidth_hz", ">=0")
    valve_bandwidth_hz: float = setting(0.0, "Hz", "second-order servo-valve natural frequency (the spool lags 90° "
                                        "there); 0: none", ">=0")
    valve_damping: float = setting(0.7, "", "second-order valve damping ratio", "number")
    delay: float = setting(0.0, "s", "computation delay: the command computed at t_k is applied from t_k + this (0 to "
                           "8 control periods; a fraction of a period switches the command inside the plant's "
                           "sub-steps)", "number")
    predictor: bool = setting(False, "", "delay compensation: the command is computed at the state predicted for "
                              "t_k + delay by the controller's own model (its estimates where it adapts them, "
                              "ideal valve, no friction) over the commands still in flight, and at the reference "
                              "of that time")
    predictor_substeps: int = setting(4, "", "the predictor's RK4 steps per control period (a fraction of a period "
                                      "takes its share, at least one)")
    quantization_l: float = setting(0.0, "m", "cylinder-length encoder resolution (0: none)", ">=0")
    noise_l: float = setting(0.0, "m", "std of white cylinder-length noise", ">=0")
    noise_q: float = setting(0.0, "rad or m", "std of white joint-encoder noise (robots with joint encoders)", ">=0")
    noise_p: float = setting(0.0, "Pa", "std of white pressure noise", ">=0")
    noise_ps: float = setting(0.0, "Pa", "std of white noise on the measured supply pressure (a [supply] that is "
                              "not constant)", ">=0")
    supply_feedback: bool = setting(True, "", "the controllers read the measured supply pressure in their ps "
                                    "input; false: the description's supply_pressure, a controller assuming a "
                                    "constant supply (a [supply] that is not constant)")
    kalman: bool = setting(False, "", "cylinder rates from fixed-gain Kalman filters (else exact)")
    kalman_accel: float = setting(50.0, "m²/s³", "the filter's white-acceleration density", ">=0")
    theta0_factor: tuple = setting((), "", "initial θ̂ = θ × factor, one per parameter",
                                   default_text="1 for every parameter")
    gamma0_factor: tuple = setting((1.0, 1.0), "", "initial [γ̂1, γ̂2] = γ × factor")
    metric_start: float = setting(0.0, "s", "metrics over t ≥ this (clamped to the run)", "number")
    q0_offset: tuple = setting((), "m, rad", "start pose offset from q_d(0), one per coordinate",
                               default_text="0 for every coordinate")
    seed: int = setting(0, "", "noise seed")
    estimator_update: str = setting("semi-implicit", "", 'controller state update: "semi-implicit" or "euler"')
    pressure_bounds: str = setting("stage", "", 'how the plant holds each pressure within its bounds (a chamber '
                                   'that would cavitate stays at 0): "stage" clips at every RK4 stage, where a '
                                   'pressure at a bound does not rate past it (RK4 keeps its order); "step" only '
                                   'after each step (first order where a pressure rests on a bound)')
    #: actuator name -> {setting of PER_ACTUATOR: value in that actuator's own unit}
    actuators: dict = field(default_factory=dict)
    gains: dict = field(default_factory=dict)  # controller name -> gain overrides for this scenario
    label: str = ""        # caption in figures and tables (e.g. the paper's figure it reproduces)
    paper: dict = field(default_factory=dict)  # published max errors (%): {coordinate: [nonlinear, P]}


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
