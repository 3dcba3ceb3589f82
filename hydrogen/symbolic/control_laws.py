"""Building blocks shared by the paper's controllers (SymPy), in cylinder-force form.

Joint-space (or task-space) design, cylinder-space actuation (READING-NOTES "Leg forces and task
space"): τ_d (generalized forces) maps to cylinder forces f_d = (JL)⁻ᵀ τ_d, with
ḟ_d = (JL)⁻ᵀ (τ̇_d − d/dt[(JL)ᵀ] f_d), and the backstepping term reads Γ_τ⁻¹ (JL) s. The spool
position u solves g0(u) γ̂2 = v per cylinder, with

    v = ḟ_d − f0 γ̂1 − Γ_τ⁻¹ JL s − K_τ f̃,   f̃ = f − f_d,

so the force error obeys ḟ̃ = −Γ_τ⁻¹ JL s − K_τ f̃ (+ parameter-error terms). (JL)⁻ᵀ is an
intermediate computed numerically (CasADi linear solve); every other quantity, including τ̇_d,
is derived in closed form. Sizes come from the model: n coordinates, m = n cylinders, p adapted
parameters. Each controller is one module of :mod:`hydrogen.controllers`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from ..actuators import actuator, baked_parameters
from ..plant.supply import PRESSURE
from ..pressures import blocks, n_pressures
from .calculus import clip, matmul, projection
from .constants import PRESSURE_EPS, baked
from .kinematics import leg_intermediates, matrix_symbols, pose_rates, pose_symbols, rate_symbols
from .rigid_body import (coriolis_matrix, gravity, inverse_dynamics, mass_matrix, mass_matrix_inverse, regressor,
                         rigid_body_stages, theta_symbols)

__all__ = ["ControllerParts", "Common", "diag", "vector", "scalar", "solve_or_inverse", "state_and_rates"]


@dataclass
class ControllerParts:
    """Inputs, intermediates (symbols defined numerically, in order) and outputs of a controller."""

    inputs: list
    outputs: list
    intermediates: list = field(default_factory=list)


def diag(v):
    return sp.diag(*list(v))


def vector(name, n):
    return rate_symbols(name, n)


def scalar(name):
    return sp.Symbol(name, real=True)


def state_and_rates(layout, parts):
    """The state xc and its rate xc_dot (column matrices) in the order the controller's
    ``state_layout`` declares, from ``parts`` = [(block name or names, states, rates)]; the blocks
    must be the layout's, in its order and of its sizes (a mismatch is an error at generation)."""
    names, xs, rs, sizes = [], [], [], dict(layout)
    for blocks, x, r in parts:
        blocks = (blocks,) if isinstance(blocks, str) else tuple(blocks)
        x, r = list(x), list(r)
        if len(x) != len(r) or len(x) != sum(sizes.get(b, -1) for b in blocks):
            raise ValueError(f"state blocks {list(blocks)}: {len(x)} states and {len(r)} rates, the layout "
                             f"declares {[sizes.get(b) for b in blocks]}")
        names += blocks
        xs += x
        rs += r
    if names != [b for b, _ in layout]:
        raise ValueError(f"state blocks {names} are not the declared layout {[b for b, _ in layout]}")
    return sp.Matrix(xs), sp.Matrix(rs)


def solve_or_inverse(model, q, theta, rhs, name):
    """D(q, θ)⁻¹ rhs: the closed form where the tree has one, else an intermediate symbol vector
    defined by a numeric linear solve. Returns (value, intermediates)."""
    Dinv = mass_matrix_inverse(model, q, theta)
    if Dinv is not None:
        return Dinv * rhs, []
    x = vector(name, len(rhs))
    return x, [(x, ("solve", mass_matrix(model, q, theta), rhs))]


class Common:
    """Symbols and expressions shared by the model-based controllers."""

    def __init__(self, model):
        self.model = model
        n, m = model.n, model.n_cylinders
        self.n, self.m, self.p = n, m, model.n_theta
        #: each cylinder's actuator kind, its laws (SymPy) and its parameters (baked SymPy numbers), by name
        self.kinds = [x.kind for x in model.cylinders]
        self.laws = [actuator(x.kind).Symbolic for x in model.cylinders]
        self.P = [baked_parameters(x) for x in model.cylinders]
        #: the measured supply pressure (Pa), an input, where the supply is a plant state (a pump): every
        #: law (force, f0, g0, valve inverse, normalisation) takes it in place of supply_pressure
        self.supply = None if model.supply.constant else vector(PRESSURE, 1)
        if self.supply is not None:
            self.P = [{**P, "supply_pressure": self.supply[0]} for P in self.P]
        self.ps = [P["supply_pressure"] for P in self.P]
        # the three-way cylinder's A and L (None for another kind)
        self.A = [P.get("piston_area") for P in self.P]
        self.L = [P.get("chamber_length") for P in self.P]
        self.g = baked(model.gravity, "gravity")
        # pc: the pressure vector, one block per actuator (hydrogen.pressures); pb[i] cylinder i's block
        self.q, self.qdot, self.pc = pose_symbols(model), vector("qdot", n), vector("pc", n_pressures(model))
        self.pb = [tuple(self.pc[a:b]) for a, b in blocks(model)]
        self.qd = [vector(f"qd{k}", n) for k in range(4)]  # q_d and its first three derivatives
        self.Lam, self.Kp, self.Kd = vector("Lambda", n), vector("Kp", n), vector("Kd", n)
        self.Ktau, self.Gtau_inv = vector("Ktau", m), vector("Gtau_inv", m)
        self.u_max = scalar("u_max")
        self.l, self.JL, self.JLdot, self.kin = leg_intermediates(model, self.q, self.qdot)
        # (R, Ṙ), (p, ṗ) of the link poses in kin, which D, C, G, Y of a staged tree hold: time_derivative needs them
        self.pose_rates = pose_rates(model, self.q, self.qdot)
        self.staged = bool(rigid_body_stages(model, self.q))
        self.ldot = self.JL * self.qdot
        self.f = sp.Matrix([self.laws[i].force(self.pb[i], self.P[i]) for i in range(m)])
        self.Jit = matrix_symbols("JLinvT", n, m)
        self.e = self.q - self.qd[0]
        # The spool commands (m) the valves held over the period the state update integrates (the
        # loop's u_applied: after the clip and the computation delay), the γ̂2 law's input.
        self.u_applied = vector("u_applied", m)
        self.u_applied_declared = False  # set by adaptive_inputs, which makes u_applied an input

    def theta(self, prefix="theta_hat"):
        return vector(prefix, self.p)

    def D(self, theta):
        return mass_matrix(self.model, self.q, theta)

    def C(self, theta, v):
        return coriolis_matrix(self.model, self.q, v, theta)

    def G(self, theta):
        return gravity(self.model, self.q, theta)

    def dynamics(self, theta, v, w, a=None):
        """D(q, θ) a + C(q, θ, v) w + G(q, θ) (n; no D a term when ``a`` is None): one Newton-Euler
        pass on a staged tree, where the products of the n×n D and C with vectors cost SymPy most of
        a controller's derivation; the same expression as the products on the closed form."""
        if not self.staged:
            out = matmul(self.C(theta, v), w) + self.G(theta)
            return out if a is None else matmul(self.D(theta), a) + out
        return inverse_dynamics(self.model, self.q, v, w, sp.zeros(self.n, 1) if a is None else a, theta)

    def Y(self, v, w, a, theta):
        return regressor(self.model, self.q, v, w, a, theta)

    def desired_rates(self):
        return [(self.qd[k], self.qd[k + 1]) for k in range(3)]

    def force_loop(self, tau_d, tau_d_dot, s, g1, g2, friction=None):
        """Stages of the cylinder-force loop as intermediates; returns (f_d, f̃, f0, v, u, τ_d, stages).

        Each stage is bound to symbols so later stages (and τ̇_d's users) refer to
        a symbol, not to a copy of a large expression. ``friction``: (f_fr, ḟ_fr, stages) of
        :meth:`friction_compensation`, added to f_d and ḟ_d (None: the paper's f_d).
        """
        n, m = self.n, self.m
        S = {k: vector(k, n) for k in ("taud", "taud_dot")}
        S.update({k: vector(k, m) for k in ("fd", "fd_rb", "fd_dot", "v", "u_raw", "u_cmd", "g0_app")})
        stages = [
            (S["taud"], tau_d),
            (S["taud_dot"], tau_d_dot),
        ]
        if friction is None:
            stages += [(S["fd"], self.Jit * S["taud"]),
                       (S["fd_dot"], self.Jit * (S["taud_dot"] - self.JLdot.T * S["fd"]))]
        else:
            # the rigid-body part first, as the paper's f_d, then the compensation added: with its
            # coefficients 0 the sums add exact zeros, so f_d and ḟ_d are the paper's to the bit
            f_fr, f_fr_dot, fr_stages = friction
            stages += [*fr_stages, (S["fd_rb"], self.Jit * S["taud"]), (S["fd"], S["fd_rb"] + f_fr),
                       (S["fd_dot"], self.Jit * (S["taud_dot"] - self.JLdot.T * S["fd_rb"]) + f_fr_dot)]
        ftil = self.f - S["fd"]
        f0 = sp.Matrix([self.laws[i].f0(self.l[i], self.ldot[i], self.pb[i], self.P[i]) for i in range(m)])
        Js = self.JL * s
        stages.append((S["v"], sp.Matrix([S["fd_dot"][i] - f0[i] * g1[i] - self.Gtau_inv[i] * Js[i]
                                          - self.Ktau[i] * ftil[i] for i in range(m)])))
        # g0 γ̂2 = v: the spool with g0 = v / γ̂2 (the valve inverse, on every branch)
        stages.append((S["u_raw"], sp.Matrix([self.laws[i].valve_inverse(S["v"][i] / g2[i], self.l[i], self.pb[i],
                                                                         self.P[i], PRESSURE_EPS) for i in range(m)])))
        stages.append((S["u_cmd"], sp.Matrix([clip(S["u_raw"][i], -self.u_max, self.u_max) for i in range(m)])))
        u = S["u_cmd"]
        # g0 of (59) at the spool the valves received (the input u_applied, not this call's u): the
        # γ̂2 law's regressor (hydraulic_adaptation). It does not depend on u, so a function with the
        # state rates as its only output needs neither τ̇_d nor the valve inverse. A stage (so the
        # projection's conditions refer to a symbol), made only where u_applied is an input.
        self.g0_applied = None
        if self.u_applied_declared:
            ua = self.u_applied
            stages.append((S["g0_app"], sp.Matrix([self.g0(i, self.l[i], self.pb[i], ua[i]) for i in range(m)])))
            self.g0_applied = S["g0_app"]
        self.taud_dot = S["taud_dot"]
        return S["fd"], ftil, f0, S["v"], u, S["taud"], stages

    def friction_compensation(self, qr_dot, qr_ddot, s, estimates=None, adapt=None):
        """Friction compensation in actuator space (a deviation from the paper, docs/paper.md):
        f_fr = F_c tanh(l̇_r / v_s) + b l̇_r per actuator at the reference velocity l̇_r = JL q̇_r, and
        ḟ_fr with l̈_r = J̇L q̇_r + JL q̈_r (``qr_ddot`` the exact rate of ``qr_dot``: no measured q̈).

        The reference velocity, not the measured one: ḟ_d then needs no acceleration, and the
        mismatch with the plant's friction at l̇, (l̇ − l̇_r)(f(l̇_r) − f(l̇)) = (JL s)ᵀ(…) ≤ 0
        (f increasing), is dissipative in V̇ (Slotine and Li's regressor at q̇_r).

        ``estimates`` None: the known coefficients, inputs ``friction_coulomb``,
        ``friction_viscous``; else the state symbols (F̂_c, b̂), adapted with
        F̂̇_c = −κ Γ_c tanh(l̇_r/v_s) (JL s), b̂̇ = −κ Γ_b l̇_r (JL s) (Γ = ``rate_friction`` × the
        upper bound², projected onto [0, bound]), which cancels (JL s)ᵀ φᵀ c̃ in V̇ against
        ½ c̃ᵀ Γ⁻¹ c̃; ``adapt`` the switch κ. Returns ((f_fr, ḟ_fr, stages) for :meth:`force_loop`,
        the estimates' rates (2m, or None), the inputs); (None, None, []) for a model generated
        without it (``[control] friction_compensation`` false, the default)."""
        if not self.model.friction_compensation:  # generated without it: the paper's f_d
            return None, None, []
        m = self.m
        vs = vector("friction_speed", m)
        S = {k: vector(k, m) for k in ("ldot_r", "lddot_r", "fric_sign")}
        stages = [(S["ldot_r"], self.JL * qr_dot), (S["lddot_r"], self.JLdot * qr_dot + self.JL * qr_ddot),
                  (S["fric_sign"], sp.Matrix([sp.tanh(S["ldot_r"][i] / vs[i]) for i in range(m)]))]
        ld, ldd, sgn = S["ldot_r"], S["lddot_r"], S["fric_sign"]
        if estimates is None:
            Fc, Fv = vector("friction_coulomb", m), vector("friction_viscous", m)
            Fc_dot = Fv_dot = sp.zeros(m, 1)
            inputs = [("friction_coulomb", Fc), ("friction_viscous", Fv), ("friction_speed", vs)]
            rates = None
        else:
            Fc, Fv = estimates
            rate = scalar("rate_friction")
            c_max, v_max = vector("friction_coulomb_max", m), vector("friction_viscous_max", m)
            Js = self.JL * s
            rates = sp.Matrix([adapt * projection(Fc[i], -rate * c_max[i] ** 2 * sgn[i] * Js[i], 0, c_max[i])
                               for i in range(m)]
                              + [adapt * projection(Fv[i], -rate * v_max[i] ** 2 * ld[i] * Js[i], 0, v_max[i])
                                 for i in range(m)])
            rate_sym = vector("fric_rate", 2 * m)
            stages.append((rate_sym, rates))
            Fc_dot, Fv_dot = rate_sym[:m, :], rate_sym[m:, :]
            rates = rate_sym
            inputs = [("friction_speed", vs), ("rate_friction", sp.Matrix([rate])),
                      ("friction_coulomb_max", c_max), ("friction_viscous_max", v_max)]
        f = sp.Matrix([Fc[i] * sgn[i] + Fv[i] * ld[i] for i in range(m)])
        f_dot = sp.Matrix([Fc_dot[i] * sgn[i] + Fc[i] * (1 - sgn[i] ** 2) * ldd[i] / vs[i]
                           + Fv_dot[i] * ld[i] + Fv[i] * ldd[i] for i in range(m)])
        return (f, f_dot, stages), rates, inputs

    def g0(self, i, l, p, u):
        """g0 of (59) (its kind's) for cylinder ``i`` at its pressure block ``p`` (a tuple) as the
        controllers evaluate it: the pressure drops clipped at 0 (a noisy measured p_c above p_s must
        not take the root of a negative number), the roots shared with the valve inverse; inside
        [0, p_s] exactly (59)."""
        return self.laws[i].g0(l, p, u, self.P[i])

    def force_scale(self, i):
        """Cylinder ``i``'s force range (N): P_s A for a three-way cylinder, the width of its
        ``force_range`` for another kind; the composite law's row normalisation."""
        if self.A[i] is not None and self.L[i] is not None:
            return self.ps[i] * self.A[i]
        lo, hi = self.laws[i].force_range(self.P[i])
        return hi - lo

    def f0_potential(self, i):
        """(k, Φ_i): f0 of cylinder ``i`` is k dΦ_i/dt. A three-way cylinder: k = −A, Φ = ln(l − L);
        another kind: k = 1, Φ its ``f0_potential``."""
        if self.A[i] is not None and self.L[i] is not None:
            return -self.A[i], sp.log(self.l[i] - self.L[i])
        return sp.S.One, self.laws[i].f0_potential(self.l[i], self.P[i])

    def jit_intermediate(self):
        return (self.Jit, ("inverse", self.JL.T))

    def hydraulic_adaptation(self, ftil, f0, u, g1, g2, adapt, Gg1_inv, Gg2_inv, g1_lo, g1_hi, g2_lo, g2_hi,
                             combine=None):
        """γ̂̇1 = κ Γ_γ1⁻¹ Γ_τ f0 f̃,  γ̂̇2 = κ Γ_γ2⁻¹ Γ_τ g0(u_applied) f̃ (per cylinder, projected).

        The paper's γ̂2 law has Π(f̃/γ̂2) v, i.e. the regressor v/γ̂2 = g0(u) of this period's
        commanded spool; here g0 is evaluated at the spool command the valves actually received over
        the period the state update integrates (the input ``u_applied``: clipped to ±u_max, and
        delayed by the loop's computation delay), which is the regressor of γ̃2 in the force-error
        equation ḟ̃ = … + f0 γ̃1 + g0(u_applied) γ̃2 also when the valve saturates or the command
        arrives late (docs/paper.md "Deviations from the paper, declared"). ``u`` (this call's command) is not used.

        ``combine(t1, t2) -> (r1, r2)`` turns the tracking terms (lists per cylinder) into the
        rates that go through the projection (the composite adaptation,
        :class:`hydrogen.controllers.composite.HydraulicComposite`); None keeps the paper's law."""
        m = self.m
        g0 = self.g0_applied  # bound by force_loop to g0(u_applied), the spool the valves received
        t1 = [Gg1_inv[i] / self.Gtau_inv[i] * f0[i] * ftil[i] for i in range(m)]
        t2 = [Gg2_inv[i] / self.Gtau_inv[i] * ftil[i] * g0[i] for i in range(m)]
        if combine is not None:
            t1, t2 = combine(t1, t2)
        g1_dot = sp.Matrix([adapt * projection(g1[i], t1[i], g1_lo, g1_hi) for i in range(m)])
        g2_dot = sp.Matrix([adapt * projection(g2[i], t2[i], g2_lo, g2_hi) for i in range(m)])
        return g1_dot, g2_dot

    def adaptive_inputs(self):
        """Adaptation gains and projection bounds, the switch ``adapt`` and the applied spool commands
        ``u_applied`` (m): (vectors, scalars, input list)."""
        p, m = self.p, self.m
        names = ("Gtheta_inv", p), ("Ggamma1_inv", m), ("Ggamma2_inv", m), ("theta_min", p), ("theta_max", p)
        vecs = {k: vector(k, size) for k, size in names}
        scal = {k: scalar(k) for k in ("gamma1_min", "gamma1_max", "gamma2_min", "gamma2_max", "adapt")}
        # u_applied is a loop signal (like adapt), listed here because only the adaptation needs it.
        inputs = [(k, vecs[k]) for k, _ in names] + [(k, sp.Matrix([scal[k]])) for k in scal] \
            + [("u_applied", self.u_applied)]
        self.u_applied_declared = True
        return vecs, scal, inputs

    def theta_rate(self, rho, th_hat, vecs, adapt):
        return sp.Matrix([adapt * projection(th_hat[k], rho[k], vecs["theta_min"][k], vecs["theta_max"][k])
                          for k in range(self.p)])

    def base_inputs(self):
        return [("q", self.q), ("qdot", self.qdot), ("pc", self.pc),
                *[(f"qd{k}", self.qd[k]) for k in range(4)],
                *([(PRESSURE, self.supply)] if self.supply is not None else [])]

    def gain_inputs(self):
        return [("Lambda", self.Lam), ("Kp", self.Kp), ("Kd", self.Kd), ("Ktau", self.Ktau),
                ("Gtau_inv", self.Gtau_inv), ("u_max", sp.Matrix([self.u_max]))]


def rigid_theta(model):
    """The symbols of the true θ (backstepping's known parameters)."""
    return theta_symbols(model)
