"""Random controller inputs for the composite-adaptation tests (numpy only)."""
import numpy as np

from hydrogen import pressures
from hydrogen.controllers.common import initial_gain_matrix


def _pressures(model, rng):
    """Pressures (n_pressures,) 30-70 % of the way through each state's bounds."""
    lo, hi = pressures.bounds(model)
    return lo + (hi - lo) * rng.uniform(0.3, 0.7, lo.size)


def random_controller_inputs(ctrl, model, rng):
    """Random measurements and states inside the projection bounds (the projection inactive)."""
    n, m = model.n, model.n_cylinders
    q = model.neutral_pose + rng.uniform(-0.02, 0.02, n)
    xc = ctrl.xc.copy()
    for name, sl in ctrl.slices.items():
        size = sl.stop - sl.start
        if name == "theta_hat":
            xc[sl] = model.theta * rng.uniform(0.9, 1.1, size)
        elif name in ("gamma1_hat", "gamma2_hat"):
            xc[sl] = model.gamma[0 if name == "gamma1_hat" else 1] * rng.uniform(0.9, 1.1, size)
        elif name == "gamma_gain":  # with k = 0, P stays where it starts: P0 I
            xc[sl] = initial_gain_matrix(2, m, float(ctrl.values["P0_gamma"][0]))
        elif name == "theta_gain":
            xc[sl] = initial_gain_matrix(model.n_theta, 1, float(ctrl.values["P0_theta"][0]))
        elif name == "q_hat":
            xc[sl] = q + rng.uniform(-1e-3, 1e-3, n)
        elif name in ("log_chamber_filter",):
            xc[sl] = rng.uniform(-1, 0, size)
        elif name == "pc_prev":
            xc[sl] = _pressures(model, rng)
        elif name == "legl_prev":  # inside each actuator's stroke (its chambers' volumes positive)
            xc[sl] = model.leg_min + (model.leg_max - model.leg_min) * rng.uniform(0.3, 0.7, size)
        else:
            xc[sl] = rng.standard_normal(size) * (1e4 if "filter" in name else 0.05)
    pc = _pressures(model, rng)
    ref = [model.neutral_pose + rng.uniform(-0.02, 0.02, n), *(rng.uniform(-0.1, 0.1, (3, n)))]
    return q, rng.uniform(-0.05, 0.05, n), pc, ref, xc
