"""The fixed-gain Kalman filter on each actuator's measured travel l (m, or rad for a rotary
actuator): a constant-velocity model per actuator, the state [l, l̇], run once per control period h.

- **Design** (:func:`kalman_gain`): the steady-state gain [K_l, K_l̇] (dimensionless, 1/s) for white
  acceleration of spectral density ``accel`` (the scenario's ``kalman_accel``, m²/s³) and a length
  measurement of variance ``r`` (:func:`length_noise_variance`: the scenario's ``noise_l`` and its
  encoder's ``quantization_l``). One gain serves every actuator, in its own unit.
- **Update** (:func:`update`, numpy; :data:`C_UPDATE`, the loop driver's C): predict with
  [1 h; 0 1], then correct with the gain against the measured l. The two are the same operations in
  the same order, so the Python engine and the C loop agree to the bit.
- **Start** (:func:`start`, :data:`C_START`): at the first pose's lengths, at rest.

An estimator of :mod:`hydrogen.estimators` (its declarations: ``NAME``, ``STATE``, ``CONFIG``, ...),
selected by ``kalman = true`` or ``estimator = "kalman"``. Plain numpy at import; SciPy only where a gain is solved.
"""
from __future__ import annotations

import functools

import numpy as np

from ..setting import setting
from . import ConfigNumbers, LoopState

__all__ = ["NAME", "POSITION", "DOC", "SWITCH", "STATE", "CONFIG", "CONFIG_DOC", "design", "config", "rate",
           "design_key", "designs", "remember", "C_START", "C_COMMENT", "SCENARIO_SETTINGS", "length_noise_variance", "filter_gain", "filter_setting", "filter_gains", "remember_filter_gains",
           "kalman_gain", "start", "update", "C_UPDATE"]

#: Its name (the scenario's ``estimator = "kalman"``) and place among the estimators.
NAME = "kalman"
POSITION = 1
DOC = "fixed-gain Kalman filter on the actuators' travel"
LABEL = "the Kalman filter"  # as the loop header's comments name it
#: The scenario's own switch that selects it (``kalman = true``), besides ``estimator = "kalman"``.
SWITCH = "kalman"

#: Its part of the loop's state: [l (NL), l̇ (NL)], m and m/s (rad, rad/s for a rotary actuator).
STATE = LoopState("kf", (2, "NL"), "Kalman state: cylinder lengths, cylinder rates")
#: Its numbers in the loop's configuration: the gain [K_l, K_l̇] (dimensionless, 1/s).
CONFIG = (ConfigNumbers("kf_gain", 2),)
CONFIG_DOC = "fixed-gain Kalman filter on the actuators' travel (use_kalman != 0), gain [K_l, K_ldot]"

#: Whether a scenario filters the travel, and the filter's model (:mod:`hydrogen.scenario_settings`).
SCENARIO_SETTINGS = {
    "kalman": setting(False, "", 'cylinder rates from fixed-gain Kalman filters (as estimator = "kalman"; else '
                      "the ideal rate sensor unless the estimator setting selects another)"),
    "kalman_accel": setting(50.0, "m²/s³", "the filter's white-acceleration density", ">=0"),
}

#: The loop driver's statements of :func:`update` for actuator ``i`` (``st->kf``: [l (NL), l̇ (NL)];
#: ``c->kf_gain``, ``c->h``: the configuration's gain and period; ``s->l_meas``: the measured lengths),
#: which also set the cylinder rate the velocities are solved from (``s->ldot``).
C_COMMENT = "predict with [1 h; 0 1], correct with the fixed gain"
C_UPDATE = """\
            double lp = st->kf[i] + c->h * st->kf[NL + i], vp = st->kf[NL + i], r = s->l_meas[i] - lp;
            st->kf[i] = lp + c->kf_gain[0] * r;
            st->kf[NL + i] = vp + c->kf_gain[1] * r;
            s->ldot[i] = st->kf[NL + i];
"""


#: :func:`start` in C for actuator ``i`` at the lengths ``l0`` (a ``const double*`` of NL, m).
C_START = """\
            st->kf[i] = l0[i];
            st->kf[NL + i] = 0.0;
"""


def design(sc, h):
    """The run's gain [K_l, K_l̇] (dimensionless, 1/s) for scenario ``sc`` at period ``h`` (s):
    :func:`kalman_gain` at :func:`filter_setting`."""
    return kalman_gain(*filter_setting(sc, h))


def config(gain) -> dict:
    """The loop configuration's numbers of ``gain``: ``kf_gain``."""
    return {"kf_gain": np.asarray(gain, float)}


def rate(kf) -> np.ndarray:
    """The actuators' rates (m/s, rad/s) of the filter's state ``kf``: its second row."""
    return kf[1].copy()


def design_key(sc, h) -> tuple:
    """What a design depends on (:func:`filter_setting`), for a sweep's workers (:func:`designs`)."""
    return filter_setting(sc, h)


def designs(keys) -> dict:
    """The gains of ``keys`` (:func:`design_key`), solved here (:func:`filter_gains`)."""
    return filter_gains(keys)


def remember(gains: dict) -> None:
    """Take the gains :func:`designs` solved in another process (:func:`remember_filter_gains`)."""
    remember_filter_gains(gains)


def length_noise_variance(noise_l, quantization_l) -> float:
    """Variance of a measured cylinder length, m²: white noise plus the encoder's quantisation
    (uniform over one step Δ: Δ²/12); a floor of (1 nm)² keeps the filter defined without either."""
    return max(float(noise_l) ** 2 + float(quantization_l) ** 2 / 12.0, 1e-18)


def filter_gain(sc, h):
    """The loop's one Kalman gain [K, K̇] (dimensionless, 1/s: the same on a length as on an angle) for
    ``sc`` at period ``h``, designed for the scenario's (a cylinder's) noise_l, quantization_l and
    kalman_accel; None where the scenario does not select the filter (``kalman = true`` or
    ``estimator = "kalman"``)."""
    from . import selected

    return design(sc, h) if selected(sc) == NAME else None


def filter_setting(sc, h) -> tuple:
    """(h, r, accel) of :func:`kalman_gain` for ``sc``'s filter at period ``h`` (s)."""
    return float(h), length_noise_variance(sc.noise_l, sc.quantization_l), float(sc.kalman_accel)


def filter_gains(settings) -> dict:
    """{(h, r, accel): gain} of the filter ``settings`` (:func:`filter_setting`), solved (or remembered)
    here: a sweep's parent hands them to its workers (:func:`remember_filter_gains`), which then
    neither import SciPy nor solve the Riccati equation again."""
    return {s: _kalman_gain(*s) for s in set(settings)}


def remember_filter_gains(gains: dict) -> None:
    """Take the gains :func:`filter_gains` solved in another process as this process's own."""
    _KNOWN_GAINS.update(gains)


#: Kalman gains by (h, r, accel) that a sweep's parent solved (:func:`remember_filter_gains`).
_KNOWN_GAINS = {}


def kalman_gain(h, r, accel):
    """Steady-state gain [K_l, K_l̇] of the fixed-gain Kalman filter on one cylinder length.

    Process model: constant velocity driven by white acceleration of spectral density ``accel``
    (m²/s³), exactly discretised over the control period h: F = [1 h; 0 1],
    Q = accel [h³/3 h²/2; h²/2 h]. Measurement: the length, variance ``r`` (m²). The predicted
    covariance P solves the filter's DARE (scipy's solver, in its control form with Fᵀ, Hᵀ);
    K = P Hᵀ (H P Hᵀ + r)⁻¹, applied after each prediction.
    """
    return np.array(_kalman_gain(float(h), float(r), float(accel)))


@functools.lru_cache(maxsize=256)
def _kalman_gain(h: float, r: float, accel: float) -> tuple:
    # once per process and (period, noise, acceleration): a sweep's runs of one scenario share it
    known = _KNOWN_GAINS.get((h, r, accel))
    if known is not None:
        return known
    from scipy.linalg import solve_discrete_are
    F = np.array([[1.0, h], [0.0, 1.0]])
    Q = accel * np.array([[h ** 3 / 3, h ** 2 / 2], [h ** 2 / 2, h]])
    H = np.array([[1.0, 0.0]])
    P = solve_discrete_are(F.T, H.T, Q, np.array([[r]]))
    return tuple(P[:, 0] / (P[0, 0] + r))


def start(l0) -> np.ndarray:
    """The filter's state [l; l̇] (2 x m) at the lengths ``l0`` (m), at rest."""
    l0 = np.asarray(l0, float)
    return np.vstack([l0, np.zeros_like(l0)])


def update(kf, l_meas, gain, h: float) -> np.ndarray:
    """The filter's state after one period of ``h`` (s) that measured ``l_meas``: :data:`C_UPDATE`'s
    operations, in its order (a new array; its second row is the rate estimate)."""
    lp = kf[0] + h * kf[1]
    vp = kf[1]
    r = l_meas - lp
    return np.vstack([lp + gain[0] * r, vp + gain[1] * r])
