"""Default gains shared by the model-based controllers (numpy only)."""
from __future__ import annotations

import numpy as np

__all__ = ["model_gains", "adaptation_gains", "RAW_ADAPTATION_GAINS", "adaptation_references",
           "normalised_adaptation", "composite_layout", "composite_static_inputs", "initial_gain_matrix"]

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
            "Gtheta_inv": np.full(p, np.nan), "Ggamma1_inv": np.full(m, np.nan), "Ggamma2_inv": np.full(m, np.nan),
            **composite_gains()}


def composite_gains() -> dict:
    """Gains of the composite (prediction-error, least-squares) terms (:mod:`hydrogen.symbolic.composite`).

    ``rate_ls_gamma`` k (1/s) weighs the composite term of γ; 0 (the default) is the paper's gradient
    law exactly. ``lambda_f_gamma`` (1/s) is the bandwidth of the filters that make the prediction
    error need no ḟ; ``P0_gamma`` the initial least-squares gain (dimensionless: the parameters are
    normalised by their references); ``ls_floor`` δ (dimensionless) bounds the growth of P⁻¹ by
    k/δ; ``ls_nu_gamma`` ν (1/s, force rate per unit of the cylinder's force range P_s A) keeps the
    normalisation positive without excitation. The explicit update keeps P positive definite
    while k h < 1 (checked per run)."""
    return {"rate_ls_gamma": np.array([0.0]), "lambda_f_gamma": np.array([100.0]), "P0_gamma": np.array([1.0]),
            "ls_floor": np.array([1.0e-4]), "ls_nu_gamma": np.array([1.0e-3])}


def composite_layout(model) -> list:
    """The state blocks the composite adaptation adds to an adaptive controller, in order: per
    cylinder the filtered force (N), ln(l − L) and g0 (N/s per unit γ2), the previous period's
    spool (m), control pressure (Pa) and length (m), and the 2×2
    least-squares gain's upper triangle [P11, P12, P22] (dimensionless). Details in
    :class:`hydrogen.symbolic.composite.HydraulicComposite`."""
    m = model.n_cylinders
    return [("force_filter", m), ("log_chamber_filter", m), ("g0_filter", m), ("spool_prev", m), ("pc_prev", m), ("legl_prev", m),
            ("gamma_gain", 3 * m)]


def composite_static_inputs(model, theta0, gamma0) -> dict:
    """Numeric inputs of the composite terms made once per run: the references x_ref the parameters
    are normalised by (those of :func:`adaptation_references`)."""
    refs = adaptation_references(model, theta0, gamma0)
    return {"gamma_ref": np.concatenate([refs["Ggamma1_inv"], refs["Ggamma2_inv"]])}


def initial_gain_matrix(k: int, copies: int, p0: float) -> np.ndarray:
    """``copies`` upper triangles (row by row) of p0 · I (k×k): the initial least-squares gains."""
    tri = np.array([p0 if i == j else 0.0 for i in range(k) for j in range(i, k)])
    return np.tile(tri, copies)


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
