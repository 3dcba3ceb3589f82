"""The closed loop: plant (RK4 sub-steps), sensors, forward kinematics, controller at a fixed rate."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import KinematicsError, SimulationError
from .control import make_controller
from .scenarios import Scenario, scenario as named_scenario

__all__ = ["simulate", "SimulationResult", "COORDS", "equilibrium_pressures"]

COORDS = ("x", "y", "z", "psi", "theta", "phi")


@dataclass
class SimulationResult:
    """Time series (one row per control period) and metrics of one run. SI units, base frame."""

    scenario: str
    controller: str
    t: np.ndarray
    q: np.ndarray
    q_d: np.ndarray
    leg_lengths: np.ndarray
    leg_forces: np.ndarray
    pressures: np.ndarray
    u: np.ndarray
    theta_hat: np.ndarray
    gamma1_hat: np.ndarray
    gamma2_hat: np.ndarray
    theta_true: np.ndarray
    gamma_true: np.ndarray
    amplitude: np.ndarray
    metric_start: float
    wall_time_s: float = 0.0
    metrics: dict = field(default_factory=dict)

    @property
    def error(self) -> np.ndarray:
        """Tracking error q − q_d, (n, 6)."""
        return self.q - self.q_d

    def compute_metrics(self) -> dict:
        """Max error in % of each coordinate's reference amplitude (None where it has none), RMS error,
        final parameter estimates, over t ≥ metric_start."""
        sel = self.t >= self.metric_start - 1e-12
        e = self.error[sel] if sel.any() else self.error
        max_abs = np.abs(e).max(axis=0) if len(e) else np.full(6, np.nan)
        rms = np.sqrt((e ** 2).mean(axis=0)) if len(e) else np.full(6, np.nan)
        pct = {c: (float(100 * m / a) if a > 0 else None) for c, m, a in zip(COORDS, max_abs, self.amplitude)}
        self.metrics = {
            "scenario": self.scenario, "controller": self.controller,
            "max_error_pct": pct,
            "max_error": dict(zip(COORDS, map(float, max_abs))),
            "rms_error": dict(zip(COORDS, map(float, rms))),
            "theta_hat_final": self.theta_hat[-1].tolist(),
            "theta_true": self.theta_true.tolist(),
            "theta_error_pct_final": (100 * (self.theta_hat[-1] - self.theta_true) / self.theta_true).tolist(),
            "gamma_hat_final": [self.gamma1_hat[-1].tolist(), self.gamma2_hat[-1].tolist()],
            "gamma_true": self.gamma_true.tolist(),
            "sim_time_s": float(self.t[-1] - self.t[0]) if len(self.t) else 0.0,
            "wall_time_s": float(self.wall_time_s),
            "metric_start_s": self.metric_start,
        }
        return self.metrics

    def to_json(self) -> str:
        return json.dumps(self.metrics or self.compute_metrics(), indent=2, sort_keys=True)


def equilibrium_pressures(dyn, q, theta) -> np.ndarray:
    """Control pressures (Pa) whose leg forces hold the platform still at pose q: (JL)ᵀ f = G."""
    m = dyn.model
    f = np.linalg.solve(dyn.leg_jacobian(q).T, dyn.gravity(q, theta))
    return (f + m.supply_pressure * m.rod_area) / m.piston_area


class _KalmanRate:
    """Fixed-gain Kalman filters (one per leg) for [l, l̇] from noisy l, constant-velocity model."""

    def __init__(self, h, noise_l, accel, l0):
        F = np.array([[1.0, h], [0.0, 1.0]])
        Q = accel * np.array([[h ** 3 / 3, h ** 2 / 2], [h ** 2 / 2, h]])
        R = max(noise_l, 1e-9) ** 2
        P = np.eye(2) * 1e-6
        for _ in range(5000):  # steady-state Riccati iteration (2×2: cheap and exact enough)
            P = F @ P @ F.T + Q
            K = P[:, 0] / (P[0, 0] + R)
            P = P - np.outer(K, P[0, :])
        self.F, self.K = F, K
        self.x = np.vstack([l0, np.zeros(6)])  # (2, 6)

    def update(self, l_meas):
        x = self.F @ self.x
        x += np.outer(self.K, l_meas - x[0])
        self.x = x
        return x[1].copy()


def _rk4(rhs, x, h):
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * h * k1)
    k3 = rhs(x + 0.5 * h * k2)
    k4 = rhs(x + h * k3)
    return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


def simulate(dyn, scenario, controller: str, *, gains=None, duration=None, check_workspace=True,
             **overrides) -> SimulationResult:
    """Run ``controller`` on ``scenario`` (a name or a :class:`Scenario`) with compiled dynamics ``dyn``.

    ``overrides`` replace scenario fields (e.g. ``t_adapt=1.0``). A run whose
    state becomes non-finite raises :class:`~hydrogen.errors.SimulationError`
    naming the time and the state; ``err.result`` holds the partial result.
    """
    model = dyn.model
    sc = named_scenario(scenario, model) if isinstance(scenario, str) else scenario
    if duration is not None:
        overrides["duration"] = float(duration)
    sc = sc.with_overrides(**overrides) if overrides else sc
    rng = np.random.default_rng(sc.seed)
    h = 1.0 / sc.control_rate
    n = int(round(sc.duration * sc.control_rate)) + 1
    theta_true, gamma_true = model.theta, model.gamma
    theta0 = theta_true * np.asarray(sc.theta0_factor)
    gamma0 = gamma_true * np.asarray(sc.gamma0_factor)
    if controller == "backstepping":
        theta0, gamma0 = theta_true, gamma_true
    if check_workspace:
        _check_reference(dyn, sc, n, h)
    ctrl = make_controller(dyn, controller, gains, theta0, gamma0)

    q0 = sc.reference(0.0)[0] + np.asarray(sc.q0_offset, float)
    pc0 = equilibrium_pressures(dyn, q0, theta_true)
    x = np.concatenate([q0, np.zeros(6), pc0, np.zeros(6)])
    ctrl.reset(q0, np.zeros(6))
    rhs_fn = dyn.functions["plant_rhs"]
    fric, tau_v = np.asarray(sc.friction, float), np.array([sc.valve_lag])
    ps = model.supply_pressure
    kf = _KalmanRate(h, sc.noise_l, sc.kalman_accel, dyn.leg_lengths(q0)) if sc.kalman else None

    log = {k: np.full((n, w), np.nan) for k, w in (("q", 6), ("q_d", 6), ("l", 6), ("f", 6), ("pc", 6),
                                                      ("u", 6), ("th", 4), ("g1", 6), ("g2", 6))}
    t_log = np.arange(n) * h
    q_meas = q0.copy()
    start = time.perf_counter()
    k_done = 0
    try:
        for k in range(n):
            t = k * h
            q, qdot, pc = x[:6], x[6:12], x[12:18]
            l_true = dyn.leg_lengths(q)
            l_meas = l_true + sc.noise_l * rng.standard_normal(6) if sc.noise_l else l_true
            pc_meas = np.clip(pc + sc.noise_p * rng.standard_normal(6), 0, ps) if sc.noise_p else pc
            ldot = kf.update(l_meas) if kf else dyn.leg_jacobian(q) @ qdot
            q_meas = dyn.forward_kinematics(l_meas, q0=q_meas)
            qdot_meas = np.linalg.solve(dyn.leg_jacobian(q_meas), ldot)
            ref = sc.reference(t)
            u = ctrl.command(q_meas, qdot_meas, pc_meas, l_meas, ref, t >= sc.t_adapt)
            log["q"][k], log["q_d"][k], log["l"][k], log["pc"][k], log["u"][k] = q, ref[0], l_true, pc, u
            log["f"][k] = pc * model.piston_area - ps * model.rod_area
            th = ctrl.part("theta_hat")
            log["th"][k] = th if th is not None else theta0
            g1, g2 = ctrl.part("gamma1_hat"), ctrl.part("gamma2_hat")
            log["g1"][k] = g1 if g1 is not None else gamma0[0]
            log["g2"][k] = g2 if g2 is not None else gamma0[1]
            k_done = k + 1
            if k == n - 1:
                break
            rhs = lambda xx: rhs_fn(xx, u, theta_true, gamma_true, fric, tau_v)  # noqa: E731
            hs = h / sc.substeps
            for _ in range(sc.substeps):
                x = _rk4(rhs, x, hs)
                np.clip(x[12:18], 0.0, ps, out=x[12:18])  # 0 ≤ p_c ≤ p_s
            ctrl.advance(h)
            if not np.all(np.isfinite(x)) or not np.all(np.isfinite(ctrl.xc)):
                bad = [i for i in range(24) if not np.isfinite(x[i])]
                raise SimulationError(
                    f"simulation '{sc.name}' with '{controller}' diverged at t = {t + h:.4f} s: "
                    f"non-finite plant state entries {bad} (x = [q, qdot, pc, spool]); state = {x.tolist()}")
    except (SimulationError, KinematicsError) as exc:
        res = _result(sc, controller, t_log, log, k_done, theta_true, gamma_true, time.perf_counter() - start)
        if isinstance(exc, SimulationError):
            exc.result = res
            raise
        raise SimulationError(f"simulation '{sc.name}' with '{controller}' stopped at t = {k * h:.4f} s: {exc}",
                              result=res) from exc
    return _result(sc, controller, t_log, log, k_done, theta_true, gamma_true, time.perf_counter() - start)


def _result(sc, controller, t, log, k, theta_true, gamma_true, wall):
    res = SimulationResult(
        scenario=sc.name, controller=controller, t=t[:k], q=log["q"][:k], q_d=log["q_d"][:k],
        leg_lengths=log["l"][:k], leg_forces=log["f"][:k], pressures=log["pc"][:k], u=log["u"][:k],
        theta_hat=log["th"][:k], gamma1_hat=log["g1"][:k], gamma2_hat=log["g2"][:k],
        theta_true=theta_true, gamma_true=gamma_true, amplitude=sc.reference.amplitude(),
        metric_start=sc.metric_start, wall_time_s=wall)
    if k:
        res.compute_metrics()
    return res


def _check_reference(dyn, sc, n, h):
    """Reject a reference that leaves the legs' stroke, naming the time and the leg."""
    m = dyn.model
    for k in range(0, n, max(1, n // 2000)):
        l = dyn.leg_lengths(sc.reference(k * h)[0])
        bad = np.nonzero((l < m.leg_min) | (l > m.leg_max))[0]
        if bad.size:
            i = int(bad[0])
            raise KinematicsError(
                f"reference of scenario '{sc.name}' leaves the workspace at t = {k * h:.3f} s: leg {i} would be "
                f"{l[i]:.4f} m, stroke is [{m.leg_min}, {m.leg_max}] m")
