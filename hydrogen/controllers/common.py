"""Default gains shared by the model-based controllers (numpy only)."""
from __future__ import annotations

import numpy as np

__all__ = ["model_gains", "adaptation_gains", "RAW_ADAPTATION_GAINS", "adaptation_references",
           "normalised_adaptation"]

#: The raw adaptation gains of the generated controllers (Γ_θ⁻¹, Γ_γ1⁻¹, Γ_γ2⁻¹) and the normalised
#: rate (one per family) each is made from when it is not given.
RAW_ADAPTATION_GAINS = {"Gtheta_inv": "rate_theta", "Ggamma1_inv": "rate_gamma1", "Ggamma2_inv": "rate_gamma2"}


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
    """Normalised adaptation gains: one rate per family, Γ⁻¹ = rate · diag(x_ref²) (see
    :func:`normalised_adaptation`), in 1/J: the Lyapunov function then holds the parameter errors as
    ½ Σ (x̃_k / x_ref,k)² / rate joules, every estimate moving in proportion to its own magnitude.

    The raw gains Γ_θ⁻¹ (p), Γ_γ1⁻¹, Γ_γ2⁻¹ (m each) of the generated controllers are NaN here,
    meaning "from the rate"; given explicitly (the names before normalisation), they win.
    """
    m, p = model.n_cylinders, model.n_theta
    return {"rate_theta": np.array([0.1]), "rate_gamma1": np.array([1.0e-3]), "rate_gamma2": np.array([1.0e-3]),
            "Gtheta_inv": np.full(p, np.nan), "Ggamma1_inv": np.full(m, np.nan), "Ggamma2_inv": np.full(m, np.nan)}


def adaptation_references(model, theta0, gamma0) -> dict:
    """Magnitudes the adaptation gains are normalised by: θ_ref = the midpoint of each parameter's
    projection bounds (or its half-width when the bounds straddle zero), γ_ref = the initial
    estimates per cylinder (the γ bounds are one interval shared by cylinders of different sizes)."""
    lo, hi = np.asarray(model.theta_min, float), np.asarray(model.theta_max, float)
    theta_ref = np.maximum(np.abs(0.5 * (lo + hi)), 0.5 * (hi - lo))
    gamma0 = np.asarray(gamma0, float)
    return {"Gtheta_inv": theta_ref, "Ggamma1_inv": np.abs(gamma0[0]), "Ggamma2_inv": np.abs(gamma0[1])}


def normalised_adaptation(model, gains: dict, theta0, gamma0) -> dict:
    """Fill the raw adaptation gains left NaN from their family's rate: Γ⁻¹_k = rate · x_ref,k²."""
    refs = adaptation_references(model, theta0, gamma0)
    out = dict(gains)
    for raw, rate in RAW_ADAPTATION_GAINS.items():
        if raw in out and rate in out:
            v = np.array(out[raw], float)
            nan = np.isnan(v)
            v[nan] = (float(np.asarray(out[rate]).ravel()[0]) * refs[raw] ** 2)[nan]
            out[raw] = v
    return out
