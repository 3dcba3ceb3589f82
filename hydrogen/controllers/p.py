"""The paper's baseline: u = K (l_d − l) per cylinder, l_d = l(q_d), saturated at ±u_max."""
from __future__ import annotations

import numpy as np

from .spec import ControllerSpec

SPEC = ControllerSpec(name="p", doc="P controller on cylinder lengths (the paper's baseline).",
                      main_gain="Kleg", grid_low=0.005, main_gain_shared=True, secondary_search=False,
                      baseline=True, compared=True, rank=3)
NAME, DOC = SPEC.name, SPEC.doc


def state_layout(model) -> list:
    return []


def default_gains(model, scale) -> dict:
    """K (m of spool per m of length error) and the spool travel u_max (m); a robot's tuned gain
    goes into its description (``[gains.p]``), found by ``hydrogen tune-p``."""
    return {"Kleg": 0.03 * np.ones(model.n_cylinders), "u_max": np.array([3.0e-3])}


def static_inputs(dyn, theta0, gamma0) -> dict:
    return {}


def derive(model):
    import sympy as sp

    from ..symbolic.calculus import clip
    from ..symbolic.control_laws import ControllerParts, scalar, vector
    from ..symbolic.kinematics import leg_stages

    m = model.n_cylinders
    l_meas, qd0, k, u_max = vector("l", m), vector("qd0", model.n), vector("Kleg", m), scalar("u_max")
    ld, _, stages = leg_stages(model, qd0)
    u = sp.Matrix([clip(k[i] * (ld[i] - l_meas[i]), -u_max, u_max) for i in range(m)])
    return ControllerParts(inputs=[("l", l_meas), ("qd0", qd0), ("Kleg", k), ("u_max", sp.Matrix([u_max]))],
                           outputs=[("u", u)], intermediates=stages[:-1])
