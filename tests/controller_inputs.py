"""Random controller inputs for the composite-adaptation tests (numpy only)."""
import numpy as np

from hydrogen.controllers.common import COMPOSITE_RATES, initial_gain_matrix
from hydrogen.pressures import bounds as pressure_bounds, uniform_three_way

#: The paper's gradient laws (composite weights 0), whatever a description stores.
PAPER_LAWS = {k: 0.0 for k in COMPOSITE_RATES}


def random_pressures(model, rng, low=0.3, high=0.7, size=None):
    """Chamber pressures (n_pressures,) at fractions [low, high] of each state's bounds (the control
    pressure's [0, P_s] for a three-way cylinder, [P_t, P_s] for a four-way cylinder's p_A and p_B)."""
    lo, hi = pressure_bounds(model)
    if uniform_three_way(model):
        return model.supply_pressure * rng.uniform(low, high, model.n_cylinders if size is None else size)
    return lo + (hi - lo) * rng.uniform(low, high, lo.size)


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
            xc[sl] = random_pressures(model, rng, size=size)
        elif name == "legl_prev":
            if uniform_three_way(model):
                xc[sl] = model.chamber_length + rng.uniform(0.3, 0.5, size)
            else:  # inside the stroke
                xc[sl] = model.leg_min + (model.leg_max - model.leg_min) * rng.uniform(0.2, 0.8, size)
        else:
            xc[sl] = rng.standard_normal(size) * (1e4 if "filter" in name else 0.05)
    pc = random_pressures(model, rng)
    ref = [model.neutral_pose + rng.uniform(-0.02, 0.02, n), *(rng.uniform(-0.1, 0.1, (3, n)))]
    return q, rng.uniform(-0.05, 0.05, n), pc, ref, xc


def kind_laws(model, l, ldot, p, u, ps=None):
    """(f, f0, g0) per cylinder (m,) from each cylinder's actuator kind's numpy laws
    (hydrogen/actuators/<kind>.py): force, f0 = the force rate at a closed valve over β, g0 the valve
    term over βc, at lengths ``l``, rates ``ldot``, the pressure vector ``p`` and spools ``u``; at the
    supply pressure ``ps`` (Pa, a measured one) instead of each actuator's own where given."""
    from hydrogen.actuators import actuator
    from hydrogen.pressures import blocks
    out = []
    for c, (a, b), li, vi, ui in zip(model.cylinders, blocks(model), l, ldot, u):
        mod = actuator(c.kind)
        P, pi = mod.parameters(c.table), tuple(p[a:b])
        if ps is not None:
            P = {**P, "supply_pressure": float(np.ravel(ps)[0])}
        out.append((mod.Numeric.force(pi, P), mod.Numeric.f0(li, vi, pi, P), mod.Numeric.g0(li, pi, ui, P)))
    return tuple(np.array(v, float) for v in zip(*out))
