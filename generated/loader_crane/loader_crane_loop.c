/* Closed-loop driver for model loader_crane (see loader_crane_loop.h).
 * Rendered by hydrogen from templates/loop.c.j2; plain C99, no dependency but libm.
 * One control period: measure (noise, quantisation, Kalman filter), joint encoders,
 * reference, controller state update and command, the command of delay periods ago (zero-order
 * hold), RK4 sub-steps of the plant. */
#include <math.h>
#include <string.h>

#include "loader_crane_loop.h"
#include "loader_crane_leg_lengths.h"
#include "loader_crane_leg_kinematics.h"
#include "loader_crane_plant_rhs.h"
#include "loader_crane_leg_force.h"

#define NQ LOADER_CRANE_NQ
#define NL LOADER_CRANE_NL
#define NX LOADER_CRANE_NX
#define NNOISE LOADER_CRANE_NNOISE
#define MAX_DELAY LOADER_CRANE_MAX_DELAY
static const double TWO_PI = 6.283185307179586;
#define NPR LOADER_CRANE_NPR
/* baked bounds of each pressure state (Pa), the clip of the measurement and of the plant */
static const double P_LOW[NPR] = { 0.0, 0.0, 0.0, 0.0, 0.0, 0.0 };
static const double P_HIGH[NPR] = { 24000000.0, 24000000.0, 24000000.0, 24000000.0, 24000000.0, 24000000.0 };

/* actuator forces (N, N m) from the pressure vector: the actuators' own laws */
static int leg_force(const double* p, double* f) {
    const double* arg[1];
    double* res[1];
    arg[0] = p;
    res[0] = f;
    return loader_crane_leg_force(arg, res, 0, 0, 0);
}

static int leg_lengths(const double* q, double* l) {
    const double* arg[1];
    double* res[1];
    arg[0] = q;
    res[0] = l;
    return loader_crane_leg_lengths(arg, res, 0, 0, 0);
}

int loader_crane_leg_lengths_many(const double* q, long long n, double* l) {
    long long k;
    for (k = 0; k < n; ++k)
        if (leg_lengths(q + NQ * k, l + NL * k)) return 1;
    return 0;
}

/* cylinder lengths and JL (column-major NL x NQ) in one call: they share the link poses */
static int leg_kinematics(const double* q, double* l, double* J) {
    const double* arg[1];
    double* res[2];
    arg[0] = q;
    res[0] = l;
    res[1] = J;
    return loader_crane_leg_kinematics(arg, res, 0, 0, 0);
}

/* Solve A x = b (A column-major NQ x NQ, overwritten), partial pivoting; returns 0 if singular. */
static int solve_n(double* A, double* b) {
    int i, j, k, piv;
    double m, tmp;
    for (k = 0; k < NQ; ++k) {
        piv = k;
        for (i = k + 1; i < NQ; ++i)
            if (fabs(A[i + NQ * k]) > fabs(A[piv + NQ * k])) piv = i;
        if (!(fabs(A[piv + NQ * k]) > 1e-12)) return 0;
        if (piv != k) {
            for (j = 0; j < NQ; ++j) {
                tmp = A[k + NQ * j]; A[k + NQ * j] = A[piv + NQ * j]; A[piv + NQ * j] = tmp;
            }
            tmp = b[k]; b[k] = b[piv]; b[piv] = tmp;
        }
        for (i = k + 1; i < NQ; ++i) {
            m = A[i + NQ * k] / A[k + NQ * k];
            for (j = k; j < NQ; ++j) A[i + NQ * j] -= m * A[k + NQ * j];
            b[i] -= m * b[k];
        }
    }
    for (k = NQ - 1; k >= 0; --k) {
        for (j = k + 1; j < NQ; ++j) b[k] -= A[k + NQ * j] * b[j];
        b[k] /= A[k + NQ * k];
    }
    return 1;
}

static void reference(const loader_crane_loop_config* c, double t, double* qd /* 4 x NQ */) {
    long long j;
    int i;
    for (i = 0; i < NQ; ++i) {
        qd[i] = c->bias[i];
        qd[NQ + i] = qd[2 * NQ + i] = qd[3 * NQ + i] = 0;
    }
    for (j = 0; j < c->n_terms; ++j) {
        double axis = c->terms[3 * j];
        double a = c->terms[3 * j + 1], w = TWO_PI * c->terms[3 * j + 2];
        double s, co;
        int ax;
        if (!(axis >= 0 && axis < NQ)) continue;  /* never index with an unchecked value */
        ax = (int)axis;
        s = sin(w * t);
        co = cos(w * t);
        qd[ax] += a * s;
        qd[NQ + ax] += a * w * co;
        qd[2 * NQ + ax] -= a * w * w * s;
        qd[3 * NQ + ax] -= a * w * w * w * co;
    }
    if (c->step_axis >= 0 && c->step_axis < NQ && t >= c->t_step) qd[c->step_axis] += c->step_height;
}

static int plant_rhs(const loader_crane_loop_config* c, const double* x, const double* u, double* xdot) {
    const double* arg[7];
    double* res[1];
    arg[0] = x; arg[1] = u; arg[2] = c->theta; arg[3] = c->gamma1; arg[4] = c->gamma2;
    arg[5] = c->friction; arg[6] = c->valve;
    res[0] = xdot;
    return loader_crane_plant_rhs(arg, res, 0, 0, 0);
}

static int rk4(const loader_crane_loop_config* c, double* x, const double* u, double h) {
    double k1[NX], k2[NX], k3[NX], k4[NX], y[NX];
    int i;
    if (plant_rhs(c, x, u, k1)) return 0;
    for (i = 0; i < NX; ++i) y[i] = x[i] + 0.5 * h * k1[i];
    if (plant_rhs(c, y, u, k2)) return 0;
    for (i = 0; i < NX; ++i) y[i] = x[i] + 0.5 * h * k2[i];
    if (plant_rhs(c, y, u, k3)) return 0;
    for (i = 0; i < NX; ++i) y[i] = x[i] + h * k3[i];
    if (plant_rhs(c, y, u, k4)) return 0;
    for (i = 0; i < NX; ++i) x[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    return 1;
}

static void set_slot(const loader_crane_loop_config* c, int s, const double* v, long long n) {
    if (c->slot[s] >= 0) memcpy(c->ctrl_arg[c->slot[s]], v, (size_t)n * sizeof(double));
}

static double clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

int loader_crane_loop_run(const loader_crane_loop_config* c, loader_crane_loop_state* st, long long n,
                     const double* noise, loader_crane_loop_log* log) {
    double l_true[NL], l_meas[NL], pc_meas[NPR], ldot[NL], qdot_meas[NQ], J[NL * NQ], qd[4 * NQ], u[NL], u_app[NL];
    double adapt;
    double* x = st->x;
    const double h = c->h, hs = c->h / (double)c->substeps;
    long long step, j;
    int i;
    if (c->delay < 0 || c->delay > MAX_DELAY) return LOADER_CRANE_CTRL_FAILED;  /* the ring holds MAX_DELAY periods */
    if (c->n_xc && !c->xc_euler && !c->step) return LOADER_CRANE_CTRL_FAILED;  /* a state needs its update */
    for (step = 0; step < n; ++step) {
        const double* nz = noise ? noise + NNOISE * step : 0;  /* row `step` of this call's table */
        const double t = (double)st->k * h;  /* k h, not a running sum: no drift */
        /* sensors (JL at the true pose only for the ideal cylinder-rate sensor) */
        if (c->use_kalman ? leg_lengths(x, l_true) : leg_kinematics(x, l_true, J)) return LOADER_CRANE_CTRL_FAILED;
        for (i = 0; i < NL; ++i) {
            l_meas[i] = l_true[i] + (nz ? nz[i] : 0);
            if (c->quant_l > 0) l_meas[i] = c->quant_l * floor(l_meas[i] / c->quant_l + 0.5);
        }
        for (i = 0; i < NPR; ++i)
            pc_meas[i] = nz ? clip(x[2 * NQ + i] + nz[NL + i], P_LOW[i], P_HIGH[i]) : x[2 * NQ + i];
        if (c->use_kalman) {
            for (i = 0; i < NL; ++i) {  /* predict with [1 h; 0 1], correct with the fixed gain */
                double lp = st->kf[i] + h * st->kf[NL + i], vp = st->kf[NL + i], r = l_meas[i] - lp;
                st->kf[i] = lp + c->kf_gain[0] * r;
                st->kf[NL + i] = vp + c->kf_gain[1] * r;
                ldot[i] = st->kf[NL + i];
            }
        } else {
            for (i = 0; i < NL; ++i) {
                ldot[i] = 0;
                for (j = 0; j < NQ; ++j) ldot[i] += J[i + NL * j] * x[NQ + j];
            }
        }
        /* joint encoders: the pose is measured; JL at the measured pose for the velocities */
        for (i = 0; i < NQ; ++i) st->q_meas[i] = x[i] + (nz ? nz[NL + NPR + i] : 0);
        {
            double l_tmp[NL];
            if (leg_kinematics(st->q_meas, l_tmp, J)) return LOADER_CRANE_CTRL_FAILED;
        }
        memcpy(qdot_meas, ldot, sizeof ldot);
        if (!solve_n(J, qdot_meas)) return LOADER_CRANE_FK_FAILED;
        /* controller */
        reference(c, t, qd);
        adapt = t >= c->t_adapt ? 1.0 : 0.0;
        set_slot(c, LOADER_CRANE_SLOT_Q, st->q_meas, NQ);
        set_slot(c, LOADER_CRANE_SLOT_QDOT, qdot_meas, NQ);
        set_slot(c, LOADER_CRANE_SLOT_PC, pc_meas, NPR);
        set_slot(c, LOADER_CRANE_SLOT_L, l_meas, NL);
        set_slot(c, LOADER_CRANE_SLOT_QD0, qd, NQ);
        set_slot(c, LOADER_CRANE_SLOT_QD1, qd + NQ, NQ);
        set_slot(c, LOADER_CRANE_SLOT_QD2, qd + 2 * NQ, NQ);
        set_slot(c, LOADER_CRANE_SLOT_QD3, qd + 3 * NQ, NQ);
        set_slot(c, LOADER_CRANE_SLOT_XC, st->xc, c->n_xc);
        set_slot(c, LOADER_CRANE_SLOT_ADAPT, &adapt, 1);
        set_slot(c, LOADER_CRANE_SLOT_U_APPLIED, st->u_app, NL);
        /* controller state: semi-implicit update. The estimates and observer states of period k are
         * xc_k = clip(xc_{k-1} + h F(measurement_k, xc_{k-1}, u_app_{k-1})), and the command of period k
         * uses xc_k: the adaptation feedback then has no one-period delay (symplectic Euler on the coupled
         * force error / estimate oscillation), stable up to about 5x the adaptation gain forward Euler
         * takes at the same rate. u_app_{k-1} is the command the valves held over the period F integrates.
         * One call of the generated step does both (what depends on the measurement only is computed
         * once) and writes u where the controller would. The first period uses the initial state. */
        if (c->n_xc && !c->xc_euler && st->k > 0) {
            if (c->step((const double**)c->step_arg, c->step_res, c->step_iw, c->step_w, 0)) return LOADER_CRANE_CTRL_FAILED;
            memcpy(st->xc, c->step_res[1], (size_t)c->n_xc * sizeof(double));
            set_slot(c, LOADER_CRANE_SLOT_XC, st->xc, c->n_xc);
        } else if (c->ctrl((const double**)c->ctrl_arg, c->ctrl_res, c->ctrl_iw, c->ctrl_w, 0)) {
            return LOADER_CRANE_CTRL_FAILED;
        }
        memcpy(u, c->ctrl_res[0], sizeof u);
        /* computation delay: apply the command of `delay` periods ago (0 before the start), keep this one */
        if (c->delay > 0) {
            long long r = (st->k - c->delay) % MAX_DELAY, w = st->k % MAX_DELAY;
            if (r < 0) r += MAX_DELAY;
            memcpy(u_app, st->u_hist + NL * r, sizeof u_app);
            memcpy(st->u_hist + NL * w, u, sizeof u);
        } else {
            memcpy(u_app, u, sizeof u);
        }
        memcpy(st->u_app, u_app, sizeof u_app);
        if (log) {
            if (log->t) log->t[st->k] = t;
            if (log->q) memcpy(log->q + NQ * st->k, x, NQ * sizeof(double));
            if (log->q_d) memcpy(log->q_d + NQ * st->k, qd, NQ * sizeof(double));
            if (log->l) memcpy(log->l + NL * st->k, l_true, NL * sizeof(double));
            if (log->pc) memcpy(log->pc + NPR * st->k, x + 2 * NQ, NPR * sizeof(double));
            if (log->u) memcpy(log->u + NL * st->k, u, NL * sizeof(double));
            if (log->u_applied) memcpy(log->u_applied + NL * st->k, u_app, NL * sizeof(double));
            if (log->l_meas) memcpy(log->l_meas + NL * st->k, l_meas, NL * sizeof(double));
            if (log->f && leg_force(x + 2 * NQ, log->f + NL * st->k)) return LOADER_CRANE_CTRL_FAILED;
            if (log->xc && c->n_xc) memcpy(log->xc + c->n_xc * st->k, st->xc, (size_t)c->n_xc * sizeof(double));
        }
        /* plant, zero-order hold on the applied command; each pressure within its bounds */
        for (j = 0; j < c->substeps; ++j) {
            if (!rk4(c, x, u_app, hs)) return LOADER_CRANE_CTRL_FAILED;
            for (i = 0; i < NPR; ++i) x[2 * NQ + i] = clip(x[2 * NQ + i], P_LOW[i], P_HIGH[i]);
        }
        /* controller state, forward Euler variant (xc_euler): the rate the command's call gave (this
         * period's measurement, state and u_applied, the command the valves held over the period that
         * ended at the measurement), applied after the plant step, kept inside the projection bounds */
        if (c->xc_euler && c->n_xc)
            for (j = 0; j < c->n_xc; ++j)
                st->xc[j] = clip(st->xc[j] + h * c->ctrl_res[1][j], c->xc_lo[j], c->xc_hi[j]);
        /* a non-finite state stops the run with st->k at the period that produced it */
        for (i = 0; i < NX; ++i)
            if (!isfinite(x[i])) return LOADER_CRANE_NONFINITE;
        for (j = 0; j < c->n_xc; ++j)
            if (!isfinite(st->xc[j])) return LOADER_CRANE_NONFINITE;
        st->k += 1;
        st->t = (double)st->k * h;
    }
    return LOADER_CRANE_OK;
}
