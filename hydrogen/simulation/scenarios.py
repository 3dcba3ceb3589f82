"""Scenarios: a reference, a rate, a plant and sensors, initial estimates. Each robot's scenarios live
in its description (``[scenarios.<name>]``, over the shared ``[rig]`` table); for the Stewart platform
they are section V's simulation and section VI's experiments, in simulation."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, dataclass, replace

import numpy as np

from .. import estimators, references
from ..errors import ScenarioError
from ..layout import MAX_DELAY, delay_split
from ..plant import (BLOCKS as plant_blocks, actuator_settings as plant_actuator_settings, block as plant_block,
                     friction, integrator)
from ..sensors import NOISE  # the loop's own sensors' noise settings
from ..scenario_settings import (_FIELDS, PER_ACTUATOR, RENAMED, VARIANT_SEPARATOR, ScenarioFields,  # noqa: F401
                                 actuator_keys, setting, settings, table_keys)
from .checks import check_fields

__all__ = ["Scenario", "setting", "settings", "PER_ACTUATOR", "actuator_settings", "per_actuator_unit", "scenario", "scenario_names", "variant_names", "variant_name", "split_variant", "current_name", "table_keys", "default_scenario_name", "RENAMED"]


@dataclass(frozen=True)
class Scenario(ScenarioFields):
    """Everything a run needs besides the controller. Units SI.

    Each field a description may set is declared with its default, unit, meaning and check by the part
    of the loop that reads it (:data:`hydrogen.scenario_settings.PARTS`, gathered into
    :class:`~hydrogen.scenario_settings.ScenarioFields`; the description table in the documentation
    lists them). Two behaviours need more words than a table cell: the command computed from the measurement at t_k is applied from
    t_k + ``delay`` (a fraction of a period switches the valves' command inside the plant's
    sub-steps); the actuators' rates come from the ideal rate sensor unless an estimator is selected
    (``estimator = "<name>"``, or an estimator's own switch: with ``kalman`` fixed-gain Kalman filters on
    the measured leg lengths, constant-velocity model, white acceleration of density ``kalman_accel``,
    measurement variance noise_l² + quantization_l²/12, steady-state gain from the discrete algebraic
    Riccati equation; :mod:`hydrogen.estimators`). ``gains`` holds this scenario's tuning per controller, under any gains the caller
    passes. The robot starts at rest at q_d(0) + q0_offset, its pressures holding it against gravity
    (and against what a rig part pushes with at rest).
    """

    def noise_free(self) -> dict:
        """The overrides that switch every sensor noise off: the loop's own sensors' (the per-actuator
        ones included) and every rig part's output's sensor (:attr:`hydrogen.plant.PlantState.noise`). A
        sensor's resolution and bias stay: they are the sensor's, not noise (an exported program, which
        draws no noise, applies them too)."""
        quiet = {a: {**v, "noise_l": 0.0} for a, v in self.actuators.items() if isinstance(v, Mapping)}
        parts = {st.noise: 0.0 for b in plant_blocks for st in plant_block(b).STATES if st.noise}
        return {**{ch.setting: 0.0 for ch in NOISE}, **parts, "actuators": quiet}

    def delay_split(self) -> tuple:
        """The delay as (whole control periods, fraction of a period): :func:`hydrogen.layout.delay_split`."""
        return delay_split(self.delay, 1.0 / self.control_rate)

    def predicts(self) -> bool:
        """Whether the loop runs the delay predictor: ``predictor`` on and a delay to predict over."""
        return bool(self.predictor) and sum(self.delay_split()) > 0

    def predictor_steps(self, periods: float) -> int:
        """RK4 steps the delay predictor takes over ``periods`` control periods of one held command:
        no step longer than a period / ``predictor_substeps``, at least one (the C loop's ``pred_hold``)."""
        return integrator.predictor_steps(periods, self.predictor_substeps)

    def with_overrides(self, **kw):
        """A copy with the given fields replaced and validated; an unknown field raises ScenarioError.
        ``actuators`` replaces the scenario's whole table (``{}`` clears it): to change one actuator's
        setting, give the table with it changed (``{**sc.actuators, name: {**sc.actuators[name], ...}}``)."""
        unknown = set(kw) - set(self.__dataclass_fields__)
        for old in sorted(unknown & set(RENAMED)):
            raise ScenarioError(f"scenario '{self.name}': {old} is now {RENAMED[old]}")
        if unknown:
            raise ScenarioError(f"scenario '{self.name}' has no field(s) {sorted(unknown)}; "
                                f"fields: {sorted(self.__dataclass_fields__)}")
        return replace(self, **kw).validated()

    def validated(self) -> "Scenario":
        """Self, or a :class:`ScenarioError` naming the field that is out of range."""
        def need(ok, field, what):
            if not ok:
                raise ScenarioError(f"scenario '{self.name}': {field} {what}, got {getattr(self, field)!r}")
        check_fields(self)  # types first (a string where a number belongs), then the ranges below
        finite = lambda v: bool(np.all(np.isfinite(np.asarray(v, float))))  # noqa: E731
        need(finite(self.duration) and self.duration > 0, "duration", "must be a finite number > 0 s")
        need(finite(self.control_rate) and self.control_rate > 0, "control_rate", "must be > 0 Hz")
        # a shorter run samples nothing after its start: no error to report, no metric but of one sample
        need(self.duration * self.control_rate >= 1.0 - 1e-9, "duration",
             f"must be at least one control period (1/control_rate = {1.0 / self.control_rate!r} s)")
        need(isinstance(self.substeps, int) and self.substeps >= 1, "substeps", "must be an integer >= 1")
        for f in self.reference.frequencies():  # a periodic reference the loop samples: below Nyquist
            if f >= 0.5 * self.control_rate:
                raise ScenarioError(f"scenario '{self.name}': reference frequency {f:g} Hz must be below half the "
                                    f"control rate ({0.5 * self.control_rate:g} Hz at control_rate "
                                    f"{self.control_rate:g} Hz): sampled there, the reference aliases")
        need(finite(self.t_adapt), "t_adapt", "must be finite (use a large value to never adapt)")
        need(friction.row_ok(self.friction), "friction", friction.ROW_RULE)
        need(finite(self.valve_damping) and self.valve_damping > 0, "valve_damping", "must be > 0")
        need(finite(self.delay) and self.delay >= 0 and sum(self.delay_split()) <= MAX_DELAY, "delay",
             f"must be 0..{MAX_DELAY} control periods, in s (1/control_rate = {1.0 / self.control_rate!r} s)")
        need(not (self.valve_lag > 0 and self.valve_bandwidth_hz > 0), "valve_lag",
             "must be 0 when valve_bandwidth_hz is set (one valve model: second order, or the first-order lag)")
        # RK4 on the spool's second-order dynamics: keep omega * sub-step well inside its stability region
        need(2 * np.pi * self.valve_bandwidth_hz / (self.control_rate * self.substeps) <= 1.0, "valve_bandwidth_hz",
             "must be <= control_rate * substeps / (2 pi) (raise substeps)")
        need(1 <= self.predictor_substeps <= 1000, "predictor_substeps", "must be an integer 1..1000")
        need(finite(self.q0_offset), "q0_offset", "must be finite numbers (one per coordinate)")
        need(self.estimator_update in ("semi-implicit", "euler"), "estimator_update",
             "must be 'semi-implicit' or 'euler'")
        need(self.pressure_bounds in ("step", "stage"), "pressure_bounds", "must be 'step' or 'stage'")
        estimators.selected(self)  # one estimator at most, a known one (a ScenarioError naming the setting)
        need(isinstance(self.actuators, Mapping) and all(isinstance(v, Mapping) for v in self.actuators.values()),
             "actuators", "must be a table {actuator name: {setting: value}}")
        blocks = plant_actuator_settings()  # the plant blocks' own, each with its check
        given = actuator_keys()
        for name, values in self.actuators.items():
            unknown = sorted(set(values) - set(given))
            if unknown:
                raise ScenarioError(f"scenario '{self.name}': actuators.{name}: unknown setting(s) {unknown}; "
                                    f"settings given per actuator: {', '.join(given)}")
            # each block checks its own (a friction table, a valve response); what it leaves to the scenario's
            # field of that name (a friction row) is checked with the sensors' below
            handled = {k for k, check in blocks.items() if k in values and not check(self, name, values[k])}
            values = {k: v for k, v in values.items() if k not in handled}
            try:  # each sensor's value as the scenario's own field of that name checks it
                replace(self, actuators={}, **{k: _tuple(v) for k, v in values.items()}).validated()
            except ScenarioError as exc:
                text = str(exc).removeprefix(f"scenario '{self.name}': ")
                raise ScenarioError(f"scenario '{self.name}': actuators.{name}.{text} (in the actuator's own "
                                    "unit)") from None
        return self







def _tuple(v):
    return tuple(v) if isinstance(v, list) else v


def per_actuator_unit(key: str, travel) -> str:
    """The unit of per-actuator setting ``key`` for an actuator of ``travel`` (its kind's TRAVEL)."""
    u, f = travel.unit, travel.force_unit
    return {"friction": f"{f}, {f} s/{u}, {u}/s", "quantization_l": u, "noise_l": u}[key]


def actuator_settings(sc: Scenario, model) -> dict:
    """Each setting of :data:`PER_ACTUATOR` per actuator of ``model``, in that actuator's own unit:
    ``{"friction": (m, k) array (:func:`hydrogen.plant.friction.actuator_row`), "quantization_l": (m,), "noise_l": (m,)}``.
    ScenarioError for an actuator the model lacks, or a joint actuator not given a sensor setting
    the scenario switches on (the scenario's is a cylinder's, in m)."""
    from ..actuators import actuator
    from ..actuators.declarations import LENGTH

    names = [c.name for c in model.cylinders]
    unknown = sorted(set(sc.actuators) - set(names))
    if unknown:
        raise ScenarioError(f"scenario '{sc.name}': actuators.{unknown[0]}: the model has no actuator of that name; "
                            f"actuators: {', '.join(names)}")
    out = {k: [] for k in PER_ACTUATOR}
    for c in model.cylinders:
        own, travel = sc.actuators.get(c.name, {}), actuator(c.kind).TRAVEL
        for key in PER_ACTUATOR:
            if key == "friction":  # the actuator's description's over the scenario's, key by key
                out[key].append(friction.actuator_row(sc, c, model.seal_friction))
                continue
            value = _tuple(own.get(key, getattr(sc, key)))
            if key not in own and travel != LENGTH and getattr(sc, key):
                raise ScenarioError(
                    f"scenario '{sc.name}': {key} = {getattr(sc, key)!r} is a cylinder's, in "
                    f"{per_actuator_unit(key, LENGTH)}; actuator '{c.name}' (kind {c.kind}) moves an "
                    f"{travel.quantity}: give its own as actuators.{c.name}.{key} in "
                    f"{per_actuator_unit(key, travel)}")
            out[key].append(value)
    return {k: np.asarray(v, float) for k, v in out.items()}


def _reference(model, where, spec, neutral):
    """A reference from its description: ``sines = [[coordinate, amplitude, Hz], ...]`` or
    ``step = { coordinate, height, time }``; coordinates by name or index, offsets from neutral."""
    def axis(c):
        if isinstance(c, str) and c in model.coordinate_names:
            return model.coordinate_names.index(c)
        if isinstance(c, int) and not isinstance(c, bool) and 0 <= c < model.n:
            return c
        raise ScenarioError(f"{where}: coordinate {c!r} is not one of {list(model.coordinate_names)}")

    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in references.KINDS:
        forms = " or ".join(f"reference.{k} = {references.kind(k).SYNTAX}" for k in references.KINDS)
        raise ScenarioError(f"{where}: expected {forms}, got {spec!r}")
    kind, value = next(iter(spec.items()))
    try:
        return references.kind(kind).Reference.parse(value, axis, neutral)
    except ScenarioError:  # a coordinate the robot lacks: its own message, naming the file once
        raise
    except (TypeError, ValueError, KeyError) as exc:
        raise ScenarioError(f"{where}: malformed reference.{kind} ({exc})") from None


def scenario_names(model) -> tuple:
    """Names of the scenarios the model's description defines."""
    return tuple(k for k in (model.scenarios or {}) if k != "rig")


def default_scenario_name(model) -> str:
    """The scenario a command runs when none is named: the first the model's description defines."""
    names = scenario_names(model)
    if not names:
        raise ScenarioError(f"model '{model.name}' defines no scenario ([scenarios.<name>] tables); "
                            "name one with --scenario or add one to its description")
    return names[0]


def variant_names(model) -> tuple:
    """Names of the variants the model's description defines (``[variants.<name>]``)."""
    return tuple(getattr(model, "variants", None) or {})


def variant_name(name, model) -> str | None:
    """The variant of the model's description that ``name`` names: itself, or the variant that lists
    it in its ``formerly`` names (its old name: a :class:`~hydrogen.errors.DescriptionNote` names the
    new one, shown once); None for no variant."""
    import warnings

    from ..errors import DescriptionNote

    variants = getattr(model, "variants", None) or {}
    if name in variants:
        return name
    new = next((v for v, table in variants.items() if name in (table.get("formerly") or ())), None)
    if new is not None:  # stacklevel 1: one warning location, so Python shows the note once per process
        warnings.warn(f"{model.source}: variant '{name}' is now '{new}' ([variants.{new}] formerly = "
                      f"[\"{name}\"]): it runs as '{new}'", DescriptionNote)
    return new


def split_variant(name: str, model) -> tuple:
    """``(scenario, variant or None)`` of a scenario name: ``<scenario>.<variant>`` names a variant of
    the model's description over one of its scenarios (by its name or a former one: the variant's
    current name is returned)."""
    base, dot, var = name.rpartition(VARIANT_SEPARATOR) if isinstance(name, str) else ("", "", "")
    if dot and base in scenario_names(model):
        var = variant_name(var, model)
        if var is not None:
            return base, var
    return name, None


def current_name(name, model):
    """``name`` with a former variant name replaced by the variant's current one (its note shown here,
    once, not again by each worker a sweep runs it in); anything else as given."""
    base, var = split_variant(name, model)
    return name if var is None else f"{base}{VARIANT_SEPARATOR}{var}"


def scenario(name: str, model) -> Scenario:
    """The named scenario of ``model``'s description (references are offsets from its neutral pose).

    A scenario table sets any :class:`Scenario` field; ``rig = true`` starts from the model's
    ``[rig]`` table (the experiment-like rig); ``gains.<controller>`` tunes a controller for it.
    ``<scenario>.<variant>`` is that scenario with the fields of the description's
    ``[variants.<variant>]`` table set over its own (the same rig at another timing, say) and the
    variant's gains over the scenario's; its label names the variant.
    """
    tables = model.scenarios or {}
    names = scenario_names(model)
    name = current_name(name, model)  # a former variant name runs as the current one
    base, var = split_variant(name, model)
    if not isinstance(name, str) or base not in names:
        shown = ", ".join(names)
        if variant_names(model):
            shown += f" (each also as <scenario>.<variant>, variants: {', '.join(variant_names(model))})"
        raise ScenarioError(f"unknown scenario {name!r} for model '{model.name}'; choose one of {shown}")
    where = f"{model.source}: [scenarios.{base}]"
    spec = dict(tables[base])
    fields, actuators = {}, {}

    def take(table):  # its fields over the ones taken, its per-actuator settings merged per actuator
        table = dict(table)
        for a, values in (table.pop("actuators", None) or {}).items():
            actuators[a] = {**actuators.get(a, {}), **values} if isinstance(values, dict) else values
        fields.update(table)

    if spec.pop("rig", False):
        take(tables.get("rig") or {})
        where += " over [rig]"
    gains = {c: dict(g) for c, g in spec.pop("gains", {}).items()}
    ref = spec.pop("reference", None)
    label = spec.pop("label", base)
    paper = spec.pop("paper", {})
    spec.pop("tuned", None)  # read by the searches (tuning.rig_scenarios), not a field of the run
    take(spec)
    if var is not None:
        vspec = dict(model.variants[var])
        for c, g in vspec.pop("gains", {}).items():
            gains[c] = {**gains.get(c, {}), **g}
        label = f"{label}, {vspec.pop('label', var)}"
        vspec.pop("formerly", None)
        take(vspec)
        where = f"{where} with [variants.{var}]"
    unknown = set(fields) - table_keys(rig=True)
    if unknown:
        raise ScenarioError(f"{where}: unknown field(s) {sorted(unknown)}; fields: {sorted(_FIELDS)}")
    if ref is None:
        raise ScenarioError(f"{where}: missing reference")
    for k in ("friction", "theta0_factor", "gamma0_factor", "q0_offset"):
        if k in fields and isinstance(fields[k], list):
            fields[k] = tuple(fields[k])
    n = model.n
    fields.setdefault("theta0_factor", (1.0,) * model.n_theta)
    fields.setdefault("q0_offset", (0.0,) * n)
    neutral = np.asarray(model.neutral_pose, float)
    # the settings without a default: named with their meaning and unit, not as a TypeError's argument
    missing = [f for f in settings() if f.name not in fields and f.default is MISSING and f.default_factory is MISSING]
    if missing:
        raise ScenarioError(f"{where}: missing field(s) " + "; ".join(
            f"{f.name} ({', '.join(filter(None, (f.metadata['meaning'], f.metadata['unit'])))})" for f in missing))
    try:
        sc = Scenario(name=name, reference=_reference(model, where, ref, neutral), gains=gains,
                      label=str(label), paper=dict(paper), actuators=actuators, **fields)
    except TypeError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    try:
        return sc.validated()
    except ScenarioError as exc:  # the tables the value came from, for a description's own scenario
        raise ScenarioError(f"{where}: {str(exc).removeprefix(f'scenario {name!r}: ')}") from None
