"""The plant's integration between control instants, written once for the two loops: RK4 steps of the
fused plant rate holding a command, each pressure held within its bounds (0 <= p_c <= p_s for a
three-way cylinder; a chamber that would cavitate stays at 0), and how a period's sub-steps are shared
out around a command switch inside it (a computation delay of a fraction of a period).

- **numpy** (:func:`bounded_steps`, :func:`period_pieces`, :func:`predictor_steps`): the Python
  engine's plant and delay predictor (:mod:`hydrogen.simulation.simulator`).
- **C** (:data:`C_FUNCTIONS`, :data:`C_PERIOD`, :data:`C_PREDICTOR_STEPS`): the same operations in the
  same order, rendered into the loop driver (``templates/loop.c.j2``, through
  :func:`hydrogen.layout.loop_context`), so the two loops agree to the bit.

The pressures are held in one of two ways (the scenario's ``pressure_bounds``): after each step only,
or also at every stage ("stage": a stage's pressures are clipped and a pressure at a bound does not
rate past it, which keeps RK4's order where a pressure rests on a bound). Plain numpy at import.
"""
from __future__ import annotations

import math
from string import Template

import numpy as np

from ..setting import setting

__all__ = ["SCENARIO_SETTINGS", "rk4", "bounded_steps", "period_pieces", "predictor_steps", "c_functions", "C_FUNCTIONS", "C_PERIOD",
           "C_PREDICTOR_STEPS"]


#: How a scenario integrates its plant (:mod:`hydrogen.scenario_settings`).
SCENARIO_SETTINGS = {
    "substeps": setting(None, "", "RK4 plant steps per control period"),
    "pressure_bounds": setting("stage", "", 'how the plant holds each pressure within its bounds (a chamber '
                               'that would cavitate stays at 0): "stage" clips at every RK4 stage, where a '
                               'pressure at a bound does not rate past it (RK4 keeps its order); "step" only '
                               'after each step (first order where a pressure rests on a bound)'),
}


def rk4(rhs, x, h):
    """One classical RK4 step of ``h`` (s) of ``x' = rhs(x)`` (a new array)."""
    k1 = rhs(x)
    k2 = rhs(x + 0.5 * h * k1)
    k3 = rhs(x + 0.5 * h * k2)
    k4 = rhs(x + h * k3)
    return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


def bounded_steps(rhs, x, n, h, pc, lo, hi, stages: bool):
    """``n`` RK4 steps of ``h`` (s) of the plant rate ``rhs`` from ``x`` (a new array), its pressures
    ``x[pc]`` (Pa) held within [``lo``, ``hi``]: each step's result clipped and, with ``stages``, at every
    stage the pressures clipped and one at a bound not rating past it (the C's ``hold``, ``rk4`` and
    ``stage_rate``)."""
    def rate(y):
        y = y.copy()
        p = np.clip(y[pc], lo, hi)
        y[pc] = p
        r = np.array(rhs(y), float).ravel()
        rp = r[pc]
        rp[((p <= lo) & (rp < 0)) | ((p >= hi) & (rp > 0))] = 0.0
        r[pc] = rp
        return r

    for _ in range(n):
        x = rk4(rate if stages else rhs, x, h)
        np.clip(x[pc], lo, hi, out=x[pc])  # e.g. 0 ≤ p_c ≤ p_s
    return x


def period_pieces(substeps: int, frac: float, h: float) -> tuple:
    """The pieces of one control period of ``h`` (s) at ``substeps`` RK4 sub-steps whose command
    switches at ``frac`` h (0 <= frac < 1; 0: no switch): ``((steps, step length), ...)``, the piece before
    the switch first. Each piece takes enough sub-steps that none is longer than h / substeps (the step
    the valve's stability check assumes), at least one (the C's ``C_PERIOD``)."""
    if frac > 0:
        n1, n2 = max(math.ceil(frac * substeps), 1), max(math.ceil((1.0 - frac) * substeps), 1)
        return (n1, frac * h / n1), (n2, (1.0 - frac) * h / n2)
    return ((substeps, h / substeps),)


def predictor_steps(periods: float, predictor_substeps: int) -> int:
    """RK4 steps the delay predictor takes over ``periods`` control periods of one held command: no step
    longer than a period / ``predictor_substeps``, at least one (the C's ``C_PREDICTOR_STEPS``)."""
    return max(math.ceil(periods * predictor_substeps - 1e-9), 1)


#: The loop driver's integration functions (``$pc``: the index prefix of the pressure states in x, e.g.
#: ``2 * NQ + ``; ``rhs_params`` and ``plant_rhs`` are the driver's): ``clip``, ``stage_rate`` (the plant's
#: rate at a stage, the pressures held with ``bound_stages``), ``rk4`` and ``hold`` (n steps holding u,
#: each result's pressures clipped), :func:`bounded_steps`'s operations in its order.
C_FUNCTIONS = Template("""\
static double clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* The plant's rate at a stage y of a step. With bound_stages its pressures are held within their
 * bounds as each step's clip holds the state (0 <= p_c <= p_s for a three-way cylinder; a chamber that
 * would cavitate stays at 0): y's pressures are clipped, and a pressure at a bound does not rate past
 * it. The clip after the step alone lets the stages see pressures past their bounds: an error of first
 * order in the step wherever a pressure rests on one. y may be changed. */
static int stage_rate(const rhs_params* m, double* y, const double* u, double* k) {
    int i;
    if (!m->bound_stages) return plant_rhs(m, y, u, k);
    for (i = 0; i < NPC; ++i) y[${pc}i] = clip(y[${pc}i], m->p_low[i], m->p_high[i]);
    if (plant_rhs(m, y, u, k)) return 1;
    for (i = 0; i < NPC; ++i) {
        const double p = y[${pc}i], r = k[${pc}i];
        if ((p <= m->p_low[i] && r < 0) || (p >= m->p_high[i] && r > 0)) k[${pc}i] = 0;
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
        for (i = 0; i < NPC; ++i) x[${pc}i] = clip(x[${pc}i], m->p_low[i], m->p_high[i]);
    }
    return 1;
}
""")

#: The loop driver's plant over one period (:func:`period_pieces`'s pieces, each :data:`C_FUNCTIONS`'
#: ``hold``): statements of its plant step, over ``m``, ``x``, ``n`` (the sub-steps), ``u_held`` and
#: ``u_app`` and the configuration ``c``; ``$failed``: the status it returns when a step fails.
C_PERIOD = Template("""\
    if (c->delay_frac > 0) {
        /* the command switches at delay_frac h: each part takes enough sub-steps that none is longer
         * than h / substeps (the step the valve's stability check assumes) */
        long long n1 = (long long)ceil(c->delay_frac * (double)n), n2 = (long long)ceil((1.0 - c->delay_frac) * (double)n);
        if (n1 < 1) n1 = 1;
        if (n2 < 1) n2 = 1;
        if (!hold(&m, x, u_held, n1, c->delay_frac * c->h / (double)n1)) return ${failed};
        if (!hold(&m, x, u_app, n2, (1.0 - c->delay_frac) * c->h / (double)n2)) return ${failed};
    } else if (!hold(&m, x, u_app, n, c->h / (double)n)) {
        return ${failed};
    }
""")

#: The loop driver's count of the predictor's steps over ``dt`` (s) (:func:`predictor_steps`): ``n``.
C_PREDICTOR_STEPS = """\
    long long n = (long long)ceil(dt / c->h * (double)c->pred_substeps - 1e-9);
    if (n < 1) n = 1;
"""


def c_functions(pc: str) -> str:
    """:data:`C_FUNCTIONS` for a plant state whose pressures start at index prefix ``pc`` (C text)."""
    return C_FUNCTIONS.substitute(pc=pc)
