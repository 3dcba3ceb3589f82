/* Closed-loop driver for model ubc_stewart (see ubc_stewart_loop.h).
 * Rendered by hydrogen from templates/loop.c.j2; plain C99, no dependency but libm.
 * One control period: measure (noise, Kalman filter), forward kinematics, reference,
 * controller (zero-order hold), RK4 sub-steps of the plant, Euler step of the controller state. */
#include <math.h>
#include <string.h>

#include "ubc_stewart_loop.h"
#include "ubc_stewart_leg_lengths.h"
#include "ubc_stewart_leg_kinematics.h"
#include "ubc_stewart_plant_rhs.h"

#define NX 24
static const double TWO_PI = 6.283185307179586;

static int leg_lengths(const double* q, double* l) {
    const double* arg[1];
    double* res[1];
    arg[0] = q;
    res[0] = l;
    return ubc_stewart_leg_lengths(arg, res, 0, 0, 0);
}

int ubc_stewart_leg_lengths_many(const double* q, long long n, double* l) {
    long long k;
    for (k = 0; k < n; ++k)
        if (leg_lengths(q + 6 * k, l + 6 * k)) return 1;
    return 0;
}

/* leg lengths and JL (column-major 6x6) in one call: they share the leg vectors */
static int leg_kinematics(const double* q, double* l, double* J) {
    const double* arg[1];
    double* res[2];
    arg[0] = q;
    res[0] = l;
    res[1] = J;
    return ubc_stewart_leg_kinematics(arg, res, 0, 0, 0);
}

/* Solve A x = b (A column-major n x n, overwritten), partial pivoting; returns 0 if singular. */
static int solve6(double* A, double* b) {
    int i, j, k, piv;
    double m, tmp;
    for (k = 0; k < 6; ++k) {
        piv = k;
        for (i = k + 1; i < 6; ++i)
            if (fabs(A[i + 6 * k]) > fabs(A[piv + 6 * k])) piv = i;
        if (!(fabs(A[piv + 6 * k]) > 1e-12)) return 0;
        if (piv != k) {
            for (j = 0; j < 6; ++j) {
                tmp = A[k + 6 * j]; A[k + 6 * j] = A[piv + 6 * j]; A[piv + 6 * j] = tmp;
            }
            tmp = b[k]; b[k] = b[piv]; b[piv] = tmp;
        }
        for (i = k + 1; i < 6; ++i) {
            m = A[i + 6 * k] / A[k + 6 * k];
            for (j = k; j < 6; ++j) A[i + 6 * j] -= m * A[k + 6 * j];
            b[i] -= m * b[k];
        }
    }
    for (k = 5; k >= 0; --k) {
        for (j = k + 1; j < 6; ++j) b[k] -= A[k + 6 * j] * b[j];
        b[k] /= A[k + 6 * k];
    }
    return 1;
}

/* Newton's method for q with l(q) = l_meas, starting from q (updated in place). Returns 1 with J holding
 * JL at the returned q (the converged iterate's own evaluation: no extra call for the velocities),
 * 0 if it does not converge or JL is singular, -1 if the generated function failed. */
static int forward_kinematics(const double* l_meas, double* q, double tol, long long max_iter, double* J) {
    double l[6], r[6], err;
    long long it;
    int i;
    for (it = 0; it <= max_iter; ++it) {
        if (leg_kinematics(q, l, J)) return -1;
        err = 0;
        for (i = 0; i < 6; ++i) {
            r[i] = l[i] - l_meas[i];
            if (fabs(r[i]) > err) err = fabs(r[i]);
        }
        if (err < tol) return 1;
        if (it == max_iter || !solve6(J, r)) return 0;  /* J is evaluated again next iteration */
        for (i = 0; i < 6; ++i) q[i] -= r[i];
    }
    return 0;
}

static void reference(const ubc_stewart_loop_config* c, double t, double* qd /* 4 x 6 */) {
    long long j;
    int i;
    for (i = 0; i < 6; ++i) {
        qd[i] = c->bias[i];
        qd[6 + i] = qd[12 + i] = qd[18 + i] = 0;
    }
    for (j = 0; j < c->n_terms; ++j) {
        int ax = (int)c->terms[3 * j];
        double a = c->terms[3 * j + 1], w = TWO_PI * c->terms[3 * j + 2];
        double s = sin(w * t), co = cos(w * t);
        qd[ax] += a * s;
        qd[6 + ax] += a * w * co;
        qd[12 + ax] -= a * w * w * s;
        qd[18 + ax] -= a * w * w * w * co;
    }
    if (c->step_axis >= 0 && t >= c->t_step) qd[c->step_axis] += c->step_height;
}

static int plant_rhs(const ubc_stewart_loop_config* c, const double* x, const double* u, double* xdot) {
    const double* arg[6];
    double* res[1];
    arg[0] = x; arg[1] = u; arg[2] = c->theta; arg[3] = c->gamma; arg[4] = c->friction; arg[5] = c->tau_valve;
    res[0] = xdot;
    return ubc_stewart_plant_rhs(arg, res, 0, 0, 0);
}

static int rk4(const ubc_stewart_loop_config* c, double* x, const double* u, double h) {
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

static void set_slot(const ubc_stewart_loop_config* c, int s, const double* v, long long n) {
    if (c->slot[s] >= 0) memcpy(c->ctrl_arg[c->slot[s]], v, (size_t)n * sizeof(double));
}

static double clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

int ubc_stewart_loop_run(const ubc_stewart_loop_config* c, ubc_stewart_loop_state* st, long long n,
                     const double* noise, ubc_stewart_loop_log* log) {
    double l_true[6], l_meas[6], pc_meas[6], ldot[6], qdot_meas[6], J[36], qd[24], u[6], adapt;
    double* x = st->x;
    const double h = c->h, hs = c->h / (double)c->substeps, ps = c->supply_pressure;
    long long step, j;
    int i;
    for (step = 0; step < n; ++step) {
        const double* nz = noise ? noise + 12 * step : 0;  /* row `step` of this call's table */
        const double t = (double)st->k * h;  /* k h, not a running sum: no drift */
        /* sensors (JL at the true pose only for the ideal leg-rate sensor) */
        if (c->use_kalman ? leg_lengths(x, l_true) : leg_kinematics(x, l_true, J)) return UBC_STEWART_CTRL_FAILED;
        for (i = 0; i < 6; ++i) {
            l_meas[i] = l_true[i] + (nz ? nz[i] : 0);
            pc_meas[i] = nz ? clip(x[12 + i] + nz[6 + i], 0, ps) : x[12 + i];
        }
        if (c->use_kalman) {
            for (i = 0; i < 6; ++i) {  /* predict with [1 h; 0 1], correct with the fixed gain */
                double lp = st->kf[i] + h * st->kf[6 + i], vp = st->kf[6 + i], r = l_meas[i] - lp;
                st->kf[i] = lp + c->kf_gain[0] * r;
                st->kf[6 + i] = vp + c->kf_gain[1] * r;
                ldot[i] = st->kf[6 + i];
            }
        } else {
            for (i = 0; i < 6; ++i) {
                ldot[i] = 0;
                for (j = 0; j < 6; ++j) ldot[i] += J[i + 6 * j] * x[6 + j];
            }
        }
        /* task space from leg space */
        switch (forward_kinematics(l_meas, st->q_meas, c->fk_tol, c->fk_max_iter, J)) {
            case 1: break;
            case 0: return UBC_STEWART_FK_FAILED;
            default: return UBC_STEWART_CTRL_FAILED;
        }
        memcpy(qdot_meas, ldot, sizeof ldot);
        if (!solve6(J, qdot_meas)) return UBC_STEWART_FK_FAILED;
        /* controller */
        reference(c, t, qd);
        adapt = t >= c->t_adapt ? 1.0 : 0.0;
        set_slot(c, UBC_STEWART_SLOT_Q, st->q_meas, 6);
        set_slot(c, UBC_STEWART_SLOT_QDOT, qdot_meas, 6);
        set_slot(c, UBC_STEWART_SLOT_PC, pc_meas, 6);
        set_slot(c, UBC_STEWART_SLOT_L, l_meas, 6);
        set_slot(c, UBC_STEWART_SLOT_QD0, qd, 6);
        set_slot(c, UBC_STEWART_SLOT_QD1, qd + 6, 6);
        set_slot(c, UBC_STEWART_SLOT_QD2, qd + 12, 6);
        set_slot(c, UBC_STEWART_SLOT_QD3, qd + 18, 6);
        set_slot(c, UBC_STEWART_SLOT_XC, st->xc, c->n_xc);
        set_slot(c, UBC_STEWART_SLOT_ADAPT, &adapt, 1);
        if (c->ctrl((const double**)c->ctrl_arg, c->ctrl_res, c->ctrl_iw, c->ctrl_w, 0)) return UBC_STEWART_CTRL_FAILED;
        memcpy(u, c->ctrl_res[0], sizeof u);
        if (log) {
            if (log->t) log->t[st->k] = t;
            if (log->q) memcpy(log->q + 6 * st->k, x, 6 * sizeof(double));
            if (log->q_d) memcpy(log->q_d + 6 * st->k, qd, 6 * sizeof(double));
            if (log->l) memcpy(log->l + 6 * st->k, l_true, 6 * sizeof(double));
            if (log->pc) memcpy(log->pc + 6 * st->k, x + 12, 6 * sizeof(double));
            if (log->u) memcpy(log->u + 6 * st->k, u, 6 * sizeof(double));
            if (log->f)
                for (i = 0; i < 6; ++i)
                    log->f[6 * st->k + i] = x[12 + i] * 0.00114 - ps * 0.000633;
            if (log->xc && c->n_xc) memcpy(log->xc + c->n_xc * st->k, st->xc, (size_t)c->n_xc * sizeof(double));
        }
        /* plant, zero-order hold on u; 0 <= pc <= ps */
        for (j = 0; j < c->substeps; ++j) {
            if (!rk4(c, x, u, hs)) return UBC_STEWART_CTRL_FAILED;
            for (i = 12; i < 18; ++i) x[i] = clip(x[i], 0, ps);
        }
        /* controller state: Euler, kept inside the projection bounds */
        for (j = 0; j < c->n_xc; ++j)
            st->xc[j] = clip(st->xc[j] + h * c->ctrl_res[1][j], c->xc_lo[j], c->xc_hi[j]);
        /* a non-finite state stops the run with st->k at the period that produced it */
        for (i = 0; i < NX; ++i)
            if (!isfinite(x[i])) return UBC_STEWART_NONFINITE;
        for (j = 0; j < c->n_xc; ++j)
            if (!isfinite(st->xc[j])) return UBC_STEWART_NONFINITE;
        st->k += 1;
        st->t = (double)st->k * h;
    }
    return UBC_STEWART_OK;
}
