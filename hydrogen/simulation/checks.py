"""Every setting of a run checked before anything runs, each failure a ScenarioError naming the field.

Called by :class:`~hydrogen.simulation.scenarios.Scenario` (types and values that need no
model) and by the simulator's preparation (sizes against the model, initial estimates against
the projection bounds, the start pose against each actuator's travel (a cylinder's stroke, a
vane's angle range: its kind's TRAVEL), the memory one run may take).
Robot sizes always come from the model (``len(model.neutral_pose)``, ``len(model.theta)``, the
number of legs), never from literals.
"""
from __future__ import annotations

import numbers
import os
from collections.abc import Mapping

import numpy as np

from ..errors import ScenarioError
from ..setting import is_number
from .seeds import MAX_SEED

__all__ = ["check_fields", "check_reference", "check_against_model", "check_gain_values",
           "gain_must_be_positive", "check_run_size", "run_doubles_per_period", "metric_window", "max_run_bytes",
           "checked_float", "MAX_RUN_BYTES"]

#: Most memory one run may allocate for its noise table, workspace check and logs, bytes
#: (``$HYDROGEN_MAX_RUN_BYTES`` overrides). paper-sim's 10 s take about 7 MB.
MAX_RUN_BYTES = 2 * 1024 ** 3


def _shown(v) -> str:
    if isinstance(v, numbers.Integral) and not isinstance(v, (bool, np.bool_)) and abs(int(v)) > 10 ** 120:
        return f"an integer of {int(v).bit_length()} bits"  # repr of a huge int is slow, or refused by Python
    text = repr(v)
    return text if len(text) <= 120 else text[:100] + f"... ({len(text)} characters)"


def _fail(name, field, what, value):
    raise ScenarioError(f"scenario '{name}': {field} {what}, got {_shown(value)}")


def checked_float(value, field: str, name: str = "(run)") -> float:
    """``value`` as a float if it is a real number (not a bool, not a string), else ScenarioError."""
    if not is_number(value):
        _fail(name, field, "must be a number", value)
    return float(value)


def _vector(name, field, value, what="must be a sequence of finite numbers") -> np.ndarray:
    if isinstance(value, (str, bytes)) or isinstance(value, Mapping):
        _fail(name, field, what, value)
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        _fail(name, field, what, value)
    if arr.ndim != 1 or arr.dtype.kind not in "iuf" or not np.all(np.isfinite(arr)):
        _fail(name, field, what, value)
    return arr.astype(float)


def _finite_ints_axis(name, field, axis, n):
    if isinstance(axis, (bool, np.bool_)) or not isinstance(axis, numbers.Integral) or not 0 <= int(axis) < n:
        _fail(name, field, f"must be a coordinate index 0..{n - 1}", axis)


def check_reference(ref, name: str, n: int | None = None) -> None:
    """A reference of one of :data:`hydrogen.references.KINDS` whose every field the C loop may use is
    valid: bias of ``n`` finite numbers, then its kind's own fields (axes in 0..n-1, integers; its
    numbers finite)."""
    from ..references import KINDS, kind, reference_kind

    if reference_kind(ref) is None:
        names = " or ".join(f"hydrogen.references.{kind(k).__name__.rsplit('.', 1)[1]}.Reference" for k in KINDS)
        _fail(name, "reference", f"must be a {names}", ref)
    bias = _vector(name, "reference.bias", ref.bias)
    n = len(bias) if n is None else n
    if len(bias) != n:
        _fail(name, "reference.bias", f"must hold {n} numbers (one per coordinate of the model)", ref.bias)

    def finite(field, v):
        if not is_number(v) or not np.isfinite(v):
            _fail(name, field, "must be a finite number", v)

    ref.check(lambda field, what, v: _fail(name, field, what, v),
              lambda field, v: _finite_ints_axis(name, field, v, n), finite)


def seed_ok(seed) -> bool:
    """Whether ``seed`` is a scenario's noise seed: None or an integer in 0 .. MAX_SEED (not a bool)."""
    return seed is None or (not isinstance(seed, (bool, np.bool_)) and isinstance(seed, numbers.Integral)
                            and 0 <= seed <= MAX_SEED)


def check_fields(sc) -> None:
    """Types and values of a Scenario's fields that need no model (called by ``Scenario.validated``)."""
    name = sc.name
    if not isinstance(name, str) or not name:
        raise ScenarioError(f"scenario name must be a non-empty string, got {_shown(name)}")
    from ..scenario_settings import settings
    from ..setting import failed_check, words
    for f in settings():  # each number's check as its field declares it
        v = getattr(sc, f.name)
        failed = failed_check(f, v)
        if failed:
            _fail(name, f.name, f"must be {words(f, 'number')}" if failed == "number"
                  else f"must be finite and {words(f, failed)}", v)
    if sc.metric_start < 0:
        _fail(name, "metric_start", "must be >= 0 s", sc.metric_start)
    for f in ("substeps", "predictor_substeps"):
        v = getattr(sc, f)
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral):
            _fail(name, f, "must be an integer >= 1", v)
    from ..estimators import switches
    for f in (*switches(), "predictor", "supply_feedback"):  # the estimators' own switches (kalman) too
        if not isinstance(getattr(sc, f), (bool, np.bool_)):
            _fail(name, f, "must be True or False", getattr(sc, f))
    if not seed_ok(sc.seed):
        _fail(name, "seed", f"must be an integer in 0 .. {MAX_SEED} (2**63 - 1)", sc.seed)
    _vector(name, "friction", sc.friction, "must be (Coulomb N, viscous N s/m, smoothing speed m/s)")
    _vector(name, "q0_offset", sc.q0_offset)
    for f in ("theta0_factor", "gamma0_factor"):
        v = _vector(name, f, getattr(sc, f), "must be a sequence of finite numbers > 0")
        if not np.all(v > 0):
            _fail(name, f, "must be a sequence of finite numbers > 0 (factors on the true parameters)",
                  getattr(sc, f))
    if not isinstance(sc.gains, Mapping) or not all(isinstance(g, Mapping) for g in sc.gains.values()):
        _fail(name, "gains", "must be a dict {controller: {gain: value}}", sc.gains)
    check_reference(sc.reference, name)


def _layout(controller, model) -> list:
    from ..controllers import CONTROLLERS, controller as controller_module

    return controller_module(controller).state_layout(model) if controller in CONTROLLERS else []


def adapts(controller, model) -> bool:
    """Whether ``controller`` estimates θ (and γ) on ``model``: its state holds θ̂."""
    return any(block == "theta_hat" for block, _ in _layout(controller, model))


def check_against_model(sc, model, controller, dyn=None) -> None:
    """Sizes against the model, initial estimates inside the projection bounds (controllers that
    adapt), and the start pose inside each actuator's travel range (with ``dyn``): a cylinder's stroke
    in m, a vane's angle range in rad (its kind's TRAVEL)."""
    name = sc.name
    n = len(model.neutral_pose)
    check_reference(sc.reference, name, n)
    if len(sc.q0_offset) != n:
        _fail(name, "q0_offset", f"must hold {n} numbers (one per coordinate)", sc.q0_offset)
    if sc.noise_ps and model.supply.constant:  # it would measure nothing: refused, not ignored
        _fail(name, "noise_ps", f"adds noise to a measured supply pressure, but {model.source} has a constant "
              "supply (no [supply] state): leave noise_ps 0, or give the robot a [supply] pump", sc.noise_ps)
    if not sc.supply_feedback and model.supply.constant:  # nothing to hold constant: refused, not ignored
        _fail(name, "supply_feedback", f"feeds the controllers the nominal supply pressure in place of the measured "
              f"one, but {model.source} has a constant supply (no [supply] state): leave supply_feedback true, or "
              "give the robot a [supply] pump", sc.supply_feedback)
    for f, size in (("theta0_factor", model.n_theta), ("gamma0_factor", len(model.gamma))):
        if len(getattr(sc, f)) != size:
            _fail(name, f, f"must hold {size} factors (one per parameter)", getattr(sc, f))
    if adapts(controller, model):
        theta0 = model.theta * np.asarray(sc.theta0_factor, float)
        gamma0 = model.gamma * np.asarray(sc.gamma0_factor, float)[:, None]
        lo, hi = np.asarray(model.theta_min, float), np.asarray(model.theta_max, float)
        if np.any(theta0 < lo) or np.any(theta0 > hi):
            _fail(name, "theta0_factor", f"puts the initial estimates {theta0.tolist()} outside the model's "
                  f"projection bounds [{lo.tolist()}, {hi.tolist()}]", sc.theta0_factor)
        bounds = ((model.gamma1_min, model.gamma1_max), (model.gamma2_min, model.gamma2_max))
        for i, (g, (a, b)) in enumerate(zip(gamma0, bounds)):
            if np.any(g < a) or np.any(g > b):
                _fail(name, "gamma0_factor", f"puts gamma{i + 1}'s initial estimates {g.tolist()} outside the "
                      f"model's projection bounds [{a:.6g}, {b:.6g}]", sc.gamma0_factor)
    if dyn is not None:
        q0 = np.asarray(sc.reference(0.0)[0], float) + np.asarray(sc.q0_offset, float)
        legs = np.asarray(dyn.leg_lengths(q0))
        bad = ~((legs >= model.leg_min) & (legs <= model.leg_max))
        if bad.any():
            i = int(np.nonzero(bad)[0][0])
            c = model.cylinders[i]
            t = c.travel  # the actuator's own travel: a length in m, an angle in rad
            _fail(name, "q0_offset", f"puts the start pose outside actuator '{c.name}''s {t.range_word} "
                  f"({t.value(legs[i])}, {t.span(model.leg_min[i], model.leg_max[i])})", sc.q0_offset)


#: Gains that must be > 0 (divisors or limits); every other gain must be >= 0.
_POSITIVE_GAINS = ("u_max", "sat_width", "lambda_f_gamma", "P0_gamma", "ls_nu_gamma",
                   "lambda_f_theta", "P0_theta", "ls_nu_theta", "friction_speed")


def gain_must_be_positive(name: str) -> bool:
    """True if gain ``name`` must be > 0 (a divisor or a limit); every other gain must be >= 0."""
    return name in _POSITIVE_GAINS


def check_gain_values(kind: str, gains: dict, origin: dict | None = None) -> None:
    """No negative gain (a negative gain turns feedback into positive feedback), and u_max, sat_width > 0.
    ``origin``: where gains came from (the description's file and table, or the caller's ``gains``),
    named in the message."""
    origin = origin or {}
    for k, v in gains.items():
        a = np.asarray(v, float)
        where = f"{origin[k]}: " if k in origin else ""
        if k in _POSITIVE_GAINS and not np.all(a > 0):
            raise ScenarioError(f"{where}controller '{kind}': gain '{k}' must be > 0, got {_shown(v)}")
        if not np.all(a >= 0):
            raise ScenarioError(f"{where}controller '{kind}': gain '{k}' must be >= 0, got {_shown(v)}")


def max_run_bytes() -> int:
    """``$HYDROGEN_MAX_RUN_BYTES`` if set to a positive number, else :data:`MAX_RUN_BYTES`."""
    try:
        v = float(os.environ.get("HYDROGEN_MAX_RUN_BYTES", ""))
    except ValueError:
        return MAX_RUN_BYTES
    return int(v) if v > 0 and np.isfinite(v) else MAX_RUN_BYTES


def run_doubles_per_period(model, controller, keep_logs: bool) -> int:
    """Doubles one control period costs: the noise table and the workspace check, plus the logs."""
    from ..layout import log_rows, model_summary, plant_sensors, robot_sizes
    from ..sensors import noise_width
    summary = model_summary(model)
    noise = noise_width(robot_sizes(summary), model.joint_encoders, plant_sensors(summary))
    workspace = model.n + model.n_cylinders
    if not keep_logs:
        return noise + workspace
    n_xc = sum(size for _, size in _layout(controller, model))
    # the run's logs as both engines allocate them (hydrogen.loop_logs; the controller state's at least 1)
    return noise + workspace + sum(max(n_xc, 1) if r["width"] is None else r["width"] for r in log_rows(summary))


def check_run_size(sc, model, controller, keep_logs: bool = True) -> int:
    """The number of control periods of ``sc``, or a ScenarioError when the run would need more memory
    than :func:`max_run_bytes`, stating the limit and how to run longer."""
    periods = float(sc.duration) * float(sc.control_rate)
    limit = max_run_bytes()
    per = 8 * run_doubles_per_period(model, controller, keep_logs)
    lean = 8 * run_doubles_per_period(model, controller, False)
    if periods + 1 > limit / per:
        need = (periods + 1) * per
        longer = (f"Run longer with hydrogen.stepper(...), which keeps no logs ({lean} B per period, up to "
                  f"{limit // lean:,} periods), reading what you need between steps; "
                  if keep_logs else "")
        raise ScenarioError(
            f"scenario '{sc.name}': duration {sc.duration:g} s at {sc.control_rate:g} Hz is {periods + 1:.4g} "
            f"control periods, which need {need / 1e9:.3g} GB ({per} B per period); one run may use at most "
            f"{limit / 1e9:.3g} GB (HYDROGEN_MAX_RUN_BYTES), that is {limit // per:,} periods. {longer}"
            "split the run into shorter runs (chunks); or raise HYDROGEN_MAX_RUN_BYTES if the memory is there.")
    return int(round(periods)) + 1


#: The fewest samples a metric window holds; a shorter one (it starts at or after the run's last period)
#: is clamped to the whole run (a max or RMS of one sample is no statistic). The exported program's C
#: applies the same rule (templates/export_main.c.j2, from this number).
MIN_WINDOW_SAMPLES = 2


def metric_window(t, metric_start: float):
    """(selection, start, note) for metrics over t >= metric_start. A window that holds fewer than two
    samples (it starts at or after the last simulated period: a max or RMS of one sample is no
    statistic) is clamped to the whole run, and ``note`` says so (else None)."""
    t = np.asarray(t)
    sel = t >= metric_start - 1e-12
    kept = np.count_nonzero(sel)
    if kept >= MIN_WINDOW_SAMPLES or kept == len(t):  # a window of samples, or the whole run already
        return sel, float(metric_start), None
    end = float(t[-1])
    where = "at" if sel.any() else "after"
    note = (f"metric window t >= {metric_start:g} s starts {where} the last simulated period ({end:g} s); "
            f"metrics are over the whole run, t >= {float(t[0]):g} s")
    return np.ones_like(sel), float(t[0]), note
