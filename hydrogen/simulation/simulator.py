"""The closed loop: plant (RK4 sub-steps), sensors, forward kinematics, controller at a fixed rate."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import KinematicsError, SimulationError
from .control import make_controller
from .scenarios import Scenario, scenario as named_scenario

__all__ = ["simulate", "SimulationResult", "COORDS", "equilibrium_pressures", "Stepper"]

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
    wall_time_s: float = 0.0  # the run: setup, loop, result, with the library already loaded (s)
    loop_wall_s: float = 0.0  # the closed loop alone (s)
    u_max: float = 0.0
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
            "loop_wall_s": float(self.loop_wall_s),
            "metric_start_s": self.metric_start,
        }
        return self.metrics

    def to_json(self) -> str:
        return json.dumps(self.metrics or self.compute_metrics(), indent=2, sort_keys=True)

    def save_log(self, path, noise_l: float = 0.0, noise_p: float = 0.0, seed: int = 0):
        """Write the run as a rig log CSV for :func:`hydrogen.identify` (columns t, l*, pc*, u*, q*),
        with white sensor noise of std ``noise_l`` m and ``noise_p`` Pa added: see :mod:`hydrogen.logs`."""
        from ..logs import log_from_result, write_log
        return write_log(log_from_result(self, noise_l, noise_p, seed), path)


def equilibrium_pressures(dyn, q, theta) -> np.ndarray:
    """Control pressures (Pa) whose leg forces hold the platform still at pose q: (JL)ᵀ f = G."""
    m = dyn.model
    f = np.linalg.solve(dyn.leg_jacobian(q).T, dyn.gravity(q, theta))
    return (f + m.supply_pressure * m.rod_area) / m.piston_area


def _rk4(rhs, x, h):
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * h * k1)
    k3 = rhs(x + 0.5 * h * k2)
    k4 = rhs(x + h * k3)
    return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


def simulate(dyn, scenario, controller: str, *, gains=None, duration=None, check_workspace=True,
             engine: str = "c", **overrides) -> SimulationResult:
    """Run ``controller`` on ``scenario`` (a name or a :class:`Scenario`) with compiled dynamics ``dyn``.

    ``engine="c"`` (default) runs the whole loop in the compiled C driver;
    ``engine="python"`` runs the same loop step by step in Python (the slow
    reference: same sensors, same noise samples). ``overrides`` replace scenario
    fields (e.g. ``t_adapt=1.0``). A run whose state becomes non-finite raises
    :class:`~hydrogen.errors.SimulationError` naming the time and the state;
    ``err.result`` holds the partial result.
    """
    call_start = time.perf_counter()
    p = _prepare(dyn, scenario, controller, gains, duration, check_workspace, overrides)
    sc, ctrl, n, h = p.sc, p.ctrl, p.n, p.h
    if engine not in ("c", "python"):
        raise ValueError(f"engine must be 'c' or 'python', not {engine!r}")
    log = {k: np.full((n, w), np.nan) for k, w in (("q", 6), ("q_d", 6), ("l", 6), ("f", 6), ("pc", 6),
                                                      ("u", 6), ("xc", max(ctrl.xc.size, 1)))}
    t_log = np.arange(n) * h
    start = time.perf_counter()
    run = _run_c if engine == "c" else _run_python
    k_done, failure = run(dyn, sc, ctrl, p.x0, p.q0, p.noise, p.kf_gain, log, n, h)
    wall = time.perf_counter() - start
    res = _result(sc, controller, ctrl, t_log, log, k_done, p.theta0, p.gamma0, dyn.model.theta,
                  dyn.model.gamma, wall)
    res.wall_time_s = time.perf_counter() - call_start
    if res.metrics:
        res.metrics["wall_time_s"] = res.wall_time_s
    if failure:
        raise SimulationError(f"simulation '{sc.name}' with '{controller}' {failure}", result=res)
    return res


@dataclass
class _Prepared:
    sc: Scenario
    ctrl: object
    n: int
    h: float
    x0: np.ndarray
    q0: np.ndarray
    noise: np.ndarray
    kf_gain: object
    theta0: np.ndarray
    gamma0: np.ndarray


def _prepare(dyn, scenario, controller, gains, duration, check_workspace, overrides) -> _Prepared:
    """Scenario, controller runtime, initial state and noise table shared by every engine."""
    model = dyn.model
    sc = named_scenario(scenario, model) if isinstance(scenario, str) else scenario
    overrides = dict(overrides)
    if duration is not None:
        overrides["duration"] = float(duration)
    sc = sc.with_overrides(**overrides) if overrides else sc
    h = 1.0 / sc.control_rate
    n = int(round(sc.duration * sc.control_rate)) + 1
    theta0 = model.theta * np.asarray(sc.theta0_factor)
    gamma0 = model.gamma * np.asarray(sc.gamma0_factor)
    if controller == "backstepping":
        theta0, gamma0 = model.theta, model.gamma
    if check_workspace:
        _check_reference(dyn, sc, n, h)
    ctrl = make_controller(dyn, controller, {**sc.gains.get(controller, {}), **(gains or {})}, theta0, gamma0)
    q0 = sc.reference(0.0)[0] + np.asarray(sc.q0_offset, float)
    x0 = np.concatenate([q0, np.zeros(6), equilibrium_pressures(dyn, q0, model.theta), np.zeros(6)])
    ctrl.reset(q0, np.zeros(6))
    # One noise table for every engine: rows [leg length noise (6), pressure noise (6)].
    rng = np.random.default_rng(sc.seed)
    noise = np.zeros((n, 12))
    if sc.noise_l:
        noise[:, :6] = sc.noise_l * rng.standard_normal((n, 6))
    if sc.noise_p:
        noise[:, 6:] = sc.noise_p * rng.standard_normal((n, 6))
    kf_gain = _kalman_gain(h, sc.noise_l, sc.kalman_accel) if sc.kalman else None
    return _Prepared(sc, ctrl, n, h, x0, q0, noise, kf_gain, theta0, gamma0)


def _kalman_gain(h, noise_l, accel):
    """Steady-state gain [K_l, K_ldot] of the constant-velocity Kalman filter (Riccati iteration)."""
    F = np.array([[1.0, h], [0.0, 1.0]])
    Q = accel * np.array([[h ** 3 / 3, h ** 2 / 2], [h ** 2 / 2, h]])
    R = max(noise_l, 1e-9) ** 2
    P = np.eye(2) * 1e-6
    for _ in range(5000):  # 2×2: cheap and converged long before the end
        P = F @ P @ F.T + Q
        K = P[:, 0] / (P[0, 0] + R)
        P = P - np.outer(K, P[0, :])
    return K


def _describe(x, t):
    bad = [i for i in range(x.size) if not np.isfinite(x[i])]
    return (f"diverged at t = {t:.4f} s: non-finite plant state entries {bad} "
            f"(x = [q, qdot, pc, spool]); state = {x.tolist()}")


def _make_runner(dyn, sc, ctrl, x0, q0, kf_gain, h):
    from ..runtime.loop import LoopRunner
    runner = LoopRunner(dyn, ctrl, h=h, substeps=sc.substeps, t_adapt=sc.t_adapt, theta=dyn.model.theta,
                        gamma=dyn.model.gamma, friction=sc.friction, valve_lag=sc.valve_lag,
                        reference=sc.reference, kalman_gain=kf_gain)
    runner.reset(x0, q0, dyn.leg_lengths(q0), ctrl.xc)
    return runner


def _loop_failure(code, runner, h):
    """Message for a non-zero return code of the C loop (None for success)."""
    from ..runtime.loop import LOOP_FK_FAILED, LOOP_NONFINITE, LOOP_OK
    k = runner.state.k
    if code == LOOP_OK:
        return None
    if code == LOOP_NONFINITE:
        return _describe(runner.plant_state, (k + 1) * h)
    if code == LOOP_FK_FAILED:
        return (f"stopped at t = {k * h:.4f} s: forward kinematics did not converge (or JL is singular) "
                f"for the measured leg lengths; state = {runner.plant_state.tolist()}")
    return f"stopped at t = {k * h:.4f} s: a generated function returned an error"


def _run_c(dyn, sc, ctrl, x0, q0, noise, kf_gain, log, n, h):
    from ..runtime.loop import LOOP_NONFINITE, LOOP_OK
    runner = _make_runner(dyn, sc, ctrl, x0, q0, kf_gain, h)
    xc_log = log["xc"] if ctrl.xc.size else None
    logs = {k: log[k] for k in ("q", "q_d", "l", "f", "pc", "u")}
    if xc_log is not None:
        logs["xc"] = xc_log
    code = runner.run(n, noise, logs)
    if code == LOOP_OK:
        return n, None
    k = runner.state.k
    return (k + 1 if code == LOOP_NONFINITE else k), _loop_failure(code, runner, h)


def _run_python(dyn, sc, ctrl, x, q0, noise, kf_gain, log, n, h):
    model = dyn.model
    rhs_fn = dyn.functions["plant_rhs"]
    theta_true, gamma_true = model.theta, model.gamma
    fric, tau_v = np.asarray(sc.friction, float), np.array([sc.valve_lag])
    ps = model.supply_pressure
    kf = np.vstack([dyn.leg_lengths(q0), np.zeros(6)]) if kf_gain is not None else None
    F = np.array([[1.0, h], [0.0, 1.0]])
    q_meas = q0.copy()
    for k in range(n):
        t = k * h
        q, qdot, pc = x[:6], x[6:12], x[12:18]
        l_true = dyn.leg_lengths(q)
        l_meas = l_true + noise[k, :6]
        pc_meas = np.clip(pc + noise[k, 6:], 0, ps) if sc.noise_p else pc
        if kf is not None:
            kf = F @ kf
            kf += np.outer(kf_gain, l_meas - kf[0])
            ldot = kf[1].copy()
        else:
            ldot = dyn.leg_jacobian(q) @ qdot
        try:
            q_meas = dyn.forward_kinematics(l_meas, q0=q_meas)
        except KinematicsError as exc:
            return k, f"stopped at t = {t:.4f} s: {exc}"
        qdot_meas = np.linalg.solve(dyn.leg_jacobian(q_meas), ldot)
        ref = sc.reference(t)
        u = ctrl.command(q_meas, qdot_meas, pc_meas, l_meas, ref, t >= sc.t_adapt)
        log["q"][k], log["q_d"][k], log["l"][k], log["pc"][k], log["u"][k] = q, ref[0], l_true, pc, u
        log["f"][k] = pc * model.piston_area - ps * model.rod_area
        if ctrl.xc.size:
            log["xc"][k] = ctrl.xc
        rhs = lambda xx: rhs_fn(xx, u, theta_true, gamma_true, fric, tau_v)  # noqa: E731
        hs = h / sc.substeps
        for _ in range(sc.substeps):
            x = _rk4(rhs, x, hs)
            np.clip(x[12:18], 0.0, ps, out=x[12:18])  # 0 ≤ p_c ≤ p_s
        ctrl.advance(h)
        if not np.all(np.isfinite(x)) or not np.all(np.isfinite(ctrl.xc)):
            return k + 1, _describe(x, t + h)
    return n, None


def _result(sc, controller, ctrl, t, log, k, theta0, gamma0, theta_true, gamma_true, wall):
    def est(name, width, default):
        s = ctrl._slices.get(name)
        return log["xc"][:k, s] if s is not None else np.tile(default, (k, 1)) * np.ones((k, width))

    res = SimulationResult(
        scenario=sc.name, controller=controller, t=t[:k], q=log["q"][:k], q_d=log["q_d"][:k],
        leg_lengths=log["l"][:k], leg_forces=log["f"][:k], pressures=log["pc"][:k], u=log["u"][:k],
        theta_hat=est("theta_hat", 4, theta0), gamma1_hat=est("gamma1_hat", 6, gamma0[0]),
        gamma2_hat=est("gamma2_hat", 6, gamma0[1]),
        theta_true=theta_true, gamma_true=gamma_true, amplitude=sc.reference.amplitude(),
        metric_start=sc.metric_start, wall_time_s=wall, loop_wall_s=wall,
        u_max=float(ctrl.values["u_max"][0]) if "u_max" in ctrl.values else 0.0)
    if k:
        res.compute_metrics()
    return res


def _check_reference(dyn, sc, n, h):
    """Reject a reference that leaves the legs' stroke at any control period, naming the time and
    the leg (one compiled call for the whole trajectory)."""
    m = dyn.model
    legs = dyn.leg_lengths_many(sc.reference.positions(np.arange(n) * h))
    bad = (legs < m.leg_min) | (legs > m.leg_max)
    if bad.any():
        k, i = (int(v[0]) for v in np.nonzero(bad))
        raise KinematicsError(
            f"reference of scenario '{sc.name}' leaves the workspace at t = {k * h:.3f} s: leg {i} would be "
            f"{legs[k, i]:.4f} m, stroke is [{m.leg_min}, {m.leg_max}] m")


class Stepper:
    """The closed loop one control period per call, for users who write their own loop in Python.

    Each :meth:`step` is one direct call into the compiled loop driver (sensors,
    forward kinematics, controller, plant sub-steps), with every buffer made
    once here. Read the state through the properties between steps.

    Examples
    --------
    >>> st = hydrogen.stepper("paper-sim", "adaptive-robust")
    >>> for _ in range(1000):
    ...     st.step()
    >>> st.t, st.q
    """

    def __init__(self, dyn, scenario="paper-sim", controller="adaptive-robust", *, gains=None,
                 duration=None, check_workspace=True, **overrides):
        p = _prepare(dyn, scenario, controller, gains, duration, check_workspace, overrides)
        self.scenario, self.controller, self.h, self.n_max = p.sc, p.ctrl, p.h, p.n
        self._noise = p.noise
        self._runner = _make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.kf_gain, p.h)
        self._run = self._runner._run
        self._cfg, self._st = self._runner._cfg_ref, self._runner._st_ref
        self._noise_addr = self._noise.ctypes.data
        self._row = self._noise.strides[0]
        self._state = self._runner.state

    def step(self) -> None:
        """Advance one control period (raises SimulationError on divergence)."""
        k = self._state.k
        if k >= self.n_max:
            raise IndexError(f"scenario '{self.scenario.name}' has {self.n_max} periods; pass a longer duration")
        code = self._run(self._cfg, self._st, 1, self._noise_addr + k * self._row, None)
        if code:
            raise SimulationError(f"simulation '{self.scenario.name}' {_loop_failure(code, self._runner, self.h)}")

    @property
    def t(self) -> float:
        """Time of the next period, s."""
        return self._state.t

    @property
    def x(self) -> np.ndarray:
        """Plant state [q, q̇, p_c, spool] (24,)."""
        return self._runner.plant_state

    @property
    def q(self) -> np.ndarray:
        """True pose (6,), base frame."""
        return self._runner.plant_state[:6]

    @property
    def u(self) -> np.ndarray:
        """Last spool command (6,), m."""
        return np.array(self.controller.fn._out_views[0])

    @property
    def xc(self) -> np.ndarray:
        """Controller state (observer and estimates)."""
        return self._runner.xc[: self.controller.xc.size].copy()
