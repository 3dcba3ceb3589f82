"""A rig log's units and ranges against the model, before identification trusts it.

Identification fits whatever numbers it is given: pressures in bar, a time column in ms or
lengths in mm give confident, wrong estimates. :func:`check_log` refuses such a log with one
message naming the column and what looks wrong, from the model's own values only:

* **sample rate** (column ``t``, s): within a factor ``RATE_FACTOR`` of the control rates of the
  model's scenarios (``control_rate``; no check for a model without scenarios);
* **actuator travel** (``l0..``, each in its actuator's unit, its kind's ``TRAVEL``: a cylinder's
  length in m, a rotary vane's angle in rad): inside its range (stroke, angle range), widened by
  ``STROKE_TOL`` of the range and 6 × the sensor noise estimated on the log; and moving (excitation)
  by more than ``NOISE_RANGES`` × that noise;
* **chamber pressures** (``pc0..``, Pa): not all 0, not all below ``TINY_PRESSURE`` × P_s (a unit
  other than Pa), and within [0, P_s] widened by ``PRESSURE_TOL`` × P_s and 6 × the noise.

A unit is guessed when the numbers rescaled by a common factor fit (ms and µs for time, the
travel's ``misread`` units: mm for a length, degrees for an angle; kPa, bar, psi and MPa for
pressures) and named in the message.
"""
from __future__ import annotations

import numpy as np

from .errors import IdentificationError, ScenarioError

__all__ = ["check_log", "noise_std", "control_rates", "fmt_number", "RATE_FACTOR", "STROKE_TOL", "NOISE_RANGES", "PRESSURE_TOL",
           "TINY_PRESSURE"]

#: The log's sample rate may be this factor below the slowest or above the fastest control rate.
RATE_FACTOR = 10.0
#: Measured lengths may leave the stroke by this fraction of its length (sensor offsets), plus noise.
STROKE_TOL = 0.01
#: Lengths whose range is below this many noise standard deviations do not move.
NOISE_RANGES = 20.0
#: Measured pressures may leave [0, P_s] by this fraction of P_s (sensor offsets), plus noise.
PRESSURE_TOL = 0.02
#: A pressure column whose largest magnitude is below this fraction of P_s is not in Pa.
TINY_PRESSURE = 0.01

_TIME_UNITS = (("ms", 1e-3), ("µs", 1e-6))
_PRESSURE_UNITS = (("kPa", 1e3), ("psi", 6894.757), ("bar", 1e5), ("MPa", 1e6))


def fmt_number(x) -> str:
    """A plain number for a message (never ``np.float64(...)``)."""
    return f"{float(x):.6g}"


_num = fmt_number


def control_rates(model) -> list:
    """The distinct control rates (Hz) of the model's scenarios, ascending (empty without scenarios)."""
    from .simulation.scenarios import scenario, scenario_names

    rates = set()
    for name in scenario_names(model):
        try:
            rates.add(float(scenario(name, model).control_rate))
        except ScenarioError:  # a broken scenario is reported when it is run, not here
            continue
    return sorted(rates)


def noise_std(x) -> np.ndarray:
    """Standard deviation of white noise on each column of ``x``, from its fourth differences: Δ⁴ of
    white noise has variance 70 σ², and a smooth trajectory's Δ⁴ is negligible at a rig's sample
    rates (a 3 Hz, 3 cm motion sampled at 1 kHz: 4·10⁻⁹ m, against 4·10⁻⁵ m for 5 µm of noise)."""
    d4 = np.diff(np.asarray(x, float), n=4, axis=0)
    return np.sqrt(np.mean(d4 ** 2, axis=0) / 70.0)


def _noise(x) -> np.ndarray:
    return noise_std(x) if len(x) > 4 else np.zeros(np.shape(x)[1])


def check_sample_rate(source, fs: float, h: float, model) -> None:
    """Refuse a sample rate ``fs`` (Hz; sample interval ``h`` in the log's time unit) far from the
    model's control rates: the time column is then not in seconds."""
    rates = control_rates(model)
    if not rates:
        return
    lo, hi = rates[0] / RATE_FACTOR, rates[-1] * RATE_FACTOR
    if lo <= fs <= hi:
        return
    rate_text = (f"the control rate is {_num(rates[0])} Hz" if len(rates) == 1 else
                 f"the control rates are {', '.join(_num(r) for r in rates)} Hz")
    guess = next((u for u, f in _TIME_UNITS if lo <= fs / f <= hi), None)
    what = f"looks like {guess}" if guess else "is not in seconds"
    raise IdentificationError(
        f"{source}: time column t {what}: sample interval {_num(h)} ({_num(fs)} Hz if in s), but {rate_text} "
        f"(the model's scenarios' control_rate; the log's rate must be within {RATE_FACTOR:g}x of it): write t "
        f"in seconds")


def check_lengths(source, t, L, model) -> None:
    """Refuse travel columns ``L`` (each in its actuator's unit: m, rad) outside their actuators'
    ranges, or none of which moves (no excitation). An actuator of unlimited travel (its range
    (−∞, ∞), a motor) is never outside, and moves when its column's span exceeds its noise."""
    lo, hi = model.leg_min, model.leg_max
    sigma = _noise(L)
    width = np.where(np.isfinite(hi - lo), hi - lo, 0.0)  # 0: unlimited, no range to scale by
    tol = STROKE_TOL * width + 6.0 * sigma
    out = (L < lo - tol) | (L > hi + tol)
    if out.any():
        k, i = (int(v[0]) for v in np.nonzero(out))
        c, col = model.cylinders[i], L[:, i]
        tr = c.travel
        fits = [u for u, f in tr.misread if np.all((col * f >= lo[i] - tol[i]) & (col * f <= hi[i] + tol[i]))]
        hint = f"; its {tr.quantity}s look like {fits[0]}: write them in {tr.unit}" if fits else ""
        raise IdentificationError(
            f"{source}: column l{i} leaves actuator '{c.name}''s {tr.range_word}: at t = {_num(t[k])} s it is "
            f"{tr.quantity} {_num(L[k, i])} {tr.unit}, {tr.span(lo[i], hi[i], '.6g')} ({_outside(out[:, i])} "
            f"outside){hint}")
    span = np.ptp(L, axis=0)
    floor = np.maximum(NOISE_RANGES * sigma, 1e-6 * width)
    if np.all(span <= floor):
        # the most, for its range (columns differ in unit), else for its noise floor
        i = int(np.argmax(span / np.where(width > 0, width, np.maximum(floor, 1e-300))))
        c = model.cylinders[i]
        unit = c.travel.unit
        raise IdentificationError(
            f"{source}: no excitation: no actuator moves (the most, for its range: '{c.name}', column l{i}, range "
            f"{_num(span[i])} {unit}; sensor noise {_num(sigma[i])} {unit}): identification needs a log of the "
            f"robot moving")


def _outside(out) -> str:
    """"k of N samples" of one column's mask of values out of range."""
    return f"{int(np.count_nonzero(out))} of {len(out)} samples"


def check_pressures(source, t, PC, model) -> None:
    """Refuse chamber pressures that are all 0, not in Pa, or outside their bounds ([0, P_s] for a
    three-way cylinder's p_c, up to the supply's ceiling where the supply is a state: the bounds the
    plant holds each chamber state to); one column per state of the pressure vector."""
    from .plant import plant_layout, slot
    from .pressures import bounds
    p_lo, ps = bounds(model)
    top = np.array(slot(plant_layout(model), "pc").upper, float)  # the plant's own clip (a pump's relief)
    cols = [f"pc{i}" for i in range(PC.shape[1])]
    peak = np.max(np.abs(PC), axis=0)
    zero = [c for c, v in zip(cols, peak) if v == 0.0]
    if len(zero) == len(cols):
        raise IdentificationError(f"{source}: pressures are all 0 (columns {cols[0]}..{cols[-1]}): the log needs "
                                  f"the measured control-chamber pressures, Pa")
    if zero:
        raise IdentificationError(f"{source}: pressure column(s) {', '.join(zero)} are all 0 (a sensor not "
                                  f"recorded?): the log needs every measured control-chamber pressure, Pa")
    tiny = peak < TINY_PRESSURE * ps
    if tiny.any():
        i = int(np.argmax(tiny))
        fits = [(u, f) for u, f in _PRESSURE_UNITS if np.all(peak[tiny] * f <= ps[tiny] * (1 + PRESSURE_TOL))]
        # the largest factor that keeps every pressure within P_s: a log's peak is a good share of P_s
        guess = f"look like {fits[-1][0]}" if fits else "are not in Pa"
        which = "pressures" if tiny.all() else f"pressure column(s) {', '.join(c for c, s in zip(cols, tiny) if s)}"
        raise IdentificationError(
            f"{source}: {which} {guess}: the largest magnitude in {cols[i]} is {_num(peak[i])}, "
            f"{_num(peak[i] / ps[i])} of the supply pressure P_s = {_num(ps[i])} Pa: write them in Pa")
    tol = PRESSURE_TOL * ps + 6.0 * _noise(PC)
    out = (PC < p_lo - tol) | (PC > top + tol)
    if out.any():
        k, i = (int(v[0]) for v in np.nonzero(out))
        side = f"below {_num(p_lo[i])}" if PC[k, i] < p_lo[i] else (
            "above the supply pressure" if top[i] == ps[i] else "above the supply's ceiling")
        raise IdentificationError(
            f"{source}: pressure column {cols[i]} at t = {_num(t[k])} s is {_num(PC[k, i])} Pa, {side} (the model's "
            f"range [{_num(p_lo[i]) if p_lo[i] else 0}, {'P_s' if top[i] == ps[i] else 'the supply ceiling'}] = "
            f"[{_num(p_lo[i]) if p_lo[i] else 0}, {_num(top[i])}] Pa; "
            f"{_outside(out[:, i])} outside): pressures must be absolute chamber pressures in Pa")


def check_log(source, t, fs: float, h: float, L, PC, model) -> None:
    """Every check of the module doc, in order: sample rate, lengths, excitation, pressures."""
    check_sample_rate(source, fs, h, model)
    check_lengths(source, t, L, model)
    check_pressures(source, t, PC, model)
