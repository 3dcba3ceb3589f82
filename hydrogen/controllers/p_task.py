"""P control of the pose: u = K_q-weighted pose error mapped to the cylinders by JL, per cylinder
u_i = Σ_j JL_ij(q) K_q,j (q_d,j − q_j), saturated at ±u_max.

To first order JL (q_d − q) = l_d − l, so equal K_q on every coordinate is the cylinder-space P
controller; per-axis gains let the stiff, well-damped axes (on the platform z and ψ) take a higher
gain than the sway modes its steep legs leave lightly damped (x, y, θ, φ), which cap one shared gain.
"""
from __future__ import annotations

import numpy as np

from .spec import ControllerSpec

SPEC = ControllerSpec(name="p-task", doc="P controller on the pose error, per-axis gains, mapped by JL.",
                      main_gain="Kq", grid_low=0.005, secondary_search=False,
                      search_description_proportions=True, compared=True, rank=4)
NAME, DOC = SPEC.name, SPEC.doc


def state_layout(model) -> list:
    return []


def default_gains(model, scale) -> dict:
    """K_q per coordinate (m of spool per m or rad of pose error, through JL: the cylinder P's K
    on every axis) and the spool travel u_max (m); a robot's per-axis gains go into its description
    (``[gains.p-task]``), found by ``hydrogen tune --controller p-task``."""
    return {"Kq": 0.03 * np.ones(model.n), "u_max": np.array([3.0e-3])}


def static_inputs(dyn, theta0, gamma0) -> dict:
    return {}


def derive(model):
    import sympy as sp

    from ..symbolic.calculus import clip
    from ..symbolic.control_laws import ControllerParts, scalar, vector
    from ..symbolic.kinematics import leg_stages

    n, m = model.n, model.n_cylinders
    q, qd0, k, u_max = vector("q", n), vector("qd0", n), vector("Kq", n), scalar("u_max")
    _, JL, stages = leg_stages(model, q)
    weighted = sp.Matrix([k[j] * (qd0[j] - q[j]) for j in range(n)])
    cmd = JL * weighted
    u = sp.Matrix([clip(cmd[i], -u_max, u_max) for i in range(m)])
    return ControllerParts(inputs=[("q", q), ("qd0", qd0), ("Kq", k), ("u_max", sp.Matrix([u_max]))],
                           outputs=[("u", u)], intermediates=stages)
