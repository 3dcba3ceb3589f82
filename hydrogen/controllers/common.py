"""Default gains shared by the model-based controllers (numpy only)."""
from __future__ import annotations

import numpy as np

__all__ = ["model_gains", "adaptation_gains"]


def model_gains(model, scale) -> dict:
    """Gains of the position and force loops, per coordinate scaled by the inertia ``scale`` so
    each coordinate has the same error dynamics (SI): Λ 1/s, K_d N s/m (N m s/rad), K_p N/m
    (N m/rad), K_τ 1/s, Γ_τ⁻¹ (N/s)/(m/s), u_max m of spool travel."""
    n, m = model.n, model.n_cylinders
    scale = np.asarray(scale, float)
    return {
        "Lambda": 60.0 * np.ones(n),
        "Kd": 60.0 * scale,
        "Kp": 300.0 * scale,
        "Ktau": 150.0 * np.ones(m),
        "Gtau_inv": 1.0e4 * np.ones(m),
        "u_max": np.array([5.0e-3]),
    }


def adaptation_gains(model) -> dict:
    """Adaptation gains Γ_θ⁻¹ (p), Γ_γ1⁻¹ and Γ_γ2⁻¹ (m each)."""
    m = model.n_cylinders
    return {"Gtheta_inv": 1.0e3 * np.ones(model.n_theta), "Ggamma1_inv": 1.0e14 * np.ones(m),
            "Ggamma2_inv": 2.0e7 * np.ones(m)}
