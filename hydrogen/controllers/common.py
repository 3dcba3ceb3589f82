"""Default gains shared by the model-based controllers (numpy only)."""
from __future__ import annotations

import numpy as np

from .spec import StateBlock

__all__ = ["model_gains", "estimate_layout", "THETA_UNITS", "theta_units", "velocity_units", "check_coupling_gains", "adaptation_gains", "RAW_ADAPTATION_GAINS", "adaptation_references",
           "normalised_adaptation", "composite_layout", "composite_static_inputs", "initial_gain_matrix",
           "COMPOSITE_BLOCKS", "COMPOSITE_GAIN_BLOCKS", "COMPOSITE_RATES", "ADAPTATION_SEARCH", "gain_block_shape", "lean_variant", "runs_lean",
           "FRICTION_BLOCKS", "friction_gains", "friction_layout", "friction_units", "check_friction_start"]

#: The composite law's weights (1/s), one per family: all 0 is the paper's gradient law.
COMPOSITE_RATES = ("rate_ls_gamma", "rate_ls_theta")

#: The adaptation gains the documented search's second stage tries, one at a time, after the main
#: gain (``ControllerSpec.adaptation_search``): the composite weights (1/s) at absolute values (0 is
#: the paper's law; below 1/h of a 512 Hz loop), the normalised rates (1/J, robot-dependent) as
#: factors of the robot's own ("x"): each stage keeps the value with the smallest worst-case error.
ADAPTATION_SEARCH = (("rate_ls_gamma", "=", (0.0, 30.0, 100.0, 300.0)),
                     ("rate_ls_theta", "=", (0.0, 5.0, 20.0, 80.0)),
                     ("rate_theta", "x", (0.25, 1.0, 4.0)),
                     ("rate_gamma1", "x", (0.25, 1.0, 4.0)),
                     ("rate_gamma2", "x", (0.25, 1.0, 4.0)))

#: The state blocks of :func:`composite_layout`, in order.
COMPOSITE_BLOCKS = ("force_filter", "log_chamber_filter", "g0_filter", "pc_prev", "legl_prev", "gamma_gain",
                    "momentum_filter", "momentum_offset_filter", "bias_filter", "bias_offset_filter",
                    "torque_filter", "theta_gain")

#: The least-squares gain blocks of :func:`composite_layout` (upper triangles of k×k matrices, one per
#: copy): block -> (k, its initial-gain input); k None: one copy filling the block.
COMPOSITE_GAIN_BLOCKS = {"gamma_gain": (2, "P0_gamma"), "theta_gain": (None, "P0_theta")}

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
        # per actuator in its own units (N/m, N m/rad); NaN: its kind has no default (check_coupling_gains)
        "Gtau_inv": np.array([np.nan if g is None else g for g in _coupling_gains(model)], float),
        "u_max": np.array([5.0e-3]),
    }


def _coupling_gains(model) -> list:
    from ..actuators import actuator
    return [actuator(c.kind).COUPLING_GAIN for c in model.cylinders]


def check_coupling_gains(model, gains) -> None:
    """ValueError naming the actuators whose force-loop gain Γ_τ⁻¹ (``Gtau_inv``) is still unset: a
    kind without a default (a rotary actuator's, in N·m/rad) needs it from the description."""
    g = np.asarray(gains.get("Gtau_inv", ()), float).ravel()
    unset = [c for c, v in zip(model.cylinders, g) if np.isnan(v)]
    if unset:
        names = ", ".join(f"'{c.name}' ({c.kind})" for c in unset)
        raise ValueError(f"gain 'Gtau_inv' (one per actuator, {model.n_cylinders} values) must be given for {names}: "
                         "its kind has no default; in N m/rad for a rotary actuator, about 1e4 r^2 with r the "
                         "lever (m) of a cylinder doing the same job, N/m for a cylinder (default 1e4)")


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
    """Gains of the composite (prediction-error, least-squares) terms (:mod:`hydrogen.controllers.composite`).

    ``rate_ls_gamma`` k (1/s) weighs the composite term of γ; 0 (the default) is the paper's gradient
    law exactly. ``lambda_f_gamma`` (1/s) is the bandwidth of the filters that make the prediction
    error need no ḟ; ``P0_gamma`` the initial least-squares gain (dimensionless: the parameters are
    normalised by their references); ``ls_floor`` δ (dimensionless) bounds the growth of P⁻¹ by
    k/δ; ``ls_nu_gamma`` ν (1/s, force rate per unit of the cylinder's force range P_s A) keeps the
    normalisation positive without excitation. The explicit update keeps P positive definite
    while k h < 1 (checked per run)."""
    return {"rate_ls_gamma": np.array([0.0]), "lambda_f_gamma": np.array([100.0]), "P0_gamma": np.array([1.0]),
            "ls_floor": np.array([1.0e-4]), "ls_nu_gamma": np.array([1.0e-3]),
            # θ: the same in the momentum form; ν in m/s² or rad/s² (rows divided by the inertia scale)
            "rate_ls_theta": np.array([0.0]), "lambda_f_theta": np.array([20.0]), "P0_theta": np.array([1.0]),
            "ls_nu_theta": np.array([1.0e-3])}


def composite_layout(model) -> list:
    """The state blocks (:class:`~hydrogen.controllers.spec.StateBlock`) the composite adaptation adds
    to an adaptive controller, in order: per
    cylinder the filtered force (N), ln(l − L) (a three-way cylinder; another kind's f0_potential) and g0
    (N/s per unit γ2), the previous period's pressures (Pa, the pressure vector) and length (m), and the 2×2 least-squares gain's upper
    triangle [P11, P12, P22] (dimensionless) (:class:`hydrogen.controllers.composite.HydraulicComposite`);
    then for θ the filtered momentum regressor Y_p (n×p, row-major) and offset p0, the filtered
    Y_b and b0 of G − Cᵀq̇, the filtered generalised force (JL)ᵀ f, and the p×p gain's upper
    triangle (:class:`hydrogen.controllers.composite.RigidBodyComposite`)."""
    from ..pressures import n_pressures
    m, n_p = model.n_cylinders, n_pressures(model)
    n, p = model.n, model.n_theta
    sizes = (m, m, m, n_p, m, 3 * m, n * p, n, n * p, n, n, p * (p + 1) // 2)
    laws = [("gamma", "beta and beta c")] * 6 + [("theta", "inertial parameters")] * 6
    # the copies of the last period's signals start at the start's (never the chamber's dead length, where
    # g0 divides by l - L); the least-squares gains at P0 I; the filters at 0
    initial = {"pc_prev": lambda s: s.pc0, "legl_prev": lambda s: s.l0,
               **{name: _initial_gain(name, size) for name, size in zip(COMPOSITE_BLOCKS, sizes)
                  if name in COMPOSITE_GAIN_BLOCKS}}
    return [StateBlock(name, size, f"the composite {law} law's {name.replace('_', ' ')} (for the {what})",
                       f"its rate rate_ls_{law} (0: the paper's gradient law) or its filter's lambda_f_{law}",
                       initial=initial.get(name, 0.0), unit="Pa" if name == "pc_prev" else None,
                       entries=entries)
            for name, size, (law, what), entries in zip(COMPOSITE_BLOCKS, sizes, laws, _COMPOSITE_ENTRIES)]


#: What the entries of each block of :func:`composite_layout` are ("": numbered).
_COMPOSITE_ENTRIES = ("actuators", "actuators", "actuators", "", "actuators", "", "", "coordinates", "",
                      "coordinates", "coordinates", "")


def _initial_gain(block: str, size: int):
    """The initial-value rule of least-squares gain block ``block`` (``size`` entries): P0 I."""
    k, copies = gain_block_shape(block, size)
    p0 = COMPOSITE_GAIN_BLOCKS[block][1]
    return lambda s: initial_gain_matrix(k, copies, float(np.asarray(s.gains[p0]).ravel()[0]))


#: The friction-compensation estimate blocks of :func:`friction_layout`, in order: Coulomb, viscous.
FRICTION_BLOCKS = ("coulomb_hat", "viscous_hat")

#: The default projection bounds of the friction estimates, as fractions of each actuator's force
#: range (the width of its kind's ``force_range``): F̂_c ≤ 5 % of it, b̂ ≤ 10 % of it per unit of
#: travel per second (N s/m, N m s/rad). A compensation force beyond those would be a model error,
#: not friction.
FRICTION_BOUND_FRACTIONS = (0.05, 0.1)


def friction_units(model) -> tuple:
    """(Coulomb, viscous, speed) units of each actuator, its kind's TRAVEL in FMI spelling: N, N.s/m,
    m/s on a cylinder; N.m, N.m.s/rad, rad/s on a rotary actuator (lists, one entry per actuator)."""
    from ..actuators import actuator
    travel = [actuator(c.kind).TRAVEL for c in model.cylinders]
    force = [t.force_unit.replace(" ", ".") for t in travel]
    return (force, [f"{f}.s/{t.unit}" for f, t in zip(force, travel)], [f"{t.unit}/s" for t in travel])


def _force_widths(model) -> np.ndarray:
    """Each actuator's force range width (its own force unit), from its kind's numeric law."""
    from ..actuators import actuator
    widths = []
    for c in model.cylinders:
        kind = actuator(c.kind)
        lo, hi = kind.Numeric.force_range(kind.parameters(c.table))
        widths.append(float(hi) - float(lo))
    return np.array(widths)


def friction_gains(model, adaptive: bool) -> dict:
    """Gains of the friction compensation (a deviation from the paper, off by default), per actuator
    in its own unit (:func:`friction_units`): f_d gets + F_c tanh(l̇_r / v_s) + b l̇_r, l̇_r = JL q̇_r.

    ``friction_coulomb`` F_c (N, N m) and ``friction_viscous`` b (N s/m, N m s/rad): the known
    coefficients (backstepping) or the estimates' initial values (the adaptive controllers), 0 by
    default (the paper's law exactly); ``friction_speed`` v_s (m/s, rad/s), the width of the smooth
    sign. An adaptive controller also has ``rate_friction`` (1/J, 0: the estimates hold), the rate
    of F̂̇_c = −κ rate F_c,max² tanh(l̇_r/v_s) (JL s), b̂̇ = −κ rate b_max² l̇_r (JL s) (the same
    normalisation as :func:`adaptation_gains`, by the bounds), and the projection's upper bounds
    ``friction_coulomb_max``, ``friction_viscous_max`` (lower bounds 0), by default
    :data:`FRICTION_BOUND_FRACTIONS` of each actuator's force range."""
    if not model.friction_compensation:  # generated without it: no gains to set
        return {}
    m = model.n_cylinders
    out = {"friction_coulomb": np.zeros(m), "friction_viscous": np.zeros(m), "friction_speed": np.full(m, 1.0e-2)}
    if adaptive:
        width = _force_widths(model)
        out.update(rate_friction=np.array([0.0]), friction_coulomb_max=FRICTION_BOUND_FRACTIONS[0] * width,
                   friction_viscous_max=FRICTION_BOUND_FRACTIONS[1] * width)
    return out


def check_friction_start(gains: dict) -> dict:
    """``gains``, or a ValueError naming the friction estimate whose initial value (``friction_coulomb``,
    ``friction_viscous``) lies above its projection bound (``..._max``): the loop would clip it there
    at the first period, silently starting elsewhere than asked."""
    for k in ("friction_coulomb", "friction_viscous"):
        if f"{k}_max" not in gains:  # no friction estimates (compensation not generated)
            continue
        start, bound = np.asarray(gains[k], float), np.asarray(gains[f"{k}_max"], float)
        if np.any(start > bound):
            raise ValueError(f"gain '{k}' = {start.tolist()} (the estimates' initial values) lies above its "
                             f"projection bound '{k}_max' = {bound.tolist()}; raise the bound or lower the start")
    return gains


def friction_layout(model) -> list:
    """The friction estimate blocks (:data:`FRICTION_BLOCKS`) of an adaptive controller's state: F̂_c
    and b̂ per actuator, starting at the gains ``friction_coulomb``, ``friction_viscous`` and kept
    inside [0, ``friction_coulomb_max``], [0, ``friction_viscous_max``]."""
    if not model.friction_compensation:
        return []
    m = model.n_cylinders
    lower = "its adaptation rate (rate_friction) or its smoothing speed (friction_speed)"
    return [StateBlock("coulomb_hat", m, "the Coulomb friction estimates (coulomb_hat)", lower,
                       initial=lambda s: s.gains["friction_coulomb"], limits=(0.0, "friction_coulomb_max"),
                       unit=lambda model: friction_units(model)[0], entries="actuators"),
            StateBlock("viscous_hat", m, "the viscous friction estimates (viscous_hat)", lower,
                       initial=lambda s: s.gains["friction_viscous"], limits=(0.0, "friction_viscous_max"),
                       unit=lambda model: friction_units(model)[1], entries="actuators")]


def estimate_layout(model) -> list:
    """The parameter-estimate blocks (:data:`~hydrogen.controllers.ESTIMATE_BLOCKS`) of an adaptive
    controller's state, each kept inside the model's projection bounds: θ̂ (the [adaptation]
    parameters' units), γ̂1 = β̂ (Pa) and γ̂2 = β̂c per cylinder."""
    m = model.n_cylinders
    return [StateBlock("theta_hat", model.n_theta, "the inertial parameter estimates (theta_hat)",
                       "its adaptation rate (rate_theta, or rate_ls_theta with the composite law)",
                       initial=lambda s: s.theta0, limits=("theta_min", "theta_max"), unit=theta_units,
                       entries="parameters"),
            StateBlock("gamma1_hat", m, "the bulk modulus estimates (gamma1_hat, beta)",
                       "its adaptation rate (rate_gamma1, or rate_ls_gamma with the composite law)",
                       initial=lambda s: s.gamma0[0], limits=("gamma1_min", "gamma1_max"), unit="Pa",
                       entries="actuators"),
            StateBlock("gamma2_hat", m, "the flow gain estimates (gamma2_hat, beta c)",
                       "its adaptation rate (rate_gamma2, or rate_ls_gamma with the composite law)",
                       initial=lambda s: s.gamma0[1], limits=("gamma2_min", "gamma2_max"), unit="m2.Pa0.5/s",
                       entries="actuators")]


#: Unit of each kind of inertial parameter (the part of a θ name after the link's name).
THETA_UNITS = {"mass": "kg", "mcx": "kg.m", "mcy": "kg.m", "mcz": "kg.m", "Ixx": "kg.m2", "Ixy": "kg.m2",
               "Iyy": "kg.m2", "Ixz": "kg.m2", "Iyz": "kg.m2", "Izz": "kg.m2"}


def theta_units(model) -> list:
    """The unit of each of the model's inertial parameters θ (None for a kind not in :data:`THETA_UNITS`)."""
    return [THETA_UNITS.get(t.split(".")[-1]) for t in model.theta_names]


def velocity_units(model) -> list:
    """The unit of each coordinate's rate (m/s or rad/s): an observer's velocity estimate's."""
    return [f"{u}/s" for u in model.coordinate_units]


def composite_static_inputs(dyn, theta0, gamma0) -> dict:
    """Numeric inputs of the composite terms made once per run: the references x_ref the parameters
    are normalised by (those of :func:`adaptation_references`) and the inertia scale the rows of the
    θ prediction error are divided by (the model's ``[control] scale``, else the diagonal of D at
    the neutral pose, as for the default gains)."""
    model = dyn.model
    refs = adaptation_references(model, theta0, gamma0)
    scale = model.scale if model.scale is not None else np.diag(dyn.mass_matrix(model.neutral_pose, model.theta))
    return {"gamma_ref": np.concatenate([refs["Ggamma1_inv"], refs["Ggamma2_inv"]]),
            "theta_ref": refs["Gtheta_inv"], "theta_row_scale": np.abs(np.asarray(scale, float)).ravel()}


def gain_block_shape(block: str, size: int) -> tuple:
    """(k, copies) of least-squares gain block ``block`` of ``size`` entries: k×k upper triangles."""
    k = COMPOSITE_GAIN_BLOCKS[block][0]
    if k is None:
        k = int(round((np.sqrt(8 * size + 1) - 1) / 2))
    return k, size // (k * (k + 1) // 2)


def lean_variant(layout) -> dict | None:
    """How the lean variant of a controller with state ``layout`` is made from its full function,
    or None when the layout has no composite blocks: ``fixed``, the input entries held constant,
    ``(input, index, value)`` with value a number or ``(input, index)`` of another input (the
    composite rates 0; the least-squares gains at P0 I, what they stay at with the rates 0); and
    ``zero``, the rows ``(output, start, stop)`` set to 0 (the composite blocks' rates: their
    filters and copies stay at their initial values). With the composite rates 0, the lean
    function's command and the rates of the other blocks equal the full function's."""
    if not any(name in COMPOSITE_BLOCKS for name, _ in layout):
        return None
    fixed = [(k, 0, 0.0) for k in COMPOSITE_RATES]
    zero, i = [], 0
    for name, size in layout:
        if name in COMPOSITE_GAIN_BLOCKS:
            k, copies = gain_block_shape(name, size)
            p0 = (COMPOSITE_GAIN_BLOCKS[name][1], 0)
            tri = [p0 if a == b else 0.0 for a in range(k) for b in range(a, k)]
            fixed += [("xc", i + j, v) for j, v in enumerate(tri * copies)]
        if name in COMPOSITE_BLOCKS:
            zero.append(("xc_dot", i, i + size))
        i += size
    return {"fixed": fixed, "zero": zero}


def runs_lean(gains: dict) -> bool:
    """Whether a controller with these gains runs its lean variant: every composite rate 0."""
    return all(k in gains and float(np.asarray(gains[k]).ravel()[0]) == 0.0 for k in COMPOSITE_RATES)


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
