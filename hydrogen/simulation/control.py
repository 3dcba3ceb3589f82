"""Controller runtimes: bind gains and state to a generated controller and step it at a fixed rate.

Every controller has the same contract, ``command(meas, ref, adapt) -> u`` then
``advance(h)`` (forward Euler on the controller state over one control period,
estimates kept inside their projection bounds), so the loop treats them alike.
"""
from __future__ import annotations

import numpy as np

from ..errors import ScenarioError
from ..symbolic.layout import STATE_LAYOUT
from .checks import check_gain_values

__all__ = ["make_controller", "DEFAULT_GAINS", "CONTROLLERS"]

_T, _R = np.array([1.0, 1, 1, 0, 0, 0]), np.array([0.0, 0, 0, 1, 1, 1])

#: Default gains (SI): translation and rotation scaled by mass and inertia so each coordinate has
#: the same error dynamics. Tuned on paper-sim and the three experiment scenarios together
#: (one set for all; see README "Gains"): Λ·K_d is limited by the 2 ms valve lag of the experiments.
DEFAULT_GAINS = {
    "common": {
        "Lambda": 60.0 * np.ones(6),                 # 1/s
        "Kd": 60.0 * (250 * _T + 45 * _R),           # N s/m, N m s/rad
        "Kp": 300.0 * (250 * _T + 45 * _R),          # N/m, N m/rad
        "Ktau": 150.0 * np.ones(6),                  # 1/s, leg-force loop
        "Gtau_inv": 1.0e4 * np.ones(6),              # (N/s)/(m/s)
        "u_max": np.array([5.0e-3]),                 # m, spool travel
    },
    "adaptive-robust": {
        "Ko": 30.0 * np.ones(6),                     # 1/s
        "Gz_inv": 1.0 / (250 * _T + 45 * _R),        # observer weight Γ_z⁻¹ ≈ D⁻¹ (1/kg, 1/(kg m²))
        "lambda_o": np.array([0.0, 0.0, 0.0, 0.0]),  # λ0..λ3 of (55): the sliding term off (see README)
        "sat_width": np.array([1.0e-3]),             # m/s, rad/s: sat(z̃/ε) in place of sgn(z̃)
        "Gtheta_inv": np.array([1.0e3, 2.0e3, 2.0e3, 2.0e3]),
        "Ggamma1_inv": 1.0e14 * np.ones(6),
        "Ggamma2_inv": 2.0e7 * np.ones(6),
    },
    "adaptive-observer": {
        "Lambda2": 60.0 * np.ones(6),
        "Lp": 3000.0 * (250 * _T + 45 * _R),
        "Kd_obs": 60.0 * (250 * _T + 45 * _R),
        "Gtheta_inv": np.array([1.0e3, 2.0e3, 2.0e3, 2.0e3]),
        "Ggamma1_inv": 1.0e14 * np.ones(6),
        "Ggamma2_inv": 2.0e7 * np.ones(6),
    },
    # The documented search (hydrogen.simulation.tuning.tune_p, `hydrogen tune-p`): the largest gain
    # stable on all three experiments; above it a ~7 Hz off-axis oscillation starts on psi-1hz.
    "p": {"Kleg": 0.0358 * np.ones(6), "u_max": np.array([3.0e-3])},
}

CONTROLLERS = ("backstepping", "adaptive-robust", "adaptive-observer", "p")


def _gains(kind, overrides):
    g = {} if kind == "p" else dict(DEFAULT_GAINS["common"])
    g.update(DEFAULT_GAINS.get(kind, {}))
    for k, v in (overrides or {}).items():
        if k not in g:
            raise ScenarioError(f"controller '{kind}' has no gain '{k}'; it has {sorted(g)}")
        try:
            g[k] = np.broadcast_to(np.asarray(v, float), np.shape(g[k])).copy()
        except (TypeError, ValueError):
            raise ScenarioError(f"controller '{kind}': gain '{k}' needs shape {np.shape(g[k])} "
                                f"(or a scalar), got {v!r}") from None
        if not np.all(np.isfinite(g[k])):
            raise ScenarioError(f"controller '{kind}': gain '{k}' must be finite, got {v!r}")
    return g


class _Controller:
    def __init__(self, dyn, kind, gains, theta0, gamma0, model):
        self.kind = kind
        # Buffers of its own: runners, steppers and threads sharing one library never see each other's gains.
        self.fn = dyn.functions[f"ctrl_{kind.replace('-', '_')}"].clone()
        self.values = dict(gains)
        self.layout = STATE_LAYOUT[kind]
        self.model = model
        self.theta0, self.gamma0 = np.asarray(theta0, float), np.asarray(gamma0, float)
        self.xc = np.zeros(sum(n for _, n in self.layout))
        self.xc_dot = np.zeros_like(self.xc)
        self._slices, i = {}, 0
        for name, n in self.layout:
            self._slices[name] = slice(i, i + n)
            i += n
        lo, hi = np.full(self.xc.size, -np.inf), np.full(self.xc.size, np.inf)
        if "theta_hat" in self._slices:
            m = model
            lo[self._slices["theta_hat"]], hi[self._slices["theta_hat"]] = m.theta_min, m.theta_max
            lo[self._slices["gamma1_hat"]], hi[self._slices["gamma1_hat"]] = m.gamma1_min, m.gamma1_max
            lo[self._slices["gamma2_hat"]], hi[self._slices["gamma2_hat"]] = m.gamma2_min, m.gamma2_max
            self.values.update(theta_min=m.theta_min, theta_max=m.theta_max,
                               gamma1_min=np.array([m.gamma1_min]), gamma1_max=np.array([m.gamma1_max]),
                               gamma2_min=np.array([m.gamma2_min]), gamma2_max=np.array([m.gamma2_max]))
        self._lo, self._hi = lo, hi
        self.tau_d = np.zeros(6)
        self.tau_d_dot = np.zeros(6)
        self.f_d = np.zeros(6)

    def part(self, name):
        s = self._slices.get(name)
        return None if s is None else self.xc[s]

    def reset(self, q0, qdot0):
        if "z" in self._slices:
            self.xc[self._slices["z"]] = qdot0
        if "q_hat" in self._slices:
            self.xc[self._slices["q_hat"]] = q0
        if "theta_hat" in self._slices:
            self.xc[self._slices["theta_hat"]] = self.theta0
            self.xc[self._slices["gamma1_hat"]] = self.gamma0[0]
            self.xc[self._slices["gamma2_hat"]] = self.gamma0[1]

    def command(self, q, qdot, pc, l, ref, adapt):
        v = self.values
        v.update(q=q, qdot=qdot, pc=pc, l=l, qd0=ref[0], qd1=ref[1], qd2=ref[2], qd3=ref[3])
        if self.xc.size:
            v["xc"] = self.xc
            v["adapt"] = np.array([1.0 if adapt else 0.0])
        out = self.fn(*[v[n] for n in self.fn.in_names])
        if not isinstance(out, tuple):
            return out
        u = out[0]
        if self.xc.size:
            self.xc_dot = out[1]
        self.tau_d, self.tau_d_dot, self.f_d = out[-3], out[-2], out[-1]
        return u

    def advance(self, h):
        if self.xc.size:
            np.clip(self.xc + h * self.xc_dot, self._lo, self._hi, out=self.xc)


def make_controller(dyn, kind, gains=None, theta0=None, gamma0=None, dbar_pose=None):
    """A controller runtime of ``kind`` (one of :data:`CONTROLLERS`) for compiled dynamics ``dyn``.

    ``theta0``/``gamma0`` are the initial estimates (the known values for
    ``backstepping``); the robust observer's constant D̄, Ḡ are D and G at
    ``dbar_pose`` (default: neutral) with ``theta0``.
    """
    if kind not in CONTROLLERS:
        raise ScenarioError(f"unknown controller '{kind}'; choose one of {', '.join(CONTROLLERS)}")
    model = dyn.model
    theta0 = model.theta if theta0 is None else theta0
    gamma0 = model.gamma if gamma0 is None else gamma0
    g = _gains(kind, gains)
    check_gain_values(kind, g)
    if kind == "backstepping":
        g.update(theta=np.asarray(theta0, float), gamma=np.asarray(gamma0, float))
    if kind == "adaptive-robust":
        pose = model.neutral_pose if dbar_pose is None else dbar_pose
        g["Dbar_inv"] = np.linalg.inv(dyn.mass_matrix(pose, theta0))
        g["Gbar"] = dyn.gravity(pose, theta0)
    return _Controller(dyn, kind, g, theta0, gamma0, model)
