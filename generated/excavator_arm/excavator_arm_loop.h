/* Closed-loop driver for model excavator_arm: plant, sensors, joint encoders, controller.
 * Rendered by hydrogen from templates/loop.h.j2; plain C99, no dependency but libm.
 * Sizes: 3 coordinates, 3 cylinders; plant state x = [q, qdot, pc, spool, spool rate, ps] (19). */
#ifndef EXCAVATOR_ARM_LOOP_H
#define EXCAVATOR_ARM_LOOP_H

#ifdef __cplusplus
extern "C" {
#endif

#define EXCAVATOR_ARM_NQ 3   /* generalized coordinates */
#define EXCAVATOR_ARM_NL 3   /* cylinders */
#define EXCAVATOR_ARM_NX 19  /* plant state */
#define EXCAVATOR_ARM_NPC 6  /* pressure states (one block per actuator) */
#define EXCAVATOR_ARM_MAX_DELAY 8  /* longest computation delay, control periods */
#define EXCAVATOR_ARM_NPS 1  /* supply pressure states */
#define EXCAVATOR_ARM_NQE 3  /* joint encoders */
#define EXCAVATOR_ARM_NNOISE 13  /* noise row (hydrogen.sensors.NOISE): actuator travel (m or rad), pressure states (Pa), joint encoders (rad or m), supply pressure (Pa) */

typedef int (*excavator_arm_casadi_fn)(const double** arg, double** res, long long int* iw, double* w, int mem);

/* Input slots of a controller, in this order, in hg_loop_config.slot (-1: not an input). */
enum { EXCAVATOR_ARM_SLOT_Q, EXCAVATOR_ARM_SLOT_QDOT, EXCAVATOR_ARM_SLOT_PC, EXCAVATOR_ARM_SLOT_L, EXCAVATOR_ARM_SLOT_QD0, EXCAVATOR_ARM_SLOT_QD1, EXCAVATOR_ARM_SLOT_QD2, EXCAVATOR_ARM_SLOT_QD3, EXCAVATOR_ARM_SLOT_XC, EXCAVATOR_ARM_SLOT_ADAPT, EXCAVATOR_ARM_SLOT_U_APPLIED, EXCAVATOR_ARM_SLOT_PS, EXCAVATOR_ARM_N_SLOTS };

/* Return codes of excavator_arm_loop_run. */
enum { EXCAVATOR_ARM_OK = 0, EXCAVATOR_ARM_NONFINITE = 1, EXCAVATOR_ARM_FK_FAILED = 2, EXCAVATOR_ARM_CTRL_FAILED = 3 };

/* Outcomes of excavator_arm_forward_kinematics (hydrogen.layout.FK_STATUS). */
enum { EXCAVATOR_ARM_FK_SOLVED = 0, EXCAVATOR_ARM_FK_SINGULAR = 1, EXCAVATOR_ARM_FK_NOT_CONVERGED = 2, EXCAVATOR_ARM_FK_FUNCTION_FAILED = 3, EXCAVATOR_ARM_FK_VELOCITY_SINGULAR = 4 };

typedef struct {
    /* timing: control period h (s), plant RK4 sub-steps per control period (bound_stages != 0: the pressures
     * held within their bounds at every stage, else after each step), adaptation on for t >= t_adapt;
     * the command computed at period k is applied from t_k + (delay + delay_frac) h (delay 0..MAX_DELAY,
     * 0 <= delay_frac < 1, delay + delay_frac <= MAX_DELAY) */
    double h;
    long long substeps;
    long long bound_stages;
    double t_adapt;
    long long delay;
    double delay_frac;
    /* plant (SI): true theta (boom.mcx, boom.mcz, boom.Iyy, stick.mcx, stick.mcz, stick.Iyy, bucket.mcx, bucket.mcz, bucket.Iyy), gamma1 = beta and gamma2 = beta c per cylinder,
     * friction per actuator (in the actuator's own unit: its description's seal friction, else the rig's): [coulomb N or N m, viscous N s/m or N m s/rad, smooth_speed m/s or rad/s, breakaway N or N m, stribeck_speed m/s or rad/s, pressure_coefficient],
     * valve per actuator (its datasheet valve, else the rig's): [lag s, omega rad/s, zeta, overlap m, full_opening m] */
    const double* theta;
    const double* gamma1;
    const double* gamma2;
    const double* friction;
    const double* valve;
    /* sensors: each actuator's travel resolution quant_l (m or rad, its own unit; 0: none; rounded to its grid
     * after the noise); sensor_res, sensor_bias: each rig part's sensor's resolution (its unit, 0:
     * none) and constant offset, the sensed outputs' entries in order; fixed-gain Kalman filter on the actuators' travel (use_kalman != 0), gain [K_l, K_ldot] */
    const double* quant_l;
    const double* sensor_res;
    const double* sensor_bias;
    long long use_kalman;
    double kf_gain[2];
    /* reference: bias + minimum-jerk moves over moves (coordinate, distance, start, duration > 0),
     * plus sum of amplitude sin(2 pi f t) over terms (coordinate, amplitude, frequency),
     * plus a raw step of step_height on coordinate step_axis (>= 0) at t_step
     * (a coordinate outside 0..NQ-1 is ignored: the runtime refuses it before a run) */
    const double* bias;
    long long n_moves;
    const double* moves;
    long long n_terms;
    const double* terms;
    long long step_axis;
    double step_height;
    double t_step;
    /* controller: generated function, its argument/result tables, work vectors */
    excavator_arm_casadi_fn ctrl;
    double** ctrl_arg;
    double** ctrl_res;
    long long int* ctrl_iw;
    double* ctrl_w;
    /* with a state (n_xc > 0): its semi-implicit step, one call per period: arguments ctrl_arg's then
     * h, xc_lo, xc_hi (step_arg); results u (step_res[0] must be ctrl_res[0]) and the updated state.
     * The forward-Euler update takes the rate from the controller's own call (ctrl_res[1]).
     * slot: the loop's input slots in the controller's inputs; n_xc: the state size; xc_lo, xc_hi: its
     * projection bounds; xc_euler: 0 semi-implicit update, 1 forward Euler after the plant step */
    excavator_arm_casadi_fn step;
    double** step_arg;
    double** step_res;
    long long int* step_iw;
    double* step_w;
    long long slot[EXCAVATOR_ARM_N_SLOTS];
    long long n_xc;
    const double* xc_lo;
    const double* xc_hi;
    long long xc_euler;
    /* delay compensation (predict != 0, a scenario's predictor with a delay): the controller's inputs are
     * the state at t_k + (delay + delay_frac) h predicted from the measured one by the plant's model at
     * the controller's own parameters (theta, gamma1, gamma2 from xc at pred_theta_at, pred_gamma1_at,
     * pred_gamma2_at where >= 0, else pred_theta, pred_gamma1, pred_gamma2), ideal valve, no friction,
     * over the commands in flight (RK4, pred_substeps steps per period), and the reference at that time;
     * pred_x0: the plant state it starts from where it measures nothing (each part's declared initial value) */
    long long predict;
    long long pred_substeps;
    const double* pred_theta;
    const double* pred_gamma1;
    const double* pred_gamma2;
    long long pred_theta_at;
    long long pred_gamma1_at;
    long long pred_gamma2_at;
    const double* pred_x0;
    /* the description's numbers: bounds of each pressure state (Pa), the clip of the measurement and of
     * the plant; numbers: the input of every generated function of a library generated with the
     * description's numbers as inputs (the manifest's "numbers" names them; else one unused 0) */
    const double* p_low;
    const double* p_high;
    const double* numbers;
    /* supply (a robot with a supply state): supply_feedback != 0: the controller's ps input is the measured
     * (or predicted) supply pressure; 0: ps_nominal (Pa), the description's supply_pressure (a controller
     * assuming a constant supply) */
    long long supply_feedback;
    double ps_nominal;
    /* forward kinematics (Newton): tolerance (m), steps, largest condition number (1-norm) of JL */
    double fk_tol;
    long long fk_max_iter;
    double fk_max_cond;
} excavator_arm_loop_config;

typedef struct {
    double t;  /* s */
    long long k;  /* control periods done */
    double x[EXCAVATOR_ARM_NX];  /* plant: q, qdot, pc, spool, spool rate, ps */
    double q_meas[EXCAVATOR_ARM_NQ];  /* last measured pose (Newton's warm start) */
    double kf[2 * EXCAVATOR_ARM_NL];  /* Kalman state: cylinder lengths, cylinder rates */
    double u_hist[EXCAVATOR_ARM_MAX_DELAY * EXCAVATOR_ARM_NL];  /* commands of past periods: ring, slot k % MAX_DELAY (0 at reset) */
    double u_app[EXCAVATOR_ARM_NL];  /* commands the valves held over the last period, m (0 at reset): the
     * controller's u_applied input in its state update */
    double* xc;  /* controller state, n_xc entries */
    double fk_info[4];  /* the last failed forward kinematics or velocity solve (written when it fails): outcome
     * (<MODEL>_FK_...), residual (m), JL's condition number (1-norm), Newton steps */
    double fk_l[EXCAVATOR_ARM_NL];  /* the cylinder lengths (m) forward kinematics failed for (q_meas: its last iterate) */
} excavator_arm_loop_state;

typedef struct {                 /* each may be NULL; rows per control period (widths below) */
    double* t;  /* 1: time of the period's start, s */
    double* q;  /* 3: true pose, m or rad */
    double* q_d;  /* 3: reference, m or rad */
    double* l;  /* 3: true actuator travel (cylinder lengths), m or rad */
    double* f;  /* 3: actuator forces of the chamber pressures, N or N m */
    double* pc;  /* 6: pressure states (a three-way cylinder's control pressure, the others' chambers), Pa */
    double* u;  /* 3: spool commands computed, m */
    double* u_applied;  /* 3: spool commands the valves held at the end of each period (delay later), m */
    double* l_meas;  /* 3: measured actuator travel (noise, resolution), m or rad */
    double* ldot;  /* 3: actuator rates the velocities came from (the estimator's, or the ideal rate sensor's), m/s or rad/s */
    double* qdot_meas;  /* 3: measured velocities (JL^-1 ldot at the measured pose), m/s or rad/s */
    double* xc;  /* n_xc: controller state, per block */
    double* ps;  /* 1: supply pressure (a state only where the supply is not constant), Pa */
} excavator_arm_loop_log;

/* One control period's signals, as the stages below hand them on (SI units). */
typedef struct {
    double t;  /* time of the period's start, s */
    double l_true[EXCAVATOR_ARM_NL];  /* true cylinder lengths, m */
    double l_meas[EXCAVATOR_ARM_NL];  /* measured cylinder lengths (noise, resolution), m */
    double pc_meas[EXCAVATOR_ARM_NPC];  /* measured pressures, Pa */
    double ps_meas[EXCAVATOR_ARM_NPS];  /* measured supply pressure, Pa (a [supply] state's only) */
    double q_enc[EXCAVATOR_ARM_NQE];  /* joint encoders' reading, rad or m (joint encoders only) */
    double ldot[EXCAVATOR_ARM_NL];  /* cylinder rates: the selected estimator's, or the ideal rate sensor's, m/s */
    double qdot_meas[EXCAVATOR_ARM_NQ];  /* measured velocities, JL^-1 ldot at the measured pose */
    double qd[4 * EXCAVATOR_ARM_NQ];  /* reference and its first three time derivatives */
    double u[EXCAVATOR_ARM_NL];  /* spool commands computed this period, m */
    double u_held[EXCAVATOR_ARM_NL];  /* spool commands the valves hold over the period's first delay_frac h, m */
    double u_app[EXCAVATOR_ARM_NL];  /* spool commands applied over the rest of the period (computation delay), m */
} excavator_arm_loop_signals;

/* Advance n control periods from st. noise: n rows of NNOISE for this call, or NULL. Logs are
 * written at row st->k (periods since the start of the run), so each log needs at least st->k + n
 * rows. Returns EXCAVATOR_ARM_OK, or a code with st->k at the failing period (its log row holds the state
 * before the failing step). Each period is the stages below, in this order: measure, estimate,
 * reference, control, (logs), plant_step, control_advance; then st->k += 1. */
int excavator_arm_loop_run(const excavator_arm_loop_config* cfg, excavator_arm_loop_state* st, long long n,
                     const double* noise, excavator_arm_loop_log* log);

/* Sensors: the readings of the plant state st->x at period st->k (s->t = k h): true and measured
 * cylinder lengths (noise row nz, or NULL, then the resolution), measured pressures (clipped to
 * their bounds when noisy), joint encoders (s->q_enc), and without the Kalman filter the ideal
 * cylinder-rate sensor's s->ldot = JL qdot. */
int excavator_arm_measure(const excavator_arm_loop_config* cfg, const excavator_arm_loop_state* st, const double* nz,
                    excavator_arm_loop_signals* s);

/* The length sensor alone: l plus noise nz (NL entries, or NULL), rounded to each one's resolution quant_l. */
void excavator_arm_sense_lengths(const excavator_arm_loop_config* cfg, const double* l, const double* nz, double* l_meas);

/* Estimation from the measured signals: the Kalman filter on s->l_meas (state st->kf) gives s->ldot
 * (use_kalman; else s->ldot is the rate sensor's), the pose st->q_meas (the joint encoders' s->q_enc),
 * and s->qdot_meas = JL^-1 s->ldot at that pose. */
int excavator_arm_estimate(const excavator_arm_loop_config* cfg, excavator_arm_loop_state* st, excavator_arm_loop_signals* s);

/* The scenario's reference at t (s): qd = [q_d, its first, second and third derivatives] (4 x NQ). */
void excavator_arm_reference(const excavator_arm_loop_config* cfg, double t, double* qd);

/* Control at s->t: the controller's inputs from st and s (s->qd the reference), the controller
 * state's semi-implicit update and the command s->u; the command of cfg->delay periods ago into
 * s->u_app and st->u_app (the ring st->u_hist keeps this one), the last period's st->u_app into
 * s->u_held. */
int excavator_arm_control(const excavator_arm_loop_config* cfg, excavator_arm_loop_state* st, excavator_arm_loop_signals* s);

/* After the period: the controller state's forward-Euler update (cfg->xc_euler), clipped to its
 * bounds; EXCAVATOR_ARM_NONFINITE if the state is not finite. */
int excavator_arm_control_advance(const excavator_arm_loop_config* cfg, excavator_arm_loop_state* st);

/* Plant: cfg->substeps RK4 sub-steps over one control period, holding u_held (NL, m) over its first
 * cfg->delay_frac h and u_app over the rest (sub-steps shared out over the two parts), each pressure
 * clipped to its bounds after each; EXCAVATOR_ARM_NONFINITE if the plant state is not finite after them. */
int excavator_arm_plant_step(const excavator_arm_loop_config* cfg, excavator_arm_loop_state* st, const double* u_held,
                       const double* u_app);

/* Cylinder lengths (m) of n poses: row k of q (NQ) gives row k of l (NL). One call for a whole
 * trajectory (workspace checks). numbers: the description's numbers (the generated functions' input).
 * Returns 0, or 1 if the generated function failed. */
int excavator_arm_leg_lengths_many(const double* numbers, const double* q, long long n, double* l);

/* Forward kinematics, the loop's own: Newton's method for the pose q (NQ) whose cylinder lengths are
 * l_meas (NL, m), from q (updated in place; on failure its last iterate). It stops when every length is
 * within tol (m) or after max_iter steps (EXCAVATOR_ARM_FK_NOT_CONVERGED); a step needs JL's condition number
 * (1-norm) at most max_cond (EXCAVATOR_ARM_FK_SINGULAR). Returns a EXCAVATOR_ARM_FK_ outcome; info (3 numbers, or
 * NULL): the residual max |l(q) - l_meas| (m) at q, JL's condition number there (NaN when not computed,
 * inf when a pivot vanishes) and the steps taken. numbers: as for excavator_arm_leg_lengths_many. */
int excavator_arm_forward_kinematics(const double* numbers, const double* l_meas, double* q, double tol,
                               long long max_iter, double max_cond, double* info);

/* Forward kinematics of n samples: row k of l_meas (NL) gives row k of q (NQ), each started from the
 * pose of the row before (row 0 from q0). Returns n, or the first sample k that failed (EXCAVATOR_ARM_FK_
 * outcome in *status, its last iterate in row k of q, info as for excavator_arm_forward_kinematics). */
long long excavator_arm_forward_kinematics_many(const double* numbers, const double* l_meas, long long n,
                                          const double* q0, double tol, long long max_iter, double max_cond,
                                          double* q, int* status, double* info);

#ifdef __cplusplus
}
#endif
#endif
