"""The paper's scenarios: section V's simulation and section VI's experiments, in simulation."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ScenarioError
from .checks import check_fields
from .reference import MultiSine, Step

__all__ = ["Scenario", "scenario", "SCENARIOS"]


@dataclass(frozen=True)
class Scenario:
    """Everything a run needs besides the controller. Units SI.

    control_rate (Hz) with zero-order hold; the plant takes ``substeps`` RK4
    steps per control period. friction = (Coulomb N, viscous N s/m, tanh
    smoothing speed m/s) per leg. noise_l (m) and noise_p (Pa) are standard
    deviations of white measurement noise. With ``kalman`` the leg rates come
    from fixed-gain Kalman filters on the measured leg lengths (constant
    velocity model, white acceleration of spectral density ``kalman_accel``).
    theta0_factor / gamma0_factor scale the true parameters into the initial
    estimates. Metrics are taken over t ≥ metric_start. ``gains`` holds this
    scenario's tuning per controller, under any gains the caller passes. The platform starts at
    rest at q_d(0) + q0_offset, its pressures holding it against gravity.
    """

    name: str
    reference: object
    duration: float
    control_rate: float
    substeps: int
    t_adapt: float
    friction: tuple = (0.0, 0.0, 1e-3)
    valve_lag: float = 0.0
    noise_l: float = 0.0
    noise_p: float = 0.0
    kalman: bool = False
    kalman_accel: float = 50.0
    theta0_factor: tuple = (1.0, 1.0, 1.0, 1.0)
    gamma0_factor: tuple = (1.0, 1.0)
    metric_start: float = 0.0
    q0_offset: tuple = (0.0,) * 6
    seed: int = 0
    gains: dict = field(default_factory=dict)  # controller name -> gain overrides for this scenario

    def with_overrides(self, **kw):
        unknown = set(kw) - set(self.__dataclass_fields__)
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
        need(isinstance(self.substeps, int) and self.substeps >= 1, "substeps", "must be an integer >= 1")
        need(finite(self.t_adapt), "t_adapt", "must be finite (use a large value to never adapt)")
        fr = np.asarray(self.friction, float)
        need(fr.shape == (3,) and finite(fr) and fr[0] >= 0 and fr[1] >= 0 and fr[2] > 0, "friction",
             "must be (Coulomb >= 0 N, viscous >= 0 N s/m, smoothing speed > 0 m/s)")
        for f in ("valve_lag", "noise_l", "noise_p", "kalman_accel"):
            need(finite(getattr(self, f)) and getattr(self, f) >= 0, f, "must be finite and >= 0")
        need(np.shape(self.q0_offset) == (6,) and finite(self.q0_offset), "q0_offset", "must be 6 finite numbers")
        return self


def _paper_sim(neutral):
    # Section V: x, z, ψ, θ, φ multi-sines (m, rad); y_d = 0.
    terms = ((0, 0.02, 1), (0, 0.01, 2), (0, 0.01, 3),
             (2, 0.02, 1), (2, 0.01, 2),
             (3, 0.0873, 1), (3, 0.0349, 2),
             (4, 0.0524, 1), (4, 0.0175, 2),
             (5, 0.0524, 1), (5, 0.0175, 2))
    # Simulation tuning: a softer position loop and a sharper sliding observer than the experiment
    # defaults; with the experiments' linear observer (λ0 = 0) the rigid-body estimates of the robust
    # controller drift to their bounds on this trajectory (README "Gains").
    slow = {"Lambda": 30.0, "Kd": 30.0 * np.array([250, 250, 250, 45, 45, 45.0])}
    gains = {"backstepping": slow, "adaptive-observer": slow,
             "adaptive-robust": {**slow, "Ko": 300.0, "lambda_o": [1.0, 0.0, 0.0, 0.0]}}
    return Scenario(
        name="paper-sim", reference=MultiSine(neutral, terms), duration=10.0,
        control_rate=1000.0, substeps=2, t_adapt=0.5, metric_start=8.0,
        theta0_factor=(1.2, 0.7, 1.3, 0.8), gamma0_factor=(0.7, 1.3), gains=gains)


#: Section VI's rig in simulation: Teflon-sealed legs (Coulomb 100 N, viscous 300 N s/m),
#: 80 Hz valves (first-order lag 2 ms), 5 µm leg-length and 20 kPa pressure noise.
_EXPERIMENT = dict(control_rate=512.0, substeps=8, t_adapt=0.5, friction=(100.0, 300.0, 1e-3),
                   valve_lag=0.002, noise_l=5e-6, noise_p=2e4, kalman=True,
                   theta0_factor=(1.05, 0.95, 0.95, 1.05), gamma0_factor=(0.9, 1.1), metric_start=2.0)


def _experiment(name, neutral, ref, duration=6.0):
    return Scenario(name=name, reference=ref, duration=duration, **_EXPERIMENT)


def scenario(name: str, model) -> Scenario:
    """The named scenario for ``model`` (references are offsets from its neutral pose)."""
    neutral = np.asarray(model.neutral_pose, float)
    builders = {
        "paper-sim": lambda: _paper_sim(neutral),
        "z-1hz": lambda: _experiment("z-1hz", neutral, MultiSine(neutral, ((2, 0.05, 1),))),
        "z-2hz": lambda: _experiment("z-2hz", neutral, MultiSine(neutral, ((2, 0.02, 2),))),
        "psi-1hz": lambda: _experiment("psi-1hz", neutral, MultiSine(neutral, ((3, 0.09, 1),))),
        "z-step": lambda: replace(_experiment("z-step", neutral, Step(neutral, 2, 0.02, 1.0), duration=3.0),
                                  metric_start=0.0),
    }
    if not isinstance(name, str) or name not in builders:
        raise ScenarioError(f"unknown scenario {name!r}; choose one of {', '.join(builders)}")
    return builders[name]()


SCENARIOS = ("paper-sim", "z-1hz", "z-2hz", "psi-1hz", "z-step")
