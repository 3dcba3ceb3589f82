"""Composite adaptation (SymPy): a filtered prediction error and a normalised least-squares gain.

The paper's laws move each estimate by its tracking error only (a gradient law). Where the
regressor's columns are nearly collinear (the two columns of ḟ = γ1 f0 + γ2 g0 per cylinder; the
slow excavator arm's θ) a gradient law converges along the weak direction λmax/λmin times slower
than along the strong one. Composite adaptation adds a prediction-error term with a least-squares
gain P: the estimate also moves by −k P Wᵀ ε / m², and P shrinks along the directions the data
has excited, which balances the rates without knowing the directions.

Prediction errors need no measured derivative: each side of a linear-in-the-parameters equation
y' = W x is passed through the first-order filter λ_f / (s + λ_f), so ẏ filtered is λ_f (y − φ)
with φ̇ = λ_f (y − φ), and the regressor's filter ω̇ = λ_f (W − ω) gives λ_f (y − φ) ≈ ω x (exactly
after the filters' start transients, e^{−λ_f t}).

Everything here is in normalised units: parameters x = x_phys / x_ref (dimensionless), rows
divided by a scale of their own, so P is dimensionless and the one rate k (1/s) is the user's
gain. With k = 0 the composite term vanishes and P stays at its initial value: the paper's law.

Normalised least squares (one scalar normalisation per equation block):

    m² = tr(W P Wᵀ) + δ ‖W‖² + ν²,   ẋ_c = −k P Wᵀ ε / m²,   Ṗ = −k P Wᵀ W P / m².

Along a direction the data excites, P shrinks at rate up to k (the tr(W P Wᵀ) term: once the
strong direction is learnt, the weak one dominates m² and is learnt at the same rate); δ bounds
the growth of P⁻¹ by k/δ, so P never reaches 0 in finite time; ν keeps m² > 0 without excitation.
P ≤ P0 (it only shrinks), and an explicit step of length h keeps P symmetric positive definite
whenever k h < 1 (the step removes at most k h of P along P^{1/2} Wᵀ). P is stored as its upper
triangle, so it is symmetric by construction.
"""
from __future__ import annotations

from ..actuators.declarations import sp  # SymPy on first use: the registry imports this module

from .common import COMPOSITE_BLOCKS
from ..pressures import blocks

__all__ = ["triangle_size", "unpack_symmetric", "pack_symmetric", "normalised_least_squares",
           "HydraulicComposite"]


def triangle_size(k: int) -> int:
    """Entries of the upper triangle of a k×k symmetric matrix (its state size)."""
    return k * (k + 1) // 2


def _pairs(k):
    return [(i, j) for i in range(k) for j in range(i, k)]


def unpack_symmetric(vec, k: int) -> sp.Matrix:
    """The k×k symmetric matrix whose upper triangle, row by row, is ``vec``."""
    M = sp.zeros(k, k)
    for v, (i, j) in zip(vec, _pairs(k)):
        M[i, j] = M[j, i] = v
    return M


def pack_symmetric(M) -> list:
    """The upper triangle of symmetric ``M``, row by row."""
    return [M[i, j] for i, j in _pairs(M.shape[0])]


def normalised_least_squares(W, eps, P_packed, rate, floor, nu):
    """The composite term and the gain's rate: returns (ẋ_c (column, p), Ṗ packed).

    ``W`` (rows × p) the normalised filtered regressor, ``eps`` (rows) the normalised prediction
    error W x̂ − y_f, ``P_packed`` the upper triangle of P (p×p, dimensionless), ``rate`` k (1/s),
    ``floor`` δ (dimensionless), ``nu`` ν (the rows' unit). Units of ẋ_c: 1/s."""
    p = W.shape[1]
    P = unpack_symmetric(P_packed, p)
    PWt = P * W.T                      # p × rows
    m2 = sum((W[r, :] * PWt[:, r])[0, 0] for r in range(W.shape[0])) \
        + floor * sum((w ** 2 for w in W), sp.S.Zero) + nu ** 2
    x_dot = -rate * PWt * sp.Matrix(eps) / m2
    P_dot = -rate * (PWt * PWt.T) / m2
    return x_dot, pack_symmetric(P_dot)


def staged_least_squares(W, eps, P_packed, rate, floor, nu, name):
    """:func:`normalised_least_squares` with W, ε, P Wᵀ and k/m² bound to symbols ``name_*``:
    returns (ẋ_c, Ṗ packed, intermediates). Each large piece is then evaluated once (SymPy would
    otherwise copy W into every entry of Ṗ)."""
    rows, p = W.shape
    sym = lambda tag, r, c: sp.Matrix(r, c, sp.symbols(f"{name}_{tag}0:{r * c}", real=True))  # noqa: E731
    Ws, es, PWs, g = sym("W", rows, p), sym("eps", rows, 1), sym("PWt", p, rows), sp.Symbol(f"{name}_gain", real=True)
    P = unpack_symmetric(P_packed, p)
    m2 = sum((Ws[r, :] * PWs[:, r])[0, 0] for r in range(rows)) \
        + floor * sum((w ** 2 for w in Ws), sp.S.Zero) + nu ** 2
    stages = [(Ws, sp.Matrix(W)), (es, sp.Matrix(eps)), (PWs, P * Ws.T), (sp.Matrix([g]), sp.Matrix([rate / m2]))]
    x_dot = -g * PWs * es
    P_dot = -g * (PWs * PWs.T)
    return x_dot, pack_symmetric(P_dot), stages


class HydraulicComposite:
    """Composite adaptation of γ = [β, βc] per cylinder (ḟ = γ1 f0 + γ2 g0, eq. (59)).

    ḟ is the small difference of two large, nearly cancelling terms, so the prediction error is
    written so that a control period's timing cannot leave a residual of the size of ḟ:

    * the compression term is an exact derivative, γ1 f0 = −γ1 A d/dt ln(l − L), so its filtered
      value is −A λ_f (ln(l − L) − φ_L) with φ_L the filter state of ln(l − L), discretised exactly
      like the force's λ_f (f − φ_f);
    * the valve term is integrated over each control period by the trapezoid with the spool the
      valve held over it: ḡ_k = ½ (g0(u_held, p_{k−1}, l_{k−1}) + g0(u_held, p_k, l_k)), the
      previous period's pressures and lengths copied in the state (by a rate (x − x_prev)/h).
      A right-rectangle rule, or g0 of a spool one period off, left residuals of 10-230 % of ḟ's
      RMS on paper-sim with the true parameters; this form, 0.03-0.6 %. The held spool is the
      controller's input ``u_applied`` (``Common.u_applied``): the command the valves held over the
      period that ends at this measurement, after the clip and the computation delay, under either
      state update. (A copy of the command computed in the update's own call is a period off under
      the semi-implicit update and left prediction errors of 50-140 % of ḟ.);
    * ε pairs the force-side filters before this period's update (λ_f (f_k − φ_{k−1})) with the
      valve filter after it (ω_{k−1} + h λ_f (ḡ_k − ω_{k−1})): both then obey the same recursion
      x_k = (1 − h λ_f) x_{k−1} + λ_f Δ_k, so the true γ leaves only the trapezoid's residual.

    States per cylinder: φ_f (N), φ_L (ln m), ω (filtered g0, N/s per unit γ2), the previous
    period's control pressure (Pa) and length (m), and P (2×2 upper triangle, dimensionless). Normalisation:
    x = γ̂ / γ_ref (γ_ref the controller's static input, the initial estimates), each cylinder's
    row divided by its force range P_s A, so W and ε are in 1/s.
    """

    def __init__(self, common, g1, g2):
        c = self.c = common
        self.g1, self.g2 = g1, g2
        m = c.m
        sym = lambda name, k: sp.Matrix(sp.symbols(f"{name}0:{k}", real=True))  # noqa: E731
        self.phi_f, self.phi_L, self.omega = sym("force_filter", m), sym("log_chamber_filter", m), sym("g0_filter", m)
        self.pc_prev, self.l_prev = sym("pc_prev", len(c.pc)), sym("legl_prev", m)
        self.pb_prev = [tuple(self.pc_prev[a:b]) for a, b in blocks(c.model)]  # per cylinder, as c.pb
        self.P = sym("gamma_gain", triangle_size(2) * m)
        self.ref = sym("gamma_ref", 2 * m)  # [γ1_ref (m), γ2_ref (m)]
        self.lam, self.rate, self.P0, self.floor, self.nu, self.h = sp.symbols(
            "lambda_f_gamma rate_ls_gamma P0_gamma ls_floor ls_nu_gamma period", real=True)
        # intermediates: ḡ (g0 at the held spool over the last period); the rates before the projection
        self.gbar, self.r1, self.r2 = sym("g0_held", m), sym("gamma1_rate", m), sym("gamma2_rate", m)
        #: intermediates (symbol, value) the rates use, in order; they follow the force loop's stages
        self.u_held = c.u_applied  # the spool the valves held over the period ending now (an input)
        self.stages = [(self.gbar, sp.Matrix(self._g0_interval()))]
        self._ls = None

    #: the state blocks of :func:`hydrogen.controllers.common.composite_layout` that :meth:`states` fills
    BLOCKS = COMPOSITE_BLOCKS[:6]

    def states(self) -> list:
        return [*self.phi_f, *self.phi_L, *self.omega, *self.pc_prev, *self.l_prev, *self.P]

    def inputs(self) -> list:
        return [("gamma_ref", self.ref), ("lambda_f_gamma", sp.Matrix([self.lam])),
                ("rate_ls_gamma", sp.Matrix([self.rate])), ("P0_gamma", sp.Matrix([self.P0])), ("ls_floor", sp.Matrix([self.floor])),
                ("ls_nu_gamma", sp.Matrix([self.nu])), ("period", sp.Matrix([self.h]))]

    def _log_chamber(self):
        """Φ_i of f0 = k_i dΦ_i/dt per cylinder (ln(l − L) of a three-way cylinder)."""
        c = self.c
        return [c.f0_potential(i)[1] for i in range(c.m)]

    def _g0_interval(self):
        """ḡ: the trapezoid of g0 over the last period with the spool held over it."""
        c = self.c
        u = self.u_held
        return [(c.g0(i, self.l_prev[i], self.pb_prev[i], u[i]) + c.g0(i, c.l[i], c.pb[i], u[i])) / 2
                for i in range(c.m)]

    def regressor_and_output(self):
        """(W1, W2, y) per cylinder, unnormalised: filtered ḟ ≈ γ1 W1 + γ2 W2 = y (N/s)."""
        c, lam = self.c, self.lam
        lnL, gbar = self._log_chamber(), self.gbar
        W1 = [c.f0_potential(i)[0] * lam * (lnL[i] - self.phi_L[i]) for i in range(c.m)]
        W2 = [self.omega[i] + self.h * lam * (gbar[i] - self.omega[i]) for i in range(c.m)]
        y = [lam * (c.f[i] - self.phi_f[i]) for i in range(c.m)]
        return W1, W2, y

    def prediction_error(self) -> sp.Matrix:
        """ε_i = (γ̂1 W1 + γ̂2 W2 − y)_i / (P_s A)_i, 1/s: ≈ 0 with the true γ once the filters settle."""
        c, g1, g2 = self.c, self.g1, self.g2
        W1, W2, y = self.regressor_and_output()
        return sp.Matrix([(g1[i] * W1[i] + g2[i] * W2[i] - y[i]) / c.force_scale(i) for i in range(c.m)])

    def combine(self, t1, t2):
        """The rates of γ̂ before the projection from the tracking terms ``t1``, ``t2`` of the
        paper's law (per cylinder): in normalised units x = γ̂/γ_ref,

            ẋ = (P/P0) t_x − k P W ε / m²,

        the composite law of Slotine and Li: the tracking term weighted by the least-squares gain
        too, so V = ½ x̃ᵀ P⁻¹ x̃ / rate holds: the growth of P⁻¹ is paid for by the prediction error
        (V̇ gains −½ k ε²/m²). With k = 0, P stays P0 I and ẋ = t_x: the paper's law. Without
        P on the tracking term its bias (the tracking error also carries the model errors of θ̂
        and of the observer) pulled β̂ away again once P had shrunk (−0.5 % at 2 s, −6.7 % at 10 s
        on leg 3 of paper-sim)."""
        m, k = self.c.m, triangle_size(2)
        x_dots, _ = self._least_squares()
        tracking = [sp.Matrix(sp.symbols(f"gamma{j}_tracking0:{m}", real=True)) for j in (1, 2)]
        self.stages += [(tracking[0], sp.Matrix(t1)), (tracking[1], sp.Matrix(t2))]
        t1, t2 = list(tracking[0]), list(tracking[1])
        # P_jj / P0 bound first: at P = P0 I it is exactly 1 for any P0 (a product P_jj t / P0 would
        # round), so the law is exactly the paper's, as its lean variant computes
        ratio = sp.Matrix(sp.symbols(f"gamma_gain_ratio0:{2 * m}", real=True))
        self.stages.append((ratio, sp.Matrix([self.P[k * i + (0, 2)[j]] / self.P0 for i in range(m) for j in (0, 1)])))
        r1, r2 = [], []
        for i in range(m):
            ref = [self.ref[i], self.ref[m + i]]
            P = unpack_symmetric(self.P[k * i:k * (i + 1)], 2)
            tx = [t1[i] / ref[0], t2[i] / ref[1]]
            x_dot = x_dots[i]
            # diagonal written apart so that P = P0 I gives back t exactly (no rounding through γ_ref)
            r1.append(ratio[2 * i] * t1[i] + ref[0] * (P[0, 1] / self.P0 * tx[1] + x_dot[0]))
            r2.append(ratio[2 * i + 1] * t2[i] + ref[1] * (P[1, 0] / self.P0 * tx[0] + x_dot[1]))
        self.stages += [(self.r1, sp.Matrix(r1)), (self.r2, sp.Matrix(r2))]
        return list(self.r1), list(self.r2)

    def _least_squares(self):
        """Per cylinder (ẋ_c, Ṗ packed), computed once; their intermediates join :attr:`stages`."""
        if self._ls is None:
            c, m, k = self.c, self.c.m, triangle_size(2)
            W1, W2, _ = self.regressor_and_output()
            eps = self.prediction_error()
            self._ls = ([], [])
            for i in range(m):
                scale = c.force_scale(i)
                W = sp.Matrix([[self.ref[i] * W1[i] / scale, self.ref[m + i] * W2[i] / scale]])
                x_dot, Pd, st = staged_least_squares(W, [eps[i]], self.P[k * i:k * (i + 1)], self.rate,
                                                     self.floor, self.nu, f"ls_gamma{i}")
                self._ls[0].append(x_dot)
                self._ls[1].append(Pd)
                self.stages += st
        return self._ls

    def rates(self, adapt):
        """Rates of the states in :meth:`states` order. The filters run whether adaptation is on or
        not; P moves only while it is on."""
        c, m, lam = self.c, self.c.m, self.lam
        P_dot = [adapt * x for Pd in self._least_squares()[1] for x in Pd]
        lnL = self._log_chamber()
        rates = [*(lam * (c.f[i] - self.phi_f[i]) for i in range(m)),
                 *(lam * (lnL[i] - self.phi_L[i]) for i in range(m)),
                 *(lam * (self.gbar[i] - self.omega[i]) for i in range(m)),
                 # copies: x_prev ← x in one period
                 *((c.pc[j] - self.pc_prev[j]) / self.h for j in range(len(c.pc))),
                 *((c.l[i] - self.l_prev[i]) / self.h for i in range(m)),
                 *P_dot]
        return rates


def _units(p):
    """The p unit parameter vectors (exact SymPy integers)."""
    return [[sp.S.One if i == k else sp.S.Zero for i in range(p)] for k in range(p)]


class RigidBodyComposite:
    """Composite adaptation of the rigid-body parameters θ, in the momentum form (no q̈ needed).

    τ = d/dt(D q̇) + G − Cᵀ q̇ with (Cᵀ q̇)_i = ½ q̇ᵀ (∂D/∂q_i) q̇ (Christoffel C: Ḋ = C + Cᵀ), both
    affine in θ: D q̇ = Y_p θ + p0 and G − Cᵀ q̇ = Y_b θ + b0, p0 and b0 the non-adapted
    parameters' share. Y_p and Y_b are derived here from D(q, θ) and G(q, θ) at unit parameter
    vectors (``mass_matrix``, ``gravity``), Cᵀ q̇ as ∂/∂q of the kinetic energy ½ q̇ᵀ D q̇. Through
    λ_f/(s + λ_f): τ_f = λ_f (Y_p − ξ) θ + ζ θ + λ_f (p0 − ξ0) + ζ0, ξ, ξ0, ζ, ζ0 the filter states
    of Y_p, p0, Y_b, b0, and τ = (JL)ᵀ f from the measured pressures. As for γ, the exact derivative
    λ_f (Y_p − ξ) pairs the filter state before this period's update with the sampled signals'
    filters after it (ζ + h λ_f (Y_b − ζ), …), so the true θ leaves the rectangle rule's residual
    of ∫ ṗ only. Normalisation: x = θ̂/θ_ref, row i divided by the inertia scale of coordinate i
    (``theta_row_scale``), so W and ε are accelerations (m/s², rad/s²) per unit x.
    """

    def __init__(self, common, th_hat):
        c = self.c = common
        n, p = c.n, c.p
        self.th_hat = th_hat
        sym = lambda name, r, k=1: sp.Matrix(r, k, sp.symbols(f"{name}0:{r * k}", real=True))  # noqa: E731
        self.xi, self.xi0 = sym("momentum_filter", n, p), sym("momentum_offset_filter", n)
        self.zeta, self.zeta0 = sym("bias_filter", n, p), sym("bias_offset_filter", n)
        self.tau_f = sym("torque_filter", n)
        self.P = sym("theta_gain", triangle_size(p))
        self.ref, self.row = sym("theta_ref", p), sym("theta_row_scale", n)
        self.lam, self.rate, self.P0, self.nu = sp.symbols("lambda_f_theta rate_ls_theta P0_theta ls_nu_theta",
                                                           real=True)
        self.floor, self.h = sp.symbols("ls_floor period", real=True)  # shared with the γ law
        # intermediates: Y_p, Y_b, p0, b0 and the rates of θ̂ before the projection
        self.Yp, self.Yb, self.p0, self.b0 = sym("Yp", n, p), sym("Yb", n, p), sym("p0", n), sym("b0", n)
        self.rho = sym("theta_rate", p)
        self.stages = []
        self._ls = None

    BLOCKS = COMPOSITE_BLOCKS[6:]  # the θ law's blocks of composite_layout

    def states(self) -> list:
        return [*self.xi, *self.xi0, *self.zeta, *self.zeta0, *self.tau_f, *self.P]

    def inputs(self) -> list:
        return [("theta_ref", self.ref), ("theta_row_scale", self.row), ("lambda_f_theta", sp.Matrix([self.lam])),
                ("rate_ls_theta", sp.Matrix([self.rate])), ("P0_theta", sp.Matrix([self.P0])),
                ("ls_nu_theta", sp.Matrix([self.nu]))]

    def signals(self):
        """(Y_p, p0, Y_b, b0) as expressions of q, q̇ (and, on a staged tree, its link-pose symbols)."""
        from ..symbolic.rigid_body import rigid_body_stages

        if rigid_body_stages(self.c.model, self.c.q):
            return self._staged_signals()
        return self._closed_form_signals()

    def _staged_signals(self):
        """A staged tree's D holds link-pose symbols, not q, so ∂/∂q of it would miss the poses'
        dependence on q. From the tree's own Newton-Euler regressor instead, in a few passes:
        D q̇ = Y(q, 0, 0, q̇) − Y(q, 0, 0, 0), C q̇ + G = Y(q, q̇, q̇, 0), and Cᵀ q̇ = Ḋ q̇ − C q̇
        (Ḋ = C + Cᵀ) with Ḋ q̇ the forward-mode time derivative of D q̇ through q and the poses,
        q̇ held (the same quantities as the closed form's, tested)."""
        from ..symbolic.calculus import time_derivative
        from ..symbolic.rigid_body import regressor, regressor_offset

        c = self.c
        q, qd, th = c.q, c.qdot, self.th_hat
        zero = sp.zeros(c.n, 1)
        Y = lambda v, w, a: regressor(c.model, q, v, w, a, th)  # noqa: E731
        y0 = lambda v, w, a: regressor_offset(c.model, q, v, w, a, th)  # noqa: E731
        Yp, p0 = Y(zero, zero, qd) - Y(zero, zero, zero), y0(zero, zero, qd) - y0(zero, zero, zero)
        # q̇ inside D q̇ has no rate listed: held, so d/dt gives Ḋ q̇
        rates = [(q, qd), *c.pose_rates]
        Ddot_Yp = time_derivative(Yp.reshape(c.n * c.p, 1), rates).reshape(c.n, c.p)
        Yb = Y(qd, qd, zero) - Ddot_Yp
        b0 = y0(qd, qd, zero) - time_derivative(sp.Matrix(p0), rates)
        return Yp, p0, Yb, b0

    def _closed_form_signals(self):
        from ..symbolic.calculus import diff, jacobian
        from ..symbolic.forms import turned_joints
        from ..symbolic.rigid_body import gravity, mass_matrix

        c, n, p = self.c, self.c.n, self.c.p
        q, qd = c.q, c.qdot
        if turned_joints(c.model):
            # Full rotations (of symbols, with the numbers as inputs): expanding D once per θ entry
            # does not end in minutes; D(θ) q̇ and G(θ) are linear in θ, so their Jacobians in θ are
            # the same columns without expanding anything.
            th = sp.Matrix(sp.symbols(f"composite_theta0:{p}", real=True))
            at_zero = {s: sp.S.Zero for s in th}
            mom, G = mass_matrix(c.model, q, th) * qd, gravity(c.model, q, th)
            p0, G0 = mom.xreplace(at_zero), G.xreplace(at_zero)  # subs would also match patterns, slowly
            Yp, YG = jacobian(mom, th), jacobian(G, th)
        else:
            zero = [sp.S.Zero] * p
            D0, G0 = mass_matrix(c.model, q, zero), gravity(c.model, q, zero)
            p0 = D0 * qd
            Yp_cols, YG_cols = [], []
            for k, unit in enumerate(_units(p)):
                Yp_cols.append(sp.expand(mass_matrix(c.model, q, unit) * qd - p0))
                YG_cols.append(sp.expand(gravity(c.model, q, unit) - G0))
            Yp = sp.Matrix.hstack(*Yp_cols)
            YG = sp.Matrix.hstack(*YG_cols)

        memos = [{} for _ in range(n)]  # ∂/∂q_i of the nodes the columns share, made once

        def half_dT(mom):  # (Cᵀ q̇)_i = ∂/∂q_i of ½ q̇ᵀ (D q̇)
            T = sp.Rational(1, 2) * (qd.T * mom)[0, 0]
            return sp.Matrix([diff(T, q[i], memos[i]) for i in range(n)])
        Yb = sp.Matrix.hstack(*[YG[:, k] - half_dT(Yp[:, k]) for k in range(p)])
        b0 = G0 - half_dT(p0)
        return Yp, p0, Yb, b0

    def _filtered(self):
        """(W (n×p), w0 (n), τ_f (n)), unnormalised: τ_f ≈ W θ + w0."""
        lam, h = self.lam, self.h
        W = lam * (self.Yp - self.xi) + self.zeta + h * lam * (self.Yb - self.zeta)
        w0 = lam * (self.p0 - self.xi0) + self.zeta0 + h * lam * (self.b0 - self.zeta0)
        tau = self.c.JL.T * self.c.f
        return W, w0, self.tau_f + h * lam * (tau - self.tau_f)

    def prediction_error(self) -> sp.Matrix:
        """ε (n) in N or N m: W θ̂ + w0 − τ_f."""
        from ..symbolic.calculus import matmul

        W, w0, tf = self._filtered()
        return matmul(W, self.th_hat) + w0 - tf

    def combine(self, rho):
        """θ̂'s rate before the projection from the paper's tracking term ``rho`` (p):
        x_ref ⊙ [(P/P0) (ρ/x_ref) − k P W_nᵀ ε_n / m²], as for γ (k = 0: P = P0 I, ρ exactly)."""
        p = self.c.p
        x_dot, _ = self._least_squares()
        tracking = sp.Matrix(sp.symbols(f"theta_tracking0:{p}", real=True))  # ρ once, not p times
        self.stages.append((tracking, sp.Matrix(rho)))
        rho = tracking
        P = unpack_symmetric(self.P, p)
        ratio = sp.Matrix(sp.symbols(f"theta_gain_ratio0:{p}", real=True))  # P_ii / P0: exactly 1 at P0 I
        self.stages.append((ratio, sp.Matrix([P[i, i] / self.P0 for i in range(p)])))
        out = []
        for i in range(p):
            cross = sum((P[i, j] / self.P0 * rho[j] / self.ref[j] for j in range(p) if j != i), sp.S.Zero)
            out.append(ratio[i] * rho[i] + self.ref[i] * (cross + x_dot[i]))
        self.stages.append((self.rho, sp.Matrix(out)))
        return self.rho

    def _least_squares(self):
        """(ẋ_c, Ṗ packed), computed once; Y_p, Y_b, p0, b0 and the least squares' pieces join
        :attr:`stages`."""
        if self._ls is None:
            n, p = self.c.n, self.c.p
            Yp, p0, Yb, b0 = self.signals()
            self.stages += [(self.Yp, Yp), (self.p0, p0), (self.Yb, Yb), (self.b0, b0)]
            W, _, _ = self._filtered()
            eps = self.prediction_error()
            Wn = sp.Matrix(n, p, lambda i, k: W[i, k] * self.ref[k] / self.row[i])
            en = [eps[i] / self.row[i] for i in range(n)]
            x_dot, Pd, st = staged_least_squares(Wn, en, self.P, self.rate, self.floor, self.nu, "ls_theta")
            self.stages += st
            self._ls = (x_dot, Pd)
        return self._ls

    def rates(self, adapt) -> list:
        """Rates of the states in :meth:`states` order (after :meth:`combine`)."""
        c, lam = self.c, self.lam
        Pd = self._least_squares()[1]
        tau = c.JL.T * c.f
        return [*(lam * (self.Yp - self.xi)), *(lam * (self.p0 - self.xi0)), *(lam * (self.Yb - self.zeta)),
                *(lam * (self.b0 - self.zeta0)), *(lam * (tau - self.tau_f)), *(adapt * x for x in Pd)]
