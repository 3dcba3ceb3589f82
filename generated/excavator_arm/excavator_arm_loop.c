/* Closed-loop driver for model excavator_arm (see excavator_arm_loop.h).
 * Rendered by hydrogen from templates/loop.c.j2; plain C99, no dependency but libm.
 * One control period is the stages declared in the header, in this order: measure (noise,
 * quantisation), estimate (the rates' estimator where one is selected, joint encoders, velocities), reference, control
 * (controller state update and command, the command of delay periods ago), the logs, plant step (RK4
 * sub-steps, zero-order hold), control advance (forward-Euler state update). */
#include <math.h>
#include <string.h>

#include "excavator_arm_loop.h"
#include "excavator_arm_leg_lengths.h"
#include "excavator_arm_leg_kinematics.h"
#include "excavator_arm_plant_rhs.h"
#include "excavator_arm_leg_force.h"

#define NQ EXCAVATOR_ARM_NQ
#define NL EXCAVATOR_ARM_NL
#define NX EXCAVATOR_ARM_NX
#define NNOISE EXCAVATOR_ARM_NNOISE
#define NOISE_L 0  /* the noise row's actuator travel: 3 from here */
#define NOISE_PC 3  /* the noise row's pressure states: 6 from here */
#define NOISE_Q 9  /* the noise row's joint encoders: 3 from here */
#define NOISE_PS 12  /* the noise row's supply pressure: 1 from here */
#define MAX_DELAY EXCAVATOR_ARM_MAX_DELAY
static const double TWO_PI = 6.283185307179586;
#define NPC EXCAVATOR_ARM_NPC
#define NPS EXCAVATOR_ARM_NPS

/* actuator forces (N, N m) from the pressure vector and the supply pressure: the actuators' own laws */
static int leg_force(const double* nb, const double* p, const double* ps, double* f) {
    const double* arg[3];
    double* res[1];
    arg[0] = p;
    arg[1] = ps;
    arg[2] = nb;  /* the description's numbers (their last input), unless folded */
    res[0] = f;
    return excavator_arm_leg_force(arg, res, 0, 0, 0);
}

static int leg_lengths(const double* nb, const double* q, double* l) {
    const double* arg[2];
    double* res[1];
    arg[0] = q;
    arg[1] = nb;  /* the description's numbers (their last input), unless folded */
    res[0] = l;
    return excavator_arm_leg_lengths(arg, res, 0, 0, 0);
}

int excavator_arm_leg_lengths_many(const double* numbers, const double* q, long long n, double* l) {
    long long k;
    for (k = 0; k < n; ++k)
        if (leg_lengths(numbers, q + NQ * k, l + NL * k)) return 1;
    return 0;
}

/* cylinder lengths and JL (column-major NL x NQ) in one call: they share the link poses */
static int leg_kinematics(const double* nb, const double* q, double* l, double* J) {
    const double* arg[2];
    double* res[2];
    arg[0] = q;
    arg[1] = nb;  /* the description's numbers (their last input), unless folded */
    res[0] = l;
    res[1] = J;
    return excavator_arm_leg_kinematics(arg, res, 0, 0, 0);
}

/* LU factorisation of A (column-major NQ x NQ, overwritten by its factors: the multipliers below the
 * diagonal) with partial pivoting, the row swaps in piv; returns 0 if a pivot is not above
 * 1e-12 (hydrogen.layout.LU_PIVOT_MIN). */
static int lu_n(double* A, int* piv) {
    int i, j, k, p;
    double m, tmp;
    for (k = 0; k < NQ; ++k) {
        p = k;
        for (i = k + 1; i < NQ; ++i)
            if (fabs(A[i + NQ * k]) > fabs(A[p + NQ * k])) p = i;
        if (!(fabs(A[p + NQ * k]) > 1e-12)) return 0;
        piv[k] = p;
        if (p != k)
            for (j = 0; j < NQ; ++j) {
                tmp = A[k + NQ * j]; A[k + NQ * j] = A[p + NQ * j]; A[p + NQ * j] = tmp;
            }
        for (i = k + 1; i < NQ; ++i) {
            m = A[i + NQ * k] / A[k + NQ * k];
            for (j = k + 1; j < NQ; ++j) A[i + NQ * j] -= m * A[k + NQ * j];
            A[i + NQ * k] = m;
        }
    }
    return 1;
}

/* Solve A x = b in place (b becomes x) from lu_n's factors of A: every row swap first (the multipliers
 * moved with their rows), then the triangular solves. */
static void lu_solve(const double* A, const int* piv, double* b) {
    int i, j, k;
    double tmp;
    for (k = 0; k < NQ; ++k)
        if (piv[k] != k) {
            tmp = b[k]; b[k] = b[piv[k]]; b[piv[k]] = tmp;
        }
    for (k = 0; k < NQ; ++k)
        for (i = k + 1; i < NQ; ++i) b[i] -= A[i + NQ * k] * b[k];
    for (k = NQ - 1; k >= 0; --k) {
        for (j = k + 1; j < NQ; ++j) b[k] -= A[k + NQ * j] * b[j];
        b[k] /= A[k + NQ * k];
    }
}

/* Solve A x = b (A column-major NQ x NQ, overwritten), partial pivoting; returns 0 if singular. */
static int solve_n(double* A, double* b) {
    int piv[NQ];
    if (!lu_n(A, piv)) return 0;
    lu_solve(A, piv, b);
    return 1;
}

/* The largest column sum of |A| (A column-major NQ x NQ): its 1-norm. */
static double norm_1(const double* A) {
    double s, norm = 0;
    int i, j;
    for (j = 0; j < NQ; ++j) {
        s = 0;
        for (i = 0; i < NQ; ++i) s += fabs(A[i + NQ * j]);
        if (!(s <= norm)) norm = s;  /* NaN propagates */
    }
    return norm;
}

/* ||A^-1||_1 from lu_n's factors of A: one solve per column of the inverse. */
static double inverse_norm_1(const double* LU, const int* piv) {
    double e[NQ], s, norm = 0;
    int i, j;
    for (j = 0; j < NQ; ++j) {
        for (i = 0; i < NQ; ++i) e[i] = i == j ? 1.0 : 0.0;
        lu_solve(LU, piv, e);
        s = 0;
        for (i = 0; i < NQ; ++i) s += fabs(e[i]);
        if (!(s <= norm)) norm = s;
    }
    return norm;
}

/* An upper bound of ||A^-1||_1 from lu_n's factors of A = P^T L U: ||A^-1||_1 <= ||U^-1||_1 ||L^-1||_1,
 * and for a triangular T, |T^-1| <= M(T)^-1 entrywise (M(T), its comparison matrix: |t_ii| on the
 * diagonal, -|t_ij| off it, has a non-negative inverse), so ||T^-1||_1 <= the largest entry of
 * M(T)^-T e: one triangular solve each instead of the NQ solves of the exact norm. */
static double inverse_norm_1_bound(const double* LU) {
    double x[NQ], y[NQ], s, nl = 0, nu = 0;
    int i, j;
    for (i = NQ - 1; i >= 0; --i) {  /* M(L)^T x = e: L unit lower, its multipliers below the diagonal */
        s = 1.0;
        for (j = i + 1; j < NQ; ++j) s += fabs(LU[j + NQ * i]) * x[j];
        x[i] = s;
        if (!(s <= nl)) nl = s;
    }
    for (i = 0; i < NQ; ++i) {  /* M(U)^T y = e: U upper, on and above the diagonal */
        s = 1.0;
        for (j = 0; j < i; ++j) s += fabs(LU[j + NQ * i]) * y[j];
        y[i] = s / fabs(LU[i + NQ * i]);
        if (!(y[i] <= nu)) nu = y[i];
    }
    return nl * nu;
}

/* Forward kinematics, the one implementation (the loop's estimate, <model>_forward_kinematics and its
 * batch, and so hydrogen's Dynamics.forward_kinematics and identification): Newton's method for q with
 * l(q) = l_meas (m), starting from q (updated in place; on failure its last iterate). Each iteration
 * evaluates l and JL at q; it stops when every |l_i - l_meas_i| < tol; else, after max_iter steps, it has
 * not converged; else a step needs JL's 1-norm condition number at most max_cond (JL singular otherwise;
 * a cheap upper bound of it settles most steps, the exact number the rest).
 * Returns a <MODEL>_FK_ outcome; J holds JL at the returned q (when solved, the converged iterate's own
 * evaluation: no extra call for the velocities; when singular, its LU factors). info (3, or NULL): residual
 * max_i |l_i - l_meas_i| (m) at q, JL's condition number there (NaN when not computed, inf when a pivot
 * vanishes), Newton steps taken. */
static int fk_newton(const double* nb, const double* l_meas, double* q, double tol, long long max_iter,
                     double max_cond, double* J, double* info) {
    double l[NL], r[NL], err = NAN, cond = NAN;
    int piv[NQ], i, status;
    long long it;
    for (it = 0;; ++it) {
        if (leg_kinematics(nb, q, l, J)) { status = EXCAVATOR_ARM_FK_FUNCTION_FAILED; break; }
        err = 0;
        for (i = 0; i < NL; ++i) {
            r[i] = l[i] - l_meas[i];
            if (!(fabs(r[i]) <= err)) err = fabs(r[i]);  /* NaN propagates: never "converged" */
        }
        if (err < tol) { status = EXCAVATOR_ARM_FK_SOLVED; break; }
        if (it >= max_iter) { status = EXCAVATOR_ARM_FK_NOT_CONVERGED; break; }
        cond = norm_1(J);
        if (!lu_n(J, piv)) { cond = INFINITY; status = EXCAVATOR_ARM_FK_SINGULAR; break; }
        if (cond * inverse_norm_1_bound(J) <= max_cond) {
            cond = NAN;  /* the bound decides: the exact number is not computed */
        } else {  /* the exact number, only where the bound does not settle it */
            cond *= inverse_norm_1(J, piv);
            if (!(cond <= max_cond)) { status = EXCAVATOR_ARM_FK_SINGULAR; break; }
        }
        lu_solve(J, piv, r);
        for (i = 0; i < NQ; ++i) q[i] -= r[i];
    }
    if (info) {
        info[0] = err;
        info[1] = cond;
        info[2] = (double)it;
    }
    return status;
}

int excavator_arm_forward_kinematics(const double* numbers, const double* l_meas, double* q, double tol,
                               long long max_iter, double max_cond, double* info) {
    double J[NL * NQ];
    return fk_newton(numbers, l_meas, q, tol, max_iter, max_cond, J, info);
}

long long excavator_arm_forward_kinematics_many(const double* numbers, const double* l_meas, long long n,
                                          const double* q0, double tol, long long max_iter, double max_cond,
                                          double* q, int* status, double* info) {
    double J[NL * NQ];
    long long k;
    *status = EXCAVATOR_ARM_FK_SOLVED;
    for (k = 0; k < n; ++k) {
        memcpy(q + NQ * k, k ? q + NQ * (k - 1) : q0, NQ * sizeof(double));
        *status = fk_newton(numbers, l_meas + NL * k, q + NQ * k, tol, max_iter, max_cond, J, info);
        if (*status != EXCAVATOR_ARM_FK_SOLVED) return k;
    }
    return n;
}

/* The parameters the plant's model is evaluated at: the plant's own (c->theta, ...), or the
 * controller's own model's (the predictor); the description's numbers and the pressure bounds */
typedef struct {
    const double *theta, *gamma1, *gamma2, *friction, *valve, *numbers, *p_low, *p_high;
    int bound_stages;  /* the pressures held within their bounds at every stage (stage_rate), else after each step */
} rhs_params;

static int plant_rhs(const rhs_params* m, const double* x, const double* u, double* xdot) {
    const double* arg[8];
    double* res[1];
    arg[0] = x; arg[1] = u; arg[2] = m->theta; arg[3] = m->gamma1; arg[4] = m->gamma2;
    arg[5] = m->friction;
    arg[6] = m->valve;
    arg[7] = m->numbers;
    res[0] = xdot;
    return excavator_arm_plant_rhs(arg, res, 0, 0, 0);
}

static double clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* The plant's rate at a stage y of a step. With bound_stages its pressures are held within their
 * bounds as each step's clip holds the state (0 <= p_c <= p_s for a three-way cylinder; a chamber that
 * would cavitate stays at 0): y's pressures are clipped, and a pressure at a bound does not rate past
 * it. The clip after the step alone lets the stages see pressures past their bounds: an error of first
 * order in the step wherever a pressure rests on one. y may be changed. */
static int stage_rate(const rhs_params* m, double* y, const double* u, double* k) {
    int i;
    if (!m->bound_stages) return plant_rhs(m, y, u, k);
    for (i = 0; i < NPC; ++i) y[2 * NQ + i] = clip(y[2 * NQ + i], m->p_low[i], m->p_high[i]);
    if (plant_rhs(m, y, u, k)) return 1;
    for (i = 0; i < NPC; ++i) {
        const double p = y[2 * NQ + i], r = k[2 * NQ + i];
        if ((p <= m->p_low[i] && r < 0) || (p >= m->p_high[i] && r > 0)) k[2 * NQ + i] = 0;
    }
    return 0;
}

static int rk4(const rhs_params* m, double* x, const double* u, double h) {
    double k1[NX], k2[NX], k3[NX], k4[NX], y[NX];
    int i;
    if (m->bound_stages) {  /* x is within its bounds; its copy only spares x the stage's clip */
        for (i = 0; i < NX; ++i) y[i] = x[i];
        if (stage_rate(m, y, u, k1)) return 0;
    } else if (plant_rhs(m, x, u, k1)) {
        return 0;
    }
    for (i = 0; i < NX; ++i) y[i] = x[i] + 0.5 * h * k1[i];
    if (stage_rate(m, y, u, k2)) return 0;
    for (i = 0; i < NX; ++i) y[i] = x[i] + 0.5 * h * k2[i];
    if (stage_rate(m, y, u, k3)) return 0;
    for (i = 0; i < NX; ++i) y[i] = x[i] + h * k3[i];
    if (stage_rate(m, y, u, k4)) return 0;
    for (i = 0; i < NX; ++i) x[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    return 1;
}

/* n RK4 steps of hs holding u, each pressure within its bounds (0 <= p_c <= p_s for a three-way
 * cylinder) */
static int hold(const rhs_params* m, double* x, const double* u, long long n, double hs) {
    long long j;
    int i;
    for (j = 0; j < n; ++j) {
        if (!rk4(m, x, u, hs)) return 0;
        for (i = 0; i < NPC; ++i) x[2 * NQ + i] = clip(x[2 * NQ + i], m->p_low[i], m->p_high[i]);
    }
    return 1;
}

/* The controller's own model has an ideal valve (spool = command) and no friction (the smoothing
 * speed only keeps tanh's argument finite). */
static const double PRED_FRICTION[6 * NL] = { 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0 };
static const double PRED_VALVE[5 * NL] = { 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0 };

/* The model held at u over dt (s) in steps no longer than h / pred_substeps. */
static int pred_hold(const excavator_arm_loop_config* c, const rhs_params* m, double* x, const double* u, double dt) {
    long long n = (long long)ceil(dt / c->h * (double)c->pred_substeps - 1e-9);
    if (n < 1) n = 1;
    return hold(m, x, u, n, dt / (double)n);
}

/* Delay compensation: the plant state x (NX) at t_k + (delay + delay_frac) h, from the measured pose,
 * velocities and pressures, by the controller's own model over the commands in flight: the one the
 * valves hold over the period's first delay_frac h (st->u_app), then a period each of the commands of
 * periods k - delay .. k - 1 (the ring; 0 before the start). Returns 0 if the model failed. */
static int predict(const excavator_arm_loop_config* c, const excavator_arm_loop_state* st, const excavator_arm_loop_signals* s,
                   double* x) {
    rhs_params m;
    long long j;
    m.theta = c->pred_theta_at >= 0 ? st->xc + c->pred_theta_at : c->pred_theta;
    m.gamma1 = c->pred_gamma1_at >= 0 ? st->xc + c->pred_gamma1_at : c->pred_gamma1;
    m.gamma2 = c->pred_gamma2_at >= 0 ? st->xc + c->pred_gamma2_at : c->pred_gamma2;
    m.friction = PRED_FRICTION;
    m.valve = PRED_VALVE;
    m.numbers = c->numbers; m.p_low = c->p_low; m.p_high = c->p_high;
    m.bound_stages = c->bound_stages != 0;
    memcpy(x, c->pred_x0, NX * sizeof(double));  /* what it measures nothing of: the declared initial values */
    memcpy(x, st->q_meas, NQ * sizeof(double));
    memcpy(x + NQ, s->qdot_meas, NQ * sizeof(double));
    memcpy(x + 2 * NQ, s->pc_meas, NPC * sizeof(double));
    x[2 * NQ + NPC + 2 * NL + 0] = s->ps_meas[0];
    if (c->delay_frac > 0 && !pred_hold(c, &m, x, st->u_app, c->delay_frac * c->h)) return 0;
    for (j = 1; j <= c->delay; ++j) {
        long long r = (st->k - c->delay - 1 + j) % MAX_DELAY;
        if (r < 0) r += MAX_DELAY;
        if (!pred_hold(c, &m, x, st->u_hist + NL * r, c->h)) return 0;
    }
    return 1;
}

static void set_slot(const excavator_arm_loop_config* c, int s, const double* v, long long n) {
    if (c->slot[s] >= 0) memcpy(c->ctrl_arg[c->slot[s]], v, (size_t)n * sizeof(double));
}

void excavator_arm_sense_lengths(const excavator_arm_loop_config* c, const double* l, const double* nz, double* l_meas) {
    int i;
    for (i = 0; i < NL; ++i) {
        l_meas[i] = l[i] + (nz ? nz[NOISE_L + i] : 0);
        if (c->quant_l[i] > 0) l_meas[i] = c->quant_l[i] * floor(l_meas[i] / c->quant_l[i] + 0.5);
    }
}

int excavator_arm_measure(const excavator_arm_loop_config* c, const excavator_arm_loop_state* st, const double* nz,
                    excavator_arm_loop_signals* s) {
    const double* x = st->x;
    double J[NL * NQ];
    long long j;
    int i;
    s->t = (double)st->k * c->h;  /* k h, not a running sum: no drift */
    /* JL at the true pose only for the ideal cylinder-rate sensor */
    if (c->use_kalman ? leg_lengths(c->numbers, x, s->l_true) : leg_kinematics(c->numbers, x, s->l_true, J)) return EXCAVATOR_ARM_CTRL_FAILED;
    excavator_arm_sense_lengths(c, s->l_true, nz, s->l_meas);
    for (i = 0; i < NPC; ++i)
        s->pc_meas[i] = nz ? clip(x[2 * NQ + i] + nz[NOISE_PC + i], c->p_low[i], c->p_high[i]) : x[2 * NQ + i];
    if (!c->use_kalman)
        for (i = 0; i < NL; ++i) {
            s->ldot[i] = 0;
            for (j = 0; j < NQ; ++j) s->ldot[i] += J[i + NL * j] * x[NQ + j];
        }
    for (i = 0; i < NQ; ++i) s->q_enc[i] = x[i] + (nz ? nz[NOISE_Q + i] : 0);
    /* the supply pressure, held at its lower bound 0 */
    s->ps_meas[0] = nz ? clip(x[2 * NQ + NPC + 2 * NL + 0] + nz[NOISE_PS], 0.0, HUGE_VAL) : x[2 * NQ + NPC + 2 * NL + 0];
    return EXCAVATOR_ARM_OK;
}

/* A failed forward kinematics or velocity solve (outcome fk, fk_newton's info) recorded in st->fk_info and
 * st->fk_l, for the runtime to word as hydrogen.dynamics.fk_failure does; returns EXCAVATOR_ARM_FK_FAILED. */
static int fk_failed(excavator_arm_loop_state* st, const excavator_arm_loop_signals* s, int fk, const double* info) {
    st->fk_info[0] = (double)fk;
    memcpy(st->fk_info + 1, info, 3 * sizeof(double));
    memcpy(st->fk_l, s->l_meas, sizeof st->fk_l);
    return EXCAVATOR_ARM_FK_FAILED;
}

int excavator_arm_estimate(const excavator_arm_loop_config* c, excavator_arm_loop_state* st, excavator_arm_loop_signals* s) {
    double J[NL * NQ];
    int i;
    if (c->use_kalman)
        for (i = 0; i < NL; ++i) {  /* predict with [1 h; 0 1], correct with the fixed gain */
            double lp = st->kf[i] + c->h * st->kf[NL + i], vp = st->kf[NL + i], r = s->l_meas[i] - lp;
            st->kf[i] = lp + c->kf_gain[0] * r;
            st->kf[NL + i] = vp + c->kf_gain[1] * r;
            s->ldot[i] = st->kf[NL + i];
        }
    /* joint encoders: the pose is measured; JL at the measured pose for the velocities */
    memcpy(st->q_meas, s->q_enc, sizeof s->q_enc);
    {
        double l_tmp[NL];
        if (leg_kinematics(c->numbers, st->q_meas, l_tmp, J)) return EXCAVATOR_ARM_CTRL_FAILED;
    }
    memcpy(s->qdot_meas, s->ldot, sizeof s->ldot);
    if (!solve_n(J, s->qdot_meas)) {  /* JL singular at the measured pose: no velocities */
        const double info[3] = {0, INFINITY, 0};
        return fk_failed(st, s, EXCAVATOR_ARM_FK_VELOCITY_SINGULAR, info);
    }
    return EXCAVATOR_ARM_OK;
}

/* q_d and its first three derivatives at t: the bias, then what each reference kind adds
 * (hydrogen.references; an idle kind adds nothing) */
void excavator_arm_reference(const excavator_arm_loop_config* c, double t, double* qd /* 4 x NQ */) {
    int i;
    for (i = 0; i < NQ; ++i) {
        qd[i] = c->bias[i];
        qd[NQ + i] = qd[2 * NQ + i] = qd[3 * NQ + i] = 0;
    }
    {
        long long j;
        for (j = 0; j < c->n_moves; ++j) {
            double axis = c->moves[4 * j], d = c->moves[4 * j + 1];
            double t0 = c->moves[4 * j + 2], dur = c->moves[4 * j + 3];
            double tau, t2;
            int ax;
            if (!(axis >= 0 && axis < NQ) || !(dur > 0)) continue;  /* never index with an unchecked value */
            ax = (int)axis;
            if (t >= t0 + dur) {
                qd[ax] += d;
                continue;
            }
            if (t <= t0) continue;
            tau = (t - t0) / dur;
            t2 = tau * tau;
            qd[ax] += d * t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
            qd[NQ + ax] += d / dur * 30.0 * t2 * (1.0 + tau * (-2.0 + tau));
            qd[2 * NQ + ax] += d / (dur * dur) * 60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau));
            qd[3 * NQ + ax] += d / (dur * dur * dur) * 60.0 * (1.0 + tau * (-6.0 + 6.0 * tau));
        }
    }
    {
        long long j;
        for (j = 0; j < c->n_terms; ++j) {
            double axis = c->terms[3 * j];
            double a = c->terms[3 * j + 1], w = TWO_PI * c->terms[3 * j + 2];
            double sn, co;
            int ax;
            if (!(axis >= 0 && axis < NQ)) continue;  /* never index with an unchecked value */
            ax = (int)axis;
            sn = sin(w * t);
            co = cos(w * t);
            qd[ax] += a * sn;
            qd[NQ + ax] += a * w * co;
            qd[2 * NQ + ax] -= a * w * w * sn;
            qd[3 * NQ + ax] -= a * w * w * w * co;
        }
    }
    if (c->step_axis >= 0 && c->step_axis < NQ && t >= c->t_step) qd[c->step_axis] += c->step_height;
}

int excavator_arm_control(const excavator_arm_loop_config* c, excavator_arm_loop_state* st, excavator_arm_loop_signals* s) {
    double adapt = s->t >= c->t_adapt ? 1.0 : 0.0;
    double xp[NX], lp[NL], qdp[4 * NQ];
    const double *q = st->q_meas, *qdot = s->qdot_meas, *pc = s->pc_meas, *l = s->l_meas, *qd = s->qd;
    /* without supply feedback the controller assumes the description's constant supply pressure */
    const double* ps = c->supply_feedback ? s->ps_meas : &c->ps_nominal;
    const double* u_prev = st->u_app;
    int i;
    if (c->n_xc && !c->xc_euler && !c->step) return EXCAVATOR_ARM_CTRL_FAILED;  /* a state needs its update */
    if (c->predict) {
        /* the controller sees the plant as it will be when this command reaches the valves, and the
         * command the valves held over the period ending there is its own last one */
        if (!predict(c, st, s, xp)) return EXCAVATOR_ARM_CTRL_FAILED;
        for (i = 0; i < NX; ++i)
            if (!isfinite(xp[i])) return EXCAVATOR_ARM_NONFINITE;
        if (leg_lengths(c->numbers, xp, lp)) return EXCAVATOR_ARM_CTRL_FAILED;
        excavator_arm_reference(c, s->t + ((double)c->delay + c->delay_frac) * c->h, qdp);
        q = xp; qdot = xp + NQ; pc = xp + 2 * NQ; l = lp; qd = qdp;
        if (c->supply_feedback) ps = xp + 2 * NQ + NPC + 2 * NL;
        if (c->delay > 0) {
            long long r = (st->k - 1) % MAX_DELAY;
            if (r < 0) r += MAX_DELAY;
            u_prev = st->u_hist + NL * r;
        }
    }
    set_slot(c, EXCAVATOR_ARM_SLOT_Q, q, NQ);
    set_slot(c, EXCAVATOR_ARM_SLOT_QDOT, qdot, NQ);
    set_slot(c, EXCAVATOR_ARM_SLOT_PC, pc, NPC);
    set_slot(c, EXCAVATOR_ARM_SLOT_L, l, NL);
    set_slot(c, EXCAVATOR_ARM_SLOT_QD0, qd, NQ);
    set_slot(c, EXCAVATOR_ARM_SLOT_QD1, qd + NQ, NQ);
    set_slot(c, EXCAVATOR_ARM_SLOT_QD2, qd + 2 * NQ, NQ);
    set_slot(c, EXCAVATOR_ARM_SLOT_QD3, qd + 3 * NQ, NQ);
    set_slot(c, EXCAVATOR_ARM_SLOT_XC, st->xc, c->n_xc);
    set_slot(c, EXCAVATOR_ARM_SLOT_ADAPT, &adapt, 1);
    set_slot(c, EXCAVATOR_ARM_SLOT_U_APPLIED, u_prev, NL);
    set_slot(c, EXCAVATOR_ARM_SLOT_PS, ps, NPS);
    /* controller state: semi-implicit update. The estimates and observer states of period k are
     * xc_k = clip(xc_{k-1} + h F(measurement_k, xc_{k-1}, u_app_{k-1})), and the command of period k
     * uses xc_k: the adaptation feedback then has no one-period delay (symplectic Euler on the coupled
     * force error / estimate oscillation), stable up to about 5x the adaptation gain forward Euler
     * takes at the same rate. u_app_{k-1} is the command the valves held over the period F integrates
     * (with a fractional delay: the one they held at its end, after the switch).
     * One call of the generated step does both (what depends on the measurement only is computed
     * once) and writes u where the controller would. The first period uses the initial state. */
    if (c->n_xc && !c->xc_euler && st->k > 0) {
        if (c->step((const double**)c->step_arg, c->step_res, c->step_iw, c->step_w, 0)) return EXCAVATOR_ARM_CTRL_FAILED;
        memcpy(st->xc, c->step_res[1], (size_t)c->n_xc * sizeof(double));
        set_slot(c, EXCAVATOR_ARM_SLOT_XC, st->xc, c->n_xc);
    } else if (c->ctrl((const double**)c->ctrl_arg, c->ctrl_res, c->ctrl_iw, c->ctrl_w, 0)) {
        return EXCAVATOR_ARM_CTRL_FAILED;
    }
    memcpy(s->u, c->ctrl_res[0], sizeof s->u);
    /* computation delay: the valves hold the last period's command over the first delay_frac h, then
     * the command of `delay` periods ago (0 before the start); the ring keeps this one */
    memcpy(s->u_held, st->u_app, sizeof s->u_held);
    if (c->delay > 0) {
        long long r = (st->k - c->delay) % MAX_DELAY, w = st->k % MAX_DELAY;
        if (r < 0) r += MAX_DELAY;
        memcpy(s->u_app, st->u_hist + NL * r, sizeof s->u_app);
        memcpy(st->u_hist + NL * w, s->u, sizeof s->u);
    } else {
        memcpy(s->u_app, s->u, sizeof s->u);
    }
    memcpy(st->u_app, s->u_app, sizeof s->u_app);
    return EXCAVATOR_ARM_OK;
}

int excavator_arm_control_advance(const excavator_arm_loop_config* c, excavator_arm_loop_state* st) {
    long long j;
    /* controller state, forward Euler variant (xc_euler): the rate the command's call gave (this
     * period's measurement, state and u_applied, the command the valves held over the period that
     * ended at the measurement), kept inside the projection bounds */
    if (c->xc_euler && c->n_xc)
        for (j = 0; j < c->n_xc; ++j)
            st->xc[j] = clip(st->xc[j] + c->h * c->ctrl_res[1][j], c->xc_lo[j], c->xc_hi[j]);
    for (j = 0; j < c->n_xc; ++j)
        if (!isfinite(st->xc[j])) return EXCAVATOR_ARM_NONFINITE;
    return EXCAVATOR_ARM_OK;
}

int excavator_arm_plant_step(const excavator_arm_loop_config* c, excavator_arm_loop_state* st, const double* u_held,
                       const double* u_app) {
    double* x = st->x;
    const long long n = c->substeps;
    rhs_params m;
    int i;
    m.theta = c->theta; m.gamma1 = c->gamma1; m.gamma2 = c->gamma2;
    m.friction = c->friction;
    m.valve = c->valve;
    m.numbers = c->numbers; m.p_low = c->p_low; m.p_high = c->p_high;
    m.bound_stages = c->bound_stages != 0;
    if (n < 1) return EXCAVATOR_ARM_CTRL_FAILED;
    if (c->delay_frac > 0) {
        /* the command switches at delay_frac h: each part takes enough sub-steps that none is longer
         * than h / substeps (the step the valve's stability check assumes) */
        long long n1 = (long long)ceil(c->delay_frac * (double)n), n2 = (long long)ceil((1.0 - c->delay_frac) * (double)n);
        if (n1 < 1) n1 = 1;
        if (n2 < 1) n2 = 1;
        if (!hold(&m, x, u_held, n1, c->delay_frac * c->h / (double)n1)) return EXCAVATOR_ARM_CTRL_FAILED;
        if (!hold(&m, x, u_app, n2, (1.0 - c->delay_frac) * c->h / (double)n2)) return EXCAVATOR_ARM_CTRL_FAILED;
    } else if (!hold(&m, x, u_app, n, c->h / (double)n)) {
        return EXCAVATOR_ARM_CTRL_FAILED;
    }
    for (i = 0; i < NX; ++i)
        if (!isfinite(x[i])) return EXCAVATOR_ARM_NONFINITE;
    return EXCAVATOR_ARM_OK;
}

/* Row st->k of each log that is not NULL, before the plant step (hydrogen.loop_logs: each log's source). */
static int write_log(const excavator_arm_loop_state* st, const excavator_arm_loop_config* c, const excavator_arm_loop_signals* s,
                     excavator_arm_loop_log* log) {
    const double* x = st->x;
    const long long k = st->k;
    if (log->t) memcpy(log->t + k, &s->t, 1 * sizeof(double));
    if (log->q) memcpy(log->q + NQ * k, x, NQ * sizeof(double));
    if (log->q_d) memcpy(log->q_d + NQ * k, s->qd, NQ * sizeof(double));
    if (log->l) memcpy(log->l + NL * k, s->l_true, NL * sizeof(double));
    if (log->pc) memcpy(log->pc + NPC * k, x + 2 * NQ, NPC * sizeof(double));
    if (log->u) memcpy(log->u + NL * k, s->u, NL * sizeof(double));
    if (log->u_applied) memcpy(log->u_applied + NL * k, s->u_app, NL * sizeof(double));
    if (log->l_meas) memcpy(log->l_meas + NL * k, s->l_meas, NL * sizeof(double));
    if (log->ldot) memcpy(log->ldot + NL * k, s->ldot, NL * sizeof(double));
    if (log->qdot_meas) memcpy(log->qdot_meas + NQ * k, s->qdot_meas, NQ * sizeof(double));
    if (log->xc && c->n_xc) memcpy(log->xc + c->n_xc * k, st->xc, (size_t)c->n_xc * sizeof(double));
    if (log->ps) memcpy(log->ps + NPS * k, x + 2 * NQ + NPC + 2 * NL, NPS * sizeof(double));
    /* the forces last: a failed call leaves the row's other logs written */
    if (log->f && leg_force(c->numbers, x + 2 * NQ, x + 2 * NQ + NPC + 2 * NL, log->f + NL * k)) return EXCAVATOR_ARM_CTRL_FAILED;
    return EXCAVATOR_ARM_OK;
}

int excavator_arm_loop_run(const excavator_arm_loop_config* c, excavator_arm_loop_state* st, long long n,
                     const double* noise, excavator_arm_loop_log* log) {
    excavator_arm_loop_signals s;
    long long step;
    int rc, rc_xc;
    /* the ring holds MAX_DELAY periods */
    if (c->delay < 0 || c->delay > MAX_DELAY || !(c->delay_frac >= 0 && c->delay_frac < 1)
        || (c->delay == MAX_DELAY && c->delay_frac > 0)) return EXCAVATOR_ARM_CTRL_FAILED;
    if (c->n_xc && !c->xc_euler && !c->step) return EXCAVATOR_ARM_CTRL_FAILED;  /* a state needs its update */
    for (step = 0; step < n; ++step) {
        const double* nz = noise ? noise + NNOISE * step : 0;  /* row `step` of this call's table */
        if ((rc = excavator_arm_measure(c, st, nz, &s))) return rc;
        if ((rc = excavator_arm_estimate(c, st, &s))) return rc;
        excavator_arm_reference(c, s.t, s.qd);
        if ((rc = excavator_arm_control(c, st, &s))) return rc;
        if (log && (rc = write_log(st, c, &s, log))) return rc;
        rc = excavator_arm_plant_step(c, st, s.u_held, s.u_app);
        if (rc == EXCAVATOR_ARM_CTRL_FAILED) return rc;
        /* a non-finite state stops the run with st->k at the period that produced it */
        rc_xc = excavator_arm_control_advance(c, st);
        if (rc) return rc;
        if (rc_xc) return rc_xc;
        st->k += 1;
        st->t = (double)st->k * c->h;
    }
    return EXCAVATOR_ARM_OK;
}
