"""The closed loop: plant (RK4 sub-steps), sensors, forward kinematics, controller at a fixed rate."""
from __future__ import annotations

import functools
import json
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .. import diagram, pressures
from ..actuators import actuator
from ..controllers import spec as controller_spec
from ..dynamics import VELOCITY_SINGULAR, fk_failure
from ..errors import KinematicsError, RunEndedError, ScenarioError, SimulationError
from ..estimators import designs_for, estimate_for, remember as remember_designs
from ..estimators.kalman import kalman_gain, length_noise_variance  # noqa: F401 - the simulator's API
from ..layout import LU_PIVOT_MIN, SUPPLY_LOG, log_rows, model_summary, plant_ports, plant_sensors, robot_sizes
from ..loop_logs import FORCES, LOGS, PLANT, SIGNAL
from ..plant import (describe_entries, initial_state, input_values, integrator, outputs as plant_outputs, plant_inputs,
                     plant_layout, sensor_numbers, slot)
from ..plant.supply import nominal as supply_nominal
from ..sensors import NOISE, noise_columns
from ..summary import SATURATED_AT, SATURATION, estimated_blocks  # saturation: defined with its line
from .checks import _shown, check_against_model, check_run_size, checked_float, metric_window
from .control import make_controller
from .pool import _ENTRY_KEYS, _error, _outcome, check_workers, entry_problem, run_sweep
from .scenarios import Scenario, actuator_settings, scenario as named_scenario, scenario_names
from .seeds import SeedResults

__all__ = ["simulate", "SimulationResult", "SeedResults", "equilibrium_pressures", "start_state", "Stepper", "prepare_run", "new_logs",
           "make_runner", "run_python_loop", "Batch", "RunPlan", "plan_run", "run_prepared", "PythonStages",
           "kalman_gain",
           "length_noise_variance", "excitation", "diverged_block", "SATURATED_AT", "SATURATION"]


@dataclass
class SimulationResult:
    """Time series (one row per control period) and metrics of one run. SI units; q in the model's
    generalized coordinates (``coordinates``), cylinder quantities one column per cylinder."""

    scenario: Scenario     # the scenario actually run (overrides applied); its name: scenario_name
    controller: str
    t: np.ndarray
    q: np.ndarray
    q_d: np.ndarray
    leg_lengths: np.ndarray
    leg_forces: np.ndarray
    pressures: np.ndarray
    u: np.ndarray            # commands as computed at each period
    u_applied: np.ndarray    # commands the valves held at the end of each period (``delay`` later)
    leg_lengths_measured: np.ndarray  # cylinder lengths as the sensors gave them (noise, quantisation)
    theta_hat: np.ndarray
    gamma1_hat: np.ndarray
    gamma2_hat: np.ndarray
    theta_true: np.ndarray
    gamma_true: np.ndarray
    amplitude: np.ndarray
    metric_start: float
    coordinates: tuple = ()
    units: tuple = ()
    theta_names: tuple = ()
    #: The estimate blocks the controller declares in its state (theta_hat, gamma1_hat, gamma2_hat);
    #: empty for a controller that adapts nothing, whose theta_hat/gamma*_hat rows are the fixed values.
    estimated: tuple = ()
    wall_time_s: float = 0.0  # the run: setup, loop, result, with the library already loaded (s)
    loop_wall_s: float = 0.0  # the closed loop alone (s)
    u_max: float = 0.0
    actuators: tuple = ()     # the actuators' names, in the order of the columns of u
    metrics: dict = field(default_factory=dict)
    #: Every block of the controller's state as it declares it, by name: its rows (k, size) over the run,
    #: in the block's own unit (the estimates above too, where the controller holds them).
    states: dict = field(default_factory=dict)
    #: The plant's outputs (:attr:`hydrogen.plant.PlantState.output`), by part name: rows (k, size) over
    #: the run in the part's unit (the supply pressure "ps" where it is a state, a rig part's own).
    plant: dict = field(default_factory=dict)
    #: The supply pressure p_s (k,), Pa, where the supply is a plant state (a pump); None for a
    #: constant supply (each actuator's supply_pressure).
    supply_pressure: np.ndarray = None
    #: The name of the robot's model the run simulated ("" where not known).
    model_name: str = ""
    #: The loop's other logs (:data:`hydrogen.loop_logs.LOGS` without a field above), by name: rows
    #: (k, size) over the run (``ldot``: the actuator rates the velocities came from, ``qdot_meas``: the
    #: measured velocities; ``<output>_meas``: a rig part's sensor's reading, where it declares one).
    signals: dict = field(default_factory=dict)

    @property
    def scenario_name(self) -> str:
        """Name of the scenario run."""
        return self.scenario.name

    @property
    def error(self) -> np.ndarray:
        """Tracking error q − q_d, (k, n)."""
        return self.q - self.q_d

    def compute_metrics(self) -> dict:
        """Max error in % of each coordinate's reference amplitude (None where it has none), RMS error,
        final parameter estimates, over t ≥ metric_start; and over the whole run the fraction of
        periods with a saturated valve (|u| ≥ SATURATED_AT × u_max): ``u_saturation_frac`` over every
        valve and period, ``u_saturation_frac_by_actuator`` per actuator; with a periodic reference,
        the high-frequency error's RMS ``hf_error_rms`` and its worst short window ``hf_error_burst``
        (m or rad), which starts at ``hf_error_burst_t`` (s); where the supply is a state (a pump),
        ``supply_pressure``: its ``min``, ``max`` and ``final`` value over the whole run (Pa)."""
        sel, start, note = metric_window(self.t, self.metric_start)  # clamped to the run, and said so
        e = self.error[sel]
        n = self.q.shape[1]
        coords = self.coordinates or tuple(f"q{i}" for i in range(n))
        max_abs = np.abs(e).max(axis=0) if len(e) else np.full(n, np.nan)
        rms = np.sqrt((e ** 2).mean(axis=0)) if len(e) else np.full(n, np.nan)
        pct = {c: (float(100 * m / a) if a > 0 else None) for c, m, a in zip(coords, max_abs, self.amplitude)}
        self.metrics = {
            "scenario": self.scenario_name, "controller": self.controller,
            "max_error_pct": pct,
            "amplitude": dict(zip(coords, map(float, self.amplitude))),
            "max_error": dict(zip(coords, map(float, max_abs))),
            "rms_error": dict(zip(coords, map(float, rms))),
            "theta_names": list(self.theta_names),
            "theta_hat_final": self.theta_hat[-1].tolist(),
            "theta_true": self.theta_true.tolist(),
            # a parameter whose true value is 0 (a sideways first moment) has an absolute error only
            "theta_error_final": (self.theta_hat[-1] - self.theta_true).tolist(),
            "theta_error_pct_final": [100 * (e - t) / t if t != 0 else None
                                      for e, t in zip(self.theta_hat[-1].tolist(), self.theta_true.tolist())],
            "gamma_hat_final": [self.gamma1_hat[-1].tolist(), self.gamma2_hat[-1].tolist()],
            "gamma_true": self.gamma_true.tolist(),
            "sim_time_s": float(self.t[-1] - self.t[0]) if len(self.t) else 0.0,
            "wall_time_s": float(self.wall_time_s),
            "loop_wall_s": float(self.loop_wall_s),
            "metric_start_s": start,
        }
        # over the whole run: a valve held at its stop during the start is a valve too small too
        sat = (np.abs(self.u) >= SATURATED_AT * self.u_max) if self.u_max else np.zeros(np.shape(self.u), bool)
        names = self.actuators or tuple(f"u{i}" for i in range(np.shape(self.u)[1]))
        self.metrics["u_saturation_frac"] = float(sat.mean()) if sat.size else 0.0
        self.metrics["u_saturation_frac_by_actuator"] = {
            c: float(v) for c, v in zip(names, sat.mean(axis=0) if len(sat) else np.zeros(len(names)))}
        pair = self._high_passed_pair()  # both high-passed errors at once: one filter of the window
        if pair is not None:
            hp, hp_ends, h, f_cut = pair
            self.metrics["hf_error_rms"] = dict(zip(coords, map(float, np.sqrt((hp ** 2).mean(axis=0)))))
            burst, at = self._burst(hp_ends, h, f_cut)  # a window at an end of the run: no ringing of the wrap
            self.metrics["hf_error_burst"] = dict(zip(coords, map(float, burst)))
            self.metrics["hf_error_burst_t"] = dict(zip(coords, map(float, at)))
        if self.supply_pressure is not None and len(self.supply_pressure):
            ps = np.asarray(self.supply_pressure, float)
            self.metrics["supply_pressure"] = {"min": float(ps.min()), "max": float(ps.max()), "final": float(ps[-1])}
        # a coordinate whose reference has an amplitude but does not move in the run (a step after its
        # end): its error is a share of an amplitude the run never asked for
        still = [c for c, a, col in zip(coords, self.amplitude, np.asarray(self.q_d).T)
                 if a > 0 and len(col) and np.ptp(col) == 0]
        if still:
            end = float(self.t[-1]) if len(self.t) else 0.0
            note = "; ".join(filter(None, [note, (
                f"the reference of {', '.join(still)} does not move within the run (t <= {end:g} s): its max error "
                "in % is of an amplitude the run never reaches")]))
        if note:
            self.metrics["metric_note"] = note
        return self.metrics

    #: An error component above this many times the reference's highest frequency is an oscillation
    #: of the loop, not tracking lag or its harmonics (hydrogen.simulation.tuning).
    HF_FACTOR = 5.0
    #: The window of the burst metric (high_frequency_burst), in periods of that cut-off: 2 periods
    #: of the slowest content counted (0.4 s at a 1 Hz reference), as short as the bursts seen on
    #: the rig (0.2-0.4 s of a 20-30 Hz ripple), which the 4 s average dilutes 10-20 times, and long
    #: enough to hold whole cycles of the ripple, so that its RMS is a level, not one noise peak.
    BURST_PERIODS = 2.0

    def _high_passed_pair(self):
        """(e_hp, e_hp_ends, h, f_cut): the error over t ≥ metric_start less its content at or below
        f_cut = HF_FACTOR × the reference's highest frequency (m or rad; h the period, s), and the same
        of the error less the line through its first and last samples (``ends``: so that the
        transform's periodic extension has no step where the window wraps, a step's content above
        f_cut would ring at the ends); None for a reference without frequencies (a step) or a window
        shorter than 8 periods. The filter is linear: the second is the first less the filtered line."""
        ref = getattr(self.scenario, "reference", None)
        f_max = max((abs(f) for f in ref.frequencies()), default=0.0) if ref is not None else 0.0
        sel, _, _ = metric_window(self.t, self.metric_start)
        e = self.error[sel]
        if f_max <= 0 or len(e) < 8:
            return None
        h, k = float(self.t[1] - self.t[0]), len(e)
        f_cut = self.HF_FACTOR * f_max
        kept = int(np.count_nonzero(np.fft.rfftfreq(k, h) <= f_cut))  # bins 0..kept-1 removed
        low = _low_bins(k, kept)
        if low is None:
            spec = np.fft.rfft(np.column_stack([e, np.arange(k) / (k - 1)]), axis=0)
            spec[:kept] = 0
            hp = np.fft.irfft(spec, n=k, axis=0)
            hp, ramp = hp[:, :-1], hp[:, -1]
        else:
            basis, ramp = low
            e = e - e.mean(axis=0)
            hp = e - basis @ (basis.T @ e)
        return hp, hp - np.outer(ramp, e[-1] - e[0]), h, f_cut

    def _high_passed(self, ends: bool = False):
        """(e_hp (k, n), h, f_cut) of :meth:`_high_passed_pair` (``ends``: its second), or None."""
        pair = self._high_passed_pair()
        return None if pair is None else (pair[1] if ends else pair[0], pair[2], pair[3])

    def high_frequency_error(self):
        """RMS (n,) over t ≥ metric_start of the error's content above HF_FACTOR × the reference's highest
        frequency (m or rad): where an oscillation of the loop shows first. None for a reference without
        frequencies (a step) or a window shorter than 8 periods."""
        hp = self._high_passed()
        return None if hp is None else np.sqrt((hp[0] ** 2).mean(axis=0))

    def high_frequency_burst(self):
        """(rms (n,), t (n,)): per coordinate the largest RMS of the same high-passed error as
        :meth:`high_frequency_error` over any window of BURST_PERIODS periods of the cut-off (m or
        rad), and the time its window starts (s): a burst of oscillation that a 4 s average dilutes.
        None where :meth:`high_frequency_error` is."""
        hp = self._high_passed(ends=True)  # a window at an end of the run: no ringing of the wrap
        return None if hp is None else self._burst(*hp)

    def _burst(self, e, h, f_cut):
        w = int(min(len(e), max(1, round(self.BURST_PERIODS / (f_cut * h)))))
        c = np.concatenate([np.zeros((1, e.shape[1])), np.cumsum(e ** 2, axis=0)])
        ms = np.maximum(c[w:] - c[:-w], 0.0) / w  # the running sum's differences: a mean square per window
        i = ms.argmax(axis=0)
        start = self.t[metric_window(self.t, self.metric_start)[0]][i]
        return np.sqrt(ms[i, np.arange(e.shape[1])]), start

    def to_json(self) -> str:
        """The metrics (:meth:`compute_metrics`) as indented JSON text, SI units and % as named."""
        return json.dumps(self.metrics or self.compute_metrics(), indent=2, sort_keys=True)

    def save_log(self, path, noise_l: float = 0.0, noise_p: float = 0.0, seed: int = 0):
        """Write the run as a rig log CSV for :func:`hydrogen.identify` (columns t, l*, pc*, ps0 where the
        supply is a state, u*, q*),
        with white sensor noise of std ``noise_l`` m and ``noise_p`` Pa added: see :mod:`hydrogen.logs`."""
        from ..logs import log_from_result, write_log
        return write_log(log_from_result(self, noise_l, noise_p, seed), path)


#: The most doubles :func:`_low_bins` keeps in one basis; a larger one is left to the FFT.
_LOW_BINS_MAX = 1 << 21


@functools.lru_cache(maxsize=8)
def _low_bins(k: int, kept: int):
    """(basis, ramp): an orthonormal basis (k, 2 kept - 1) of the first ``kept`` DFT bins of a real signal
    of ``k`` samples (the constant, then a cosine and a sine per bin) and the line 0..1 over the ``k``
    samples less its projection on them; None where the projection would cost
    more than the transform (many bins, a Nyquist bin, a basis over :data:`_LOW_BINS_MAX` doubles).
    Removing the projection on it is zeroing those bins of the rfft and transforming back, to rounding,
    at a fraction of the cost: the metric window's usual length (2^m + 1 samples) is a slow FFT size,
    and the sweeps compute the high-passed error of every run."""
    cols = 2 * kept - 1
    if kept < 1 or 2 * kept > k // 4 or k * cols > _LOW_BINS_MAX:
        return None
    phase = 2.0 * np.pi * np.outer(np.arange(k), np.arange(1, kept)) / k
    basis = np.hstack([np.ones((k, 1)), np.sqrt(2.0) * np.cos(phase), np.sqrt(2.0) * np.sin(phase)]) / np.sqrt(k)
    ramp = np.arange(k) / (k - 1)
    ramp = ramp - basis @ (basis.T @ ramp)  # the line 0..1 over the window, filtered
    for a in (basis, ramp):
        a.setflags(write=False)  # shared by every run of that window: read only
    return basis, ramp


#: The share of the weight's joint force a start state's rest force may leave unbalanced: rounding
#: leaves ~1e-15; a rig part pushing at rest (a counterbalance) far more, which the start pressures
#: then take up too.
REST_TOLERANCE = 1e-9


def start_state(dyn, sc, q0) -> tuple:
    """(pressures, x) where a run of scenario ``sc`` starts: at rest at pose ``q0``, the valves closed,
    every other part at its declared initial value, the pressures holding the robot still against
    gravity and against what the plant's other blocks push with at rest (a counterbalance; found from
    the generated plant's acceleration there, and taken up where it exceeds :data:`REST_TOLERANCE` of
    the weight's joint force). One linear step: exact where that push does not depend on the pressures
    and the pressures it takes stay within their bounds."""
    model = dyn.model
    layout = plant_layout(model)
    JLt, G = dyn.leg_jacobian(q0).T, dyn.gravity(q0, model.theta)
    f = np.linalg.solve(JLt, G)
    x0 = initial_state(layout, sc, q=q0, pc=pressures.equilibrium(model, f))
    inputs = [v.ravel() for v in input_values(sc, model).values()]
    xdot = np.asarray(dyn.functions["plant_rhs"](x0, np.zeros(model.n_cylinders), model.theta, *model.gamma,
                                                 *inputs), float).ravel()
    push = dyn.mass_matrix(q0, model.theta) @ xdot[slot(layout, "qdot").slice]  # JL^T f_parts at rest
    if np.max(np.abs(push)) > REST_TOLERANCE * max(float(np.max(np.abs(G))), 1.0):
        x0 = initial_state(layout, sc, q=q0, pc=pressures.equilibrium(model, f - np.linalg.solve(JLt, push)))
    return x0[slot(layout, "pc").slice].copy(), x0


def equilibrium_pressures(dyn, q, theta) -> np.ndarray:
    """The pressure vector (Pa, :mod:`hydrogen.pressures`) whose forces hold the robot still at q:
    (JL)ᵀ f = G, each actuator's pressures its kind's ``equilibrium_pressures``."""
    f = np.linalg.solve(dyn.leg_jacobian(q).T, dyn.gravity(q, theta))
    return pressures.equilibrium(dyn.model, f)


def simulate(dyn, scenario, controller: str, *, gains=None, duration=None, check_workspace=True,
             engine: str = "c", seeds=None, executor=None, max_workers=None, **overrides):
    """Run ``controller`` on ``scenario`` (a name or a :class:`Scenario`) with compiled dynamics ``dyn``.

    ``engine="c"`` (default) runs the whole loop in the compiled C driver;
    ``engine="python"`` runs the same loop step by step in Python (the slow
    reference: same sensors, same noise samples). ``overrides`` replace scenario
    fields (e.g. ``t_adapt=1.0``). A run whose state becomes non-finite raises
    :class:`~hydrogen.errors.SimulationError` naming the time and the state;
    ``err.result`` holds the partial result.

    ``seeds`` (a count N: noise seeds 0..N-1, or a list of seeds): one run per seed (the scenario
    field ``seed``), through :func:`~hydrogen.simulation.sweep.sweep` (a process pool of
    ``max_workers``, or ``executor``; the workers load ``dyn.model``'s library through
    :func:`hydrogen.build`'s defaults), returning a :class:`~hydrogen.simulation.seeds.SeedResults`:
    the per-seed results and the median, min and max of each metric. A seed whose run diverges is
    listed in its ``failures`` (the others still count); bad arguments raise before any run.
    """
    if seeds is not None:
        return _simulate_seeds(dyn, scenario, controller, seeds, executor, max_workers,
                               dict(gains=gains, duration=duration, check_workspace=check_workspace,
                                    engine=engine), overrides)
    if executor is not None or max_workers is not None:
        from ..errors import ScenarioError
        raise ScenarioError("simulate: executor and max_workers spread runs over seeds; pass seeds= too "
                            "(one run without seeds runs in this process)")
    call_start = time.perf_counter()
    p = prepare_run(dyn, scenario, controller, gains, duration, check_workspace, overrides)
    if engine not in ("c", "python"):
        raise ValueError(f"engine must be 'c' or 'python', not {engine!r}")
    return run_prepared(dyn, p, controller, engine, call_start)


def run_prepared(dyn, p, controller: str, engine: str = "c", call_start=None, runner=None):
    """The closed loop of a prepared run ``p`` (:func:`prepare_run`) on ``engine``, its result and metrics:
    :func:`simulate` after its checks (a :class:`SimulationError` with the partial result when the run
    diverges). ``call_start``: :func:`time.perf_counter` at the call's start (the result's
    ``wall_time_s`` counts from it); ``runner``: a C-loop runner of ``p.ctrl`` already reset to ``p``'s
    start (:meth:`Batch.run` keeps one per gain set), else one is made."""
    call_start = time.perf_counter() if call_start is None else call_start
    sc, ctrl, n, h = p.sc, p.ctrl, p.n, p.h
    log = new_logs(dyn.model, n, ctrl.xc.size, p.log_widths)
    if engine != "c":
        ctrl.rates_fn  # noqa: B018 - its library loaded (compiled the first time) before the loop is timed
    start = time.perf_counter()
    if engine == "c":
        k_done, failure = _run_c(dyn, sc, ctrl, p.x0, p.q0, p.noise, p.estimate, log, n, h, runner)
    else:
        k_done, failure = run_python_loop(dyn, sc, ctrl, p.x0, p.q0, p.noise, p.estimate, log, n, h)
    wall = time.perf_counter() - start
    theta_true, gamma_true = (dyn.model.theta, dyn.model.gamma) if p.truth is None else (a.copy() for a in p.truth)
    res = _result(sc, controller, ctrl, log, k_done, p.theta0, p.gamma0, theta_true, gamma_true, wall)
    # how well the run excites what the controller estimates (none: no metric); not of a run that
    # diverged, whose last row may hold the non-finite state it stopped at
    if res.metrics and res.estimated and not failure:
        res.metrics["excitation"] = excitation(dyn, res, ctrl)
    res.wall_time_s = time.perf_counter() - call_start
    if res.metrics:
        res.metrics["wall_time_s"] = res.wall_time_s
    if failure:
        cause = diverged_block(ctrl, log["xc"][:k_done], log["t"][:k_done, 0]) if ctrl.xc.size else None
        lead = f": {cause}; then it" if cause else ""  # the cause first, then the state at the stop
        raise SimulationError(f"simulation '{sc.name}' with '{controller}'{lead} {failure}", result=res)
    return res


def check_call(scenario, controller, gains, duration, check_workspace) -> None:
    """The arguments of simulate/stepper/export, before anything is built from them."""
    from ..controllers import CONTROLLERS

    if not isinstance(scenario, (str, Scenario)):
        raise ScenarioError(f"scenario must be a scenario name or a Scenario, got {_shown(scenario)}")
    if not isinstance(controller, str) or controller not in CONTROLLERS:
        raise ScenarioError(f"unknown controller {_shown(controller)}; choose one of {', '.join(CONTROLLERS)}")
    if gains is not None and (not isinstance(gains, Mapping) or not all(isinstance(k, str) for k in gains)):
        raise ScenarioError(f"gains must be a dict {{gain name: value}}, got {_shown(gains)}")
    if duration is not None:
        checked_float(duration, "duration", scenario if isinstance(scenario, str) else scenario.name)
    if not isinstance(check_workspace, (bool, np.bool_)):
        raise ScenarioError(f"check_workspace must be True or False, got {_shown(check_workspace)}")


def _simulate_seeds(dyn, scenario, controller, seeds, executor, max_workers, args, overrides):
    """:func:`simulate` over ``seeds``: checked here first (one clear message, no pool started),
    then one run per seed through the sweep."""
    from ..errors import ScenarioError
    from .seeds import SeedResults, seed_list, summarize

    seeds = seed_list(seeds)
    if "seed" in overrides:
        raise ScenarioError(f"simulate: seed={overrides['seed']!r} and seeds={seeds!r}; give one of the two")
    if args["engine"] not in ("c", "python"):
        raise ValueError(f"engine must be 'c' or 'python', not {args['engine']!r}")
    if executor is None:
        check_workers(max_workers)
    prepare_run(dyn, scenario, controller, args["gains"], args["duration"], args["check_workspace"],
                {**overrides, "seed": seeds[0]})
    runs = [dict(scenario=scenario, controller=controller, **args, **overrides, seed=s) for s in seeds]
    from ..codegen.generate import numbers_mode
    out = run_sweep(runs, _run_chunk, _estimator_designs, executor=executor, max_workers=max_workers, model=dyn.model,
                    results=True, numbers=numbers_mode(dyn.library.manifest))  # the workers build as dyn was built
    results = [r if isinstance(r, SimulationResult) else None for r in out]
    failures = {s: r["error"] for s, r in zip(seeds, out) if not isinstance(r, SimulationResult)}
    per_seed = [r.metrics if isinstance(r, SimulationResult) else r for r in out]
    return SeedResults(seeds, results, failures, summarize(seeds, per_seed))


def _own_gains(model, scenario, controller: str, gains=None):
    """By controller, the gains a worker's first build compiles the variant for: the entry's own over
    its scenario's (as the run's library is chosen); None where the scenario cannot be read here (the
    run itself then names the problem)."""
    from ..runtime.build import as_model

    try:
        sc = scenario if isinstance(scenario, Scenario) else named_scenario(scenario, as_model(model))
    except Exception:  # noqa: BLE001 - the run gives the message
        return None
    return {controller: {**(sc.gains.get(controller) or {}), **(gains if isinstance(gains, Mapping) else {})}}


def _run_one(job):
    """Worker: build (once per process) and run one simulation alone, as :func:`hydrogen.simulate`
    does; return its metrics (its SimulationResult when ``keep``, the metrics completed the same way)
    or its error."""
    from ..runtime.build import default_dynamics

    model, run, keep, numbers = job
    problem = entry_problem(run)
    if problem:
        return {"error": problem}
    run = dict(run)
    scenario = run.pop("scenario", "paper-sim")
    controller = run.pop("controller", "adaptive-robust")
    try:
        dyn = default_dynamics(model, controller=controller, numbers=numbers,
                               gains=_own_gains(model, scenario, controller, run.get("gains")))
        res = simulate(dyn, scenario, controller, **run)
    except Exception as exc:  # noqa: BLE001 - one bad entry must not cost the others their results
        return _error(exc)
    return _outcome(res, keep)


#: Entry keys a run of a batch takes one by one; the rest (scenario, controller, duration, check_workspace
#: and the scenario fields) decide which runs share one Batch.
_PER_RUN = ("gains", "seed")


def _run_chunk(job):
    """Worker: the runs of a chunk of entries (``job``: model, entries, keep, numbers, the estimators'
    designs the parent solved for their scenarios: :func:`_estimator_designs`), in order, each
    as :func:`_run_one` would give it. Entries that differ only in gains and seed share one
    :class:`~hydrogen.simulation.simulator.Batch` (the scenario resolved and checked once, a controller
    per gain set). Whatever fails before a run's loop starts is run again alone, so that its message is
    exactly the one the run alone gives."""
    import pickle

    from ..runtime.build import default_dynamics

    model, runs, keep, numbers, designs = job
    remember_designs(designs)
    batches, out = {}, []
    for run in runs:
        alone = (model, run, keep, numbers)
        engine = run.get("engine", "c") if isinstance(run, Mapping) else None
        if entry_problem(run) or not (isinstance(engine, str) and engine == "c"):
            out.append(_run_one(alone))
            continue
        rest = {k: v for k, v in run.items() if k not in _PER_RUN}
        try:
            key = pickle.dumps(rest)  # equal bytes, equal arguments: one Batch
        except Exception:  # noqa: BLE001 - not picklable: it runs alone
            out.append(_run_one(alone))
            continue
        if key not in batches:
            rest.pop("engine", None)
            scenario, controller = rest.pop("scenario", "paper-sim"), rest.pop("controller", "adaptive-robust")
            try:
                dyn = default_dynamics(model, controller=controller, numbers=numbers,
                                       gains=_own_gains(model, scenario, controller, run.get("gains")))
                batches[key] = Batch(dyn, scenario, controller, **rest)
            except Exception:  # noqa: BLE001 - each of its runs alone gives its own message
                batches[key] = None
        batch = batches[key]
        if batch is None:
            out.append(_run_one(alone))
            continue
        try:
            p, runner = batch.prepare(run.get("gains"), run.get("seed", SCENARIO_SEED))
        except Exception:  # noqa: BLE001 - the run alone raises it with its own message
            out.append(_run_one(alone))
            continue
        try:
            res = run_prepared(batch.dyn, p, batch.controller, "c", None, runner)
        except Exception as exc:  # noqa: BLE001 - it diverged: the run's error in its place
            out.append(_error(exc))
            continue
        out.append(_outcome(res, keep))
    return out


def _estimator_designs(model, runs) -> dict:
    """The estimators' designs of the runs' scenarios (:func:`hydrogen.estimators.designs_for`: the
    Kalman gains), solved once here for the whole sweep: each worker would otherwise import SciPy and
    solve the same Riccati equation (a third of a second of CPU per worker process). An entry whose
    scenario does not resolve is left to its run to report."""
    import pickle

    from .scenarios import Scenario, scenario as named_scenario

    settings, seen = [], set()
    for run in runs:
        if entry_problem(run):
            continue
        # the scenario fields an entry overrides ("gains" and "duration" are simulate's own arguments)
        fields = {k: v for k, v in run.items()
                  if k in Scenario.__dataclass_fields__ and k not in _ENTRY_KEYS and k != "seed"}
        name = run.get("scenario", "paper-sim")
        try:
            key = pickle.dumps((name, fields))
            if key in seen:
                continue
            seen.add(key)
            sc = named_scenario(name, model) if isinstance(name, str) else name
            sc = sc.with_overrides(**fields) if fields else sc
            settings.append((sc, 1.0 / sc.control_rate))
        except Exception:  # noqa: BLE001 - the run reports it with its own message
            continue
    return designs_for(settings)


class _ScenarioSeed:
    def __repr__(self):
        return "SCENARIO_SEED"


#: ``seed`` of :meth:`Batch.run` when the run keeps the scenario's own seed (None is a seed: fresh entropy).
SCENARIO_SEED = _ScenarioSeed()


class Batch:
    """Many runs of one scenario and controller that differ only in gains and noise seed, on the C loop:
    the scenario is resolved and checked against the model once (:func:`plan_run`), the controller
    runtime and its loop runner made once per gain set, and each run costs its noise table, the loop
    and its metrics. :meth:`run` gives what :func:`simulate` gives for the same arguments, to the bit.

    ``scenario``, ``duration``, ``check_workspace`` and ``overrides`` (scenario fields, not ``seed``:
    a run's own) as for :func:`simulate`; the checks that need no gains or seed raise here. One
    thread at a time: its runner is one set of buffers (a thread pool gives each task its own Batch,
    as the sweep's chunks do).
    """

    def __init__(self, dyn, scenario, controller: str, *, duration=None, check_workspace=True, **overrides):
        if "seed" in overrides:
            from ..errors import ScenarioError
            raise ScenarioError("Batch: the seed is each run's (Batch.run(gains, seed)), not the batch's")
        check_call(scenario, controller, None, duration, check_workspace)
        self.dyn, self.controller = dyn, controller
        self._call = (scenario, duration, check_workspace)
        self.plan = plan_run(dyn, scenario, controller, duration, check_workspace, overrides)
        self._truth = (dyn.model.theta, dyn.model.gamma)
        self._l0 = dyn.leg_lengths(self.plan.q0)
        self._gains_key, self._ctrl, self._runner, self._widths = None, None, None, None

    def prepare(self, gains=None, seed=SCENARIO_SEED) -> tuple:
        """(prepared run, its reset runner) of ``gains`` and noise ``seed``; raises as :func:`simulate`
        would before its loop. The runner of the last gain set is kept: runs of one gain set in a row
        (the seeds of a sweep entry) share it."""
        import pickle
        from dataclasses import replace

        from .checks import seed_ok
        scenario, duration, check_workspace = self._call
        check_call(scenario, self.controller, gains, duration, check_workspace)
        plan = self.plan
        if seed is SCENARIO_SEED:
            sc = plan.sc
        else:  # the one field a run changes: its check alone (the message of with_overrides when it fails)
            sc = replace(plan.sc, seed=seed) if seed_ok(seed) else plan.sc.with_overrides(seed=seed)
        key = pickle.dumps(gains)  # equal bytes, equal gains: the same controller
        if key != self._gains_key:
            self._gains_key, self._runner = None, None
            self._ctrl = plan.controller_runtime(gains)
            self._runner = make_runner(self.dyn, plan.sc, self._ctrl, plan.x0, plan.q0, plan.estimate, plan.h)
            self._widths = log_widths(self.dyn.model, self._ctrl.xc.size)
            self._gains_key = key
        else:  # every buffer the loop reads but does not write each period is static: only its state restarts
            self._runner.reset(plan.x0, plan.q0, self._l0, self._ctrl.xc)
        p = _Prepared(sc, self._ctrl, plan.n, plan.h, plan.x0, plan.q0, plan.noise(sc.seed), plan.estimate,
                      plan.theta0, plan.gamma0, self._truth, self._widths)
        return p, self._runner

    def run(self, gains=None, seed=SCENARIO_SEED):
        """One run with ``gains`` (over the scenario's) and noise ``seed`` (:data:`SCENARIO_SEED`: the
        scenario's): a :class:`SimulationResult`, or the errors :func:`simulate` raises."""
        start = time.perf_counter()
        p, runner = self.prepare(gains, seed)
        return run_prepared(self.dyn, p, self.controller, "c", start, runner)

    def grid(self, gain_sets, seeds) -> dict:
        """Every run of ``gain_sets`` (a list of gains dicts, None: the scenario's) times ``seeds`` (a
        list), the seeds of a gain set in a row: {"metrics": per gain set, per seed, the run's metrics
        or {"error": message} (as a sweep gives them); "max_error_pct": a (gain sets, seeds,
        coordinates) array of the max errors in % of the amplitude (NaN where the run failed or the
        coordinate has no amplitude); "failed": a (gain sets, seeds) bool array}."""
        gain_sets, seeds = list(gain_sets), list(seeds)
        coords = tuple(self.dyn.model.coordinate_names)
        out = np.full((len(gain_sets), len(seeds), len(coords)), np.nan)
        table = []
        for i, gains in enumerate(gain_sets):
            row = []
            for j, seed in enumerate(seeds):
                try:
                    m = self.run(gains, seed).metrics
                except Exception as exc:  # noqa: BLE001 - one failed run must not cost the others theirs
                    m = _error(exc)
                else:
                    out[i, j] = [np.nan if v is None else v for v in (m["max_error_pct"][c] for c in coords)]
                row.append(m)
            table.append(row)
        failed = np.array([["error" in m for m in row] for row in table], bool).reshape(len(gain_sets), len(seeds))
        return {"metrics": table, "max_error_pct": out, "failed": failed}


@dataclass
class _Prepared:
    sc: Scenario
    ctrl: object
    n: int
    h: float
    x0: np.ndarray
    q0: np.ndarray
    noise: np.ndarray
    estimate: object  # the run's estimator (hydrogen.estimators.Estimate), or None: ideal rate sensors
    theta0: np.ndarray
    gamma0: np.ndarray
    truth: tuple = None  # (θ, γ) of the model, computed once for a batch (None: read from the model)
    log_widths: tuple = None  # log_widths of the model and controller, once for a batch (None: worked out)


def log_widths(model, n_xc: int) -> tuple:
    """((log name, columns), ...) of a run's logs (:data:`hydrogen.loop_logs.LOGS`, then the plant's
    outputs: :func:`hydrogen.layout.log_rows`, as the C loop has them): :func:`new_logs`'s layout, the
    same for every run of one model and controller state size (a batch works it out once)."""
    return tuple((r["name"], max(n_xc, 1) if r["width"] is None else r["width"])
                 for r in log_rows(model_summary(model)))


def new_logs(model, n: int, n_xc: int, widths=None) -> dict:
    """The logs of a run of ``n`` periods (NaN-filled rows), as both engines write them (``widths``:
    :func:`log_widths` of the same model and ``n_xc``, when the caller has it)."""
    return {k: np.full((n, w), np.nan) for k, w in (widths or log_widths(model, n_xc))}


@dataclass
class RunPlan:
    """What every run of one scenario and controller shares, whatever its gains and noise seed: the
    scenario checked against the model, the period ``h`` (s) and the ``n`` periods, the initial
    estimates, the start state, the estimator and its design, each actuator's rig settings (:func:`plan_run`)."""
    dyn: object
    controller: str
    sc: Scenario
    n: int
    h: float
    theta0: np.ndarray
    gamma0: np.ndarray
    q0: np.ndarray
    pc0: np.ndarray
    x0: np.ndarray
    estimate: object  # the run's estimator (hydrogen.estimators.Estimate), or None: ideal rate sensors
    own: dict          # actuator_settings(sc, model)
    pinned: dict       # the scenario's own gains for the controller
    sources: dict      # where each pinned gain comes from (named in messages about it)

    def controller_runtime(self, gains):
        """The controller runtime of this plan with ``gains`` over the scenario's, reset to the start."""
        ctrl = make_controller(self.dyn, self.controller, {**self.pinned, **(gains or {})}, self.theta0,
                               self.gamma0, period=self.h,
                               sources={k: v for k, v in self.sources.items() if k not in (gains or {})})
        ctrl.reset(self.q0, np.zeros(self.dyn.model.n), self.pc0)
        return ctrl

    @functools.cached_property
    def noise_channels(self) -> tuple:
        """The noise row's channels in order: the loop's own, then the plant's sensors', once per plan."""
        return (*NOISE, *plant_sensors(model_summary(self.dyn.model)))

    @functools.cached_property
    def noise_columns(self) -> dict:
        """The noise row's columns (:func:`hydrogen.sensors.noise_columns`), worked out once per plan."""
        return _noise_columns(self.dyn)

    def noise(self, seed) -> np.ndarray:
        """The sensor noise table of a run with noise ``seed``: one row per period, the channels of
        :data:`hydrogen.sensors.NOISE` (actuator travel, pressure states, the joint encoders where
        fitted, the supply pressure where it is a state), then each rig part's output's sensor
        (:func:`hydrogen.layout.plant_sensors`), each drawn in that order only where its
        standard deviation (the actuator's own, else the scenario's) is not 0; one table for every engine."""
        n = self.n
        rng = np.random.default_rng(seed)
        columns = self.noise_columns
        noise = np.zeros((n, sum(count for _, count in columns.values())))
        for ch in self.noise_channels:
            if ch.name not in columns:
                continue
            start, count = columns[ch.name]
            std = self.own.get(ch.setting, getattr(self.sc, ch.setting))  # per actuator, in its own unit
            if np.any(std):
                noise[:, start:start + count] = std * rng.standard_normal((n, count))
        return noise


def _noise_columns(dyn) -> dict:
    """The noise row's columns of ``dyn``'s robot (:func:`hydrogen.sensors.noise_columns`; its plant's
    sensors' after the loop's own)."""
    summary = model_summary(dyn.model)
    return noise_columns(robot_sizes(summary), dyn.model.joint_encoders, plant_sensors(summary))


def plan_run(dyn, scenario, controller, duration, check_workspace, overrides, *, keep_logs=True) -> RunPlan:
    """The :class:`RunPlan` of ``scenario`` (a name or a Scenario) with ``overrides`` and ``duration`` for
    ``controller``: every check of the scenario against the model (``check_workspace``: the reference
    inside the workspace), done once for all the runs that share them (``keep_logs``: as :func:`prepare_run`)."""
    model = dyn.model
    sc = named_scenario(scenario, model) if isinstance(scenario, str) else scenario
    overrides = dict(overrides)
    if duration is not None:
        overrides["duration"] = checked_float(duration, "duration", sc.name)
    sc = sc.with_overrides(**overrides) if overrides else sc.validated()
    check_against_model(sc, model, controller, dyn)
    h = 1.0 / sc.control_rate
    n = check_run_size(sc, model, controller, keep_logs)  # before any table of n rows is made
    theta0 = model.theta * np.asarray(sc.theta0_factor)
    gamma0 = model.gamma * np.asarray(sc.gamma0_factor, float)[:, None]
    if controller_spec(controller).knows_true_parameters:
        theta0, gamma0 = model.theta, model.gamma
    if check_workspace:
        _check_reference(dyn, sc, n, h)
    pinned = sc.gains.get(controller, {})  # the scenario's own tuning, named in messages about it
    table = f"{model.source}: [scenarios.{sc.name}]" if sc.name in scenario_names(model) else f"scenario {sc.name!r}:"
    q0 = sc.reference(0.0)[0] + np.asarray(sc.q0_offset, float)
    pc0, x0 = start_state(dyn, sc, q0)  # at rest, the valves closed, the rest as declared
    own = actuator_settings(sc, model)  # each actuator's travel noise, resolution, friction in its own unit
    return RunPlan(dyn, controller, sc, n, h, theta0, gamma0, q0, pc0, x0, estimate_for(sc, h), own, pinned,
                   {k: f"{table} gains.{controller}" for k in pinned})


def prepare_run(dyn, scenario, controller, gains, duration, check_workspace, overrides, *,
             keep_logs=True) -> _Prepared:
    """Scenario, controller runtime, initial state and noise table shared by every engine
    (``keep_logs``: the caller keeps a log row per period, counted in the memory bound)."""
    check_call(scenario, controller, gains, duration, check_workspace)
    plan = plan_run(dyn, scenario, controller, duration, check_workspace, overrides, keep_logs=keep_logs)
    ctrl = plan.controller_runtime(gains)
    return _Prepared(plan.sc, ctrl, plan.n, plan.h, plan.x0, plan.q0, plan.noise(plan.sc.seed), plan.estimate,
                     plan.theta0, plan.gamma0)


def _describe(x, t, ctrl=None, xc=None, u=None):
    """Which signal went non-finite (the command, the controller state, the plant state), where, and
    the values: the first of them named is where the divergence shows first."""
    x = np.asarray(x, float)
    parts = []
    if u is not None:
        u = np.asarray(u, float)
        bad_u = np.flatnonzero(~np.isfinite(u)).tolist()
        if bad_u:
            parts.append(f"the command u (spool positions) is non-finite at entries {bad_u}: u = {u.tolist()}")
    if xc is not None and np.size(xc):
        xc = np.asarray(xc, float)
        names = [""] * xc.size
        for block, sl in (getattr(ctrl, "slices", None) or {}).items():
            for j, i in enumerate(range(*sl.indices(xc.size))):
                names[i] = f"{block}[{j}]"
        bad_c = np.flatnonzero(~np.isfinite(xc)).tolist()
        if bad_c:
            parts.append(f"the controller state is non-finite at {[names[i] or i for i in bad_c]}: xc = {xc.tolist()}")
    bad = np.flatnonzero(~np.isfinite(x)).tolist()
    if bad:
        # each entry by its part of x and what it belongs to: "pc[leg1.pc]", "q[x]"
        where = f" ({describe_entries(plant_layout(ctrl.model), bad)})" if ctrl is not None else ""
        parts.append(f"the plant state is non-finite at entries {bad}{where}: x = {np.array2string(x, precision=6, threshold=60)}")
    if not parts:
        parts.append(f"a value went non-finite inside the step (every signal is finite at its end): x = {np.array2string(x, precision=6, threshold=60)}")
    return f"diverged at t = {t:.4f} s: " + "; ".join(parts)


def diverged_block(ctrl, xc, t):
    """The controller state block that diverged first, as a sentence naming its role and what to
    lower (its :class:`~hydrogen.controllers.spec.StateBlock` declaration), or None when no block
    went non-finite or past its bound. ``xc``: the state at the periods of ``t`` (k, size; s), in
    order. The earliest period at which an entry is non-finite or past its block's bound decides;
    among the blocks bad at that period, the one furthest past its bound (a non-finite value is
    what the others' overflow leaves, so it counts last), then the one declared first. With one
    period (the stepper keeps no history) that ranking alone names the block."""
    xc = np.atleast_2d(np.asarray(xc, float))
    with np.errstate(invalid="ignore"):
        bad = {b.name: ~np.isfinite(xc[:, ctrl.slices[b.name]]) | (np.abs(xc[:, ctrl.slices[b.name]]) > b.bound)
               for b in getattr(ctrl, "layout", ())}
    rows = [int(np.flatnonzero(v.any(axis=1))[0]) for v in bad.values() if v.any()]
    if not rows:
        return None
    r = min(rows)

    def excess(block):  # how far past its bound the block's worst finite entry is at period r (0: none)
        x = np.abs(xc[r, ctrl.slices[block.name]])
        x = x[np.isfinite(x)]
        return float(x.max() / block.bound) if x.size and x.max() > block.bound else 0.0

    hit = [b for b in ctrl.layout if bad[b.name][r].any()]
    block = max(hit, key=excess)  # max keeps the first declared of equals
    x = xc[r, ctrl.slices[block.name]]
    finite_past = np.isfinite(x) & (np.abs(x) > block.bound)
    j = int(np.argmax(np.where(finite_past, np.abs(x), -1.0))) if finite_past.any() else \
        int(np.flatnonzero(bad[block.name][r])[0])
    v = x[j]
    why = f"{v:.3g}, past its bound {block.bound:g}" if np.isfinite(v) else f"{v}"
    return (f"{block.role} diverged at t = {float(np.ravel(t)[r]):.4f} s ({block.name}[{j}] = {why}): "
            f"lower {block.lower}")


def make_runner(dyn, sc, ctrl, x0, q0, estimate, h):
    """A C-loop runner for scenario ``sc`` and controller runtime ``ctrl``, reset to the plant state
    ``x0`` at pose ``q0`` (generalized coordinates), with the estimator ``estimate``
    (:class:`hydrogen.estimators.Estimate`, or None: ideal rate sensors) and control period ``h`` (s)."""
    from ..runtime.loop import LoopRunner
    from .loop_config import Run, config_values
    runner = LoopRunner(dyn, ctrl, config_values(Run(dyn, sc, ctrl, h, estimate)))
    runner.reset(x0, q0, dyn.leg_lengths(q0), ctrl.xc)
    return runner


def _loop_failure(code, runner, h):
    """Message for a non-zero return code of the C loop (None for success)."""
    from ..runtime.loop import LOOP_FK_FAILED, LOOP_NONFINITE, LOOP_OK
    k = runner.state.k
    if code == LOOP_OK:
        return None
    if code == LOOP_NONFINITE:
        return _describe(runner.plant_state, (k + 1) * h, runner.ctrl, runner.xc[: runner.ctrl.xc.size],
                         runner.fn.output(0))
    if code == LOOP_FK_FAILED:  # worded as Dynamics.forward_kinematics, from what the loop recorded
        st, cfg = runner.state, runner.cfg
        why = fk_failure(int(st.fk_info[0]), st.fk_info[1:4], st.q_meas[:], st.fk_l[:], cfg.fk_max_iter,
                         cfg.fk_max_cond)
        return f"stopped at t = {k * h:.4f} s: {why}"
    return f"stopped at t = {k * h:.4f} s: a generated function returned an error"


def _run_c(dyn, sc, ctrl, x0, q0, noise, estimate, log, n, h, runner=None):
    from ..runtime.loop import LOOP_NONFINITE, LOOP_OK
    runner = make_runner(dyn, sc, ctrl, x0, q0, estimate, h) if runner is None else runner
    xc_log = log["xc"] if ctrl.xc.size else None
    logs = {k: v for k, v in log.items() if k != "xc"}  # the fixed logs and the plant's outputs
    if xc_log is not None:
        logs["xc"] = xc_log
    code = runner.run(n, noise, logs)
    if code == LOOP_OK:
        return n, None
    k = runner.state.k
    return (k + 1 if code == LOOP_NONFINITE else k), _loop_failure(code, runner, h)


class _Signals:
    """One period's signals as the stages hand them on (the C loop's ``<model>_loop_signals``)."""
    __slots__ = ("nz", "t", "l_true", "l_meas", "pc_meas", "ps_meas", "q_enc", "plant_meas", "ldot", "qdot_meas", "qd",
                 "adapt", "u", "u_held", "u_app")

    def __getattr__(self, name):
        """A rig part's sensor's reading by the C loop's field name, ``<output>_meas`` (``plant_meas``)."""
        if name.endswith("_meas") and name != "plant_meas":
            try:
                return self.plant_meas[name.removesuffix("_meas")]
            except (AttributeError, KeyError):
                pass
        raise AttributeError(name)


def _on_grid(reading: np.ndarray, resolution: np.ndarray) -> np.ndarray:
    """A sensor's ``reading`` rounded to each entry's ``resolution`` (0: none), as the C loop's sensors
    round: ``res * floor(reading / res + 0.5)``."""
    step = np.where(resolution > 0, resolution, 1.0)
    return np.where(resolution > 0, step * np.floor(reading / step + 0.5), reading)


class PythonStages:
    """The reference closed loop in Python: an interpreter of the loop's diagram
    (:data:`hydrogen.diagram.LOOP_BLOCKS`), one method per block, named as the block, run in the
    diagram's order by :meth:`run_period` (the discrete blocks, the period's log, the continuous plant,
    then :meth:`after_period`); the same numbers as the C loop's stages (``templates/loop.c.j2``) to
    rounding. ``x`` is the plant state, ``q_meas`` the last measured pose, ``estimate`` the run's
    estimator (:class:`hydrogen.estimators.Estimate`, or None: the ideal rate sensor) and
    ``est_state`` its state (its module's ``start`` and ``update``)."""

    def __init__(self, dyn, sc, ctrl, x, q0, estimate, h):
        from ..layout import MAX_DELAY
        model = self.model = dyn.model
        self.dyn, self.sc, self.ctrl, self.h, self.estimate = dyn, sc, ctrl, h, estimate
        self._rhs_fn = dyn.functions["plant_rhs"]
        # the plant's true θ and γ, read once: model.theta computes θ from the links (a tenth of a period's time)
        self._theta, self._gamma = model.theta, model.gamma
        own = actuator_settings(sc, model)  # each actuator's resolution, in its own unit
        self._quant = own["quantization_l"]
        # each plant input's numbers (hydrogen.plant.plant_inputs: friction, valve), in the plant's order:
        # the run's (each block's rule), and the controller's own model's in the predictor (the C loop's
        # PRED_<INPUT>, from the same declaration)
        self._inputs = tuple(v.ravel() for v in input_values(sc, model).values())
        self._pred_inputs = tuple(np.tile(np.array(i.ideal, float), model.n_cylinders) for i in plant_inputs(model))
        self.layout = plant_layout(model)
        self._q, self._qdot, self._pc = (slot(self.layout, k).slice for k in ("q", "qdot", "pc"))
        self._ps = next((b.slice for b in self.layout if b.name == SUPPLY_LOG), None)  # a supply state
        # the plant's outputs a controller may read (hydrogen.layout.plant_ports): their parts of x
        self._plant_ports = [(p.name, slot(self.layout, p.name).slice) for p in plant_ports(model_summary(model))]
        pc = slot(self.layout, "pc")
        self._lo, self._hi = np.array(pc.lower), np.array(pc.upper)  # each pressure state's clip (0 and P_s for p_c)
        self._stages = sc.pressure_bounds == "stage"  # the bounds held at every RK4 stage too
        self.nq, self.m, self.n_p = model.n, model.n_cylinders, pc.size
        # each sensor's columns of the noise row (hydrogen.sensors.NOISE)
        self._noise = {k: slice(a, a + b) for k, (a, b) in _noise_columns(dyn).items()}
        # each sensed output's resolution (0: none) and bias
        self._resolution, self._bias = (sensor_numbers(self.layout, sc, k) for k in ("resolution", "bias"))
        self._max_delay = MAX_DELAY
        self.u_hist = np.zeros((MAX_DELAY, self.m))  # the C loop's ring: command of period k in slot k % MAX_DELAY
        self._est = None if estimate is None else estimate.module
        self.est_state = None if estimate is None else self._est.start(dyn.leg_lengths(q0))
        self.x, self.q_meas, self.k = x, q0.copy(), 0
        self.delay, self.delay_frac = sc.delay_split()
        self.u_app = np.zeros(self.m)  # the command the valves held at the end of the last period
        self.predict = sc.predicts()
        #: each block's numeric step, by the diagram's block name (a block without one is a bug here)
        self.stages = {b.name: getattr(self, b.name) for b in diagram.LOOP_BLOCKS}

    def run_period(self, nz, log=None) -> _Signals:
        """One control period from the noise row ``nz``: every block of the diagram in order; ``log``
        (a callable of the period's signals) runs after the discrete blocks, before the plant moves.
        Raises :class:`KinematicsError` when the estimator's forward kinematics fails."""
        s = self.signals(nz)
        for block in diagram.LOOP_BLOCKS:
            if block.continuous and log is not None:
                log(s)
            self.stages[block.name](s)
        self.after_period()
        return s

    def signals(self, nz) -> _Signals:
        """A new period's signals at t = k h, with the sensors' noise row ``nz``."""
        s = _Signals()
        s.nz, s.t = nz, self.k * self.h
        return s

    def sensors(self, s: _Signals) -> None:
        """The sensors' readings of the plant state with the period's noise row."""
        sc, x, nz, col = self.sc, self.x, s.nz, self._noise
        q, qdot, pc = x[self._q], x[self._qdot], x[self._pc]
        s.l_true = self.dyn.leg_lengths(q)
        s.l_meas = s.l_true + nz[col["l"]]
        s.l_meas = _on_grid(s.l_meas, self._quant)  # each actuator's resolution (0: none)
        s.pc_meas = np.clip(pc + nz[col["pc"]], self._lo, self._hi) if sc.noise_p else pc
        s.ldot = None if self._est is not None else self.dyn.leg_jacobian(q) @ qdot  # ideal rate sensor
        s.q_enc = q + nz[col["q"]] if self.model.joint_encoders else None
        if self._ps is not None:  # the supply pressure, held at its lower bound 0
            s.ps_meas = np.maximum(x[self._ps] + nz[col["ps"]], 0.0)
        # the plant's outputs the controller may read: their sensors' readings (true where ideal)
        s.plant_meas = {name: _on_grid(x[part] + self._bias[name] + nz[col[name]], self._resolution[name])
                        if name in col else x[part] for name, part in self._plant_ports}

    def estimator(self, s: _Signals) -> None:
        """The run's estimator (the actuators' rates), pose (encoders or forward kinematics, warm-started),
        velocities through JL. Raises :class:`KinematicsError` when forward kinematics fails."""
        if self._est is not None:
            self.est_state = self._est.update(self.est_state, s.l_meas, self.estimate.design, self.h)
            s.ldot = self._est.rate(self.est_state)
        if s.q_enc is not None:
            self.q_meas = s.q_enc
        else:
            self.q_meas = self.dyn.forward_kinematics(s.l_meas, q0=self.q_meas)
        s.qdot_meas = self._velocities(s)

    def _velocities(self, s: _Signals) -> np.ndarray:
        """Joint velocities from the cylinder rates through JL at the measured pose: the C loop's LU and
        its pivot test (:data:`~hydrogen.layout.LU_PIVOT_MIN`). A KinematicsError when JL is singular."""
        from scipy.linalg import lu_factor, lu_solve

        lu, piv = lu_factor(self.dyn.leg_jacobian(self.q_meas), check_finite=False)
        if not np.all(np.abs(np.diag(lu)) > LU_PIVOT_MIN):
            raise KinematicsError(fk_failure(VELOCITY_SINGULAR, (0.0, np.inf, 0.0), self.q_meas, s.l_meas, 0))
        return lu_solve((lu, piv), s.ldot, check_finite=False)

    def reference(self, s: _Signals) -> None:
        """The scenario's reference and its derivatives at the period's start."""
        s.qd = self.sc.reference(s.t)

    def schedule(self, s: _Signals) -> None:
        """Adaptation on from the scenario's ``t_adapt``."""
        s.adapt = s.t >= self.sc.t_adapt

    def controller(self, s: _Signals) -> None:
        """The controller's inputs by port name (measured, or predicted at the time the command reaches the
        valves), its state's semi-implicit update, the command."""
        sc, ctrl, delay = self.sc, self.ctrl, self.delay
        if self.predict:  # the plant as it will be when this command reaches the valves
            x = self.predicted(s)
            q = x[self._q]
            ports = diagram.signals(q, x[self._qdot], x[self._pc], np.asarray(self.dyn.leg_lengths(q), float),
                                    sc.reference(s.t + (delay + self.delay_frac) * self.h), s.adapt,
                                    ps=self._ps_input(x[self._ps] if self._ps is not None else None))
        else:
            ports = diagram.signals(self.q_meas, s.qdot_meas, s.pc_meas, s.l_meas, s.qd, s.adapt,
                                    ps=self._ps_input(s.ps_meas if self._ps is not None else None))
        if self.predict:  # a rig part's state the controller reads: predicted, or its sensor's reading
            ports.update((name, x[part]) for name, part in self._plant_ports)
        else:
            ports.update(s.plant_meas)
        if self.k and sc.estimator_update != "euler":  # semi-implicit: state from this measurement, then command
            ctrl.update_for(self.h, ports)
        s.u = ctrl.command_for(ports)

    def _ps_input(self, ps):
        """The controller's ``ps`` input from the measured (or predicted) supply pressure ``ps`` (Pa; None:
        a constant supply): the description's supply pressure instead without ``supply_feedback``."""
        if ps is None or self.sc.supply_feedback:
            return ps
        return np.full(np.shape(ps), supply_nominal(self.model))

    def hold(self, s: _Signals) -> None:
        """The computation delay and zero-order hold: the command the valves hold over the period's first
        ``delay_frac`` h (the last one's) and over the rest (that of ``delay`` periods ago)."""
        ctrl, delay = self.ctrl, self.delay
        if delay > 0:
            s.u_app = self.u_hist[(self.k - delay) % self._max_delay].copy()
            self.u_hist[self.k % self._max_delay] = s.u
        else:
            s.u_app = s.u
        s.u_held, self.u_app = self.u_app, s.u_app
        # with the predictor the period the controller sees ends when this command reaches the valves
        ctrl.applied(s.u if self.predict else s.u_app)

    def predicted(self, s: _Signals) -> np.ndarray:
        """The plant state at t_k + delay from the measured pose, velocities and pressures, by the
        controller's own model (its estimates, ideal valve, no friction) over the commands in flight:
        the one the valves hold over the period's first ``delay_frac`` h, then a period each of the
        commands of periods k − delay … k − 1 (the C loop's ``predict``)."""
        h, pc = self.h, self._pc
        th, g1, g2 = self.ctrl.own_parameters()
        supply = {} if self._ps is None else {SUPPLY_LOG: s.ps_meas}
        # the rig parts' states the controller reads: from their sensors' reading
        supply.update((name, s.plant_meas[name]) for name, _ in self._plant_ports if name in self.ctrl.plant_reads)
        # what it measures nothing of (spool: unused by the ideal valve) at its declared initial value
        x = initial_state(self.layout, self.sc, q=self.q_meas, qdot=s.qdot_meas, pc=s.pc_meas, **supply)

        def hold(x, u, dt):
            n = self.sc.predictor_steps(dt / h)
            rhs = lambda xx: self._rhs_fn(xx, u, th, g1, g2, *self._pred_inputs)  # noqa: E731
            return integrator.bounded_steps(rhs, x, n, dt / n, pc, self._lo, self._hi, self._stages)

        if self.delay_frac > 0:
            x = hold(x, self.u_app, self.delay_frac * h)
        for j in range(1, self.delay + 1):
            x = hold(x, self.u_hist[(self.k - self.delay - 1 + j) % self._max_delay], h)
        return x

    def plant(self, s: _Signals) -> None:
        """The plant over one period (:meth:`integrate` at the scenario's ``substeps``)."""
        self.x = self.integrate(self.x, s.u_held, s.u_app, self.sc.substeps)

    def integrate(self, x, u_held, u_app, substeps: int) -> np.ndarray:
        """The plant state one period after ``x``: ``substeps`` RK4 sub-steps holding ``u_held`` over the
        period's first ``delay_frac`` h and ``u_app`` over the rest (the sub-steps shared out as the C
        loop does: :func:`hydrogen.plant.integrator.period_pieces`), each pressure held within its bounds
        (:func:`hydrogen.plant.integrator.bounded_steps`); ``x`` itself is not changed."""
        pc, lo, hi = self._pc, self._lo, self._hi
        th, g = self._theta, self._gamma

        def hold(x, u, n, hs):
            rhs = lambda xx: self._rhs_fn(xx, u, th, g[0], g[1], *self._inputs)  # noqa: E731
            return integrator.bounded_steps(rhs, x, n, hs, pc, lo, hi, self._stages)

        pieces = integrator.period_pieces(substeps, self.delay_frac, self.h)
        held = (u_held, u_app) if len(pieces) == 2 else (u_app,)  # the piece before a switch first
        for (n, hs), u in zip(pieces, held):
            x = hold(x, u, n, hs)
        return x

    @property
    def xc(self) -> np.ndarray:
        """The controller's state (the C loop's ``st->xc``)."""
        return self.ctrl.xc

    def log_sources(self) -> list:
        """``[(log name, source), ...]``: each log of the run (:func:`hydrogen.layout.log_rows`, as the C
        loop's ``write_log`` reads them) and the function giving its row from a period's signals: a
        signal, a part of the plant state, a field of the loop's state, the actuators' forces (an empty
        controller state is no log row)."""
        def plant(part):
            sl = slot(self.layout, part).slice
            return lambda s: self.x[sl]

        law = pressures.force_law(self.model)  # each actuator's parameters read once, not every period

        def forces(s):
            ps = None if self._ps is None else self.x[self._ps][0]  # a supply state's pressure, else the nominal
            return law(self.x[self._pc], ps)

        kinds = {SIGNAL: lambda field: (lambda s: getattr(s, field)), PLANT: plant,
                 FORCES: lambda field: forces}
        return [(r["name"], kinds.get(r["kind"], lambda field: (lambda s: getattr(self, field)))(r["field"]))
                for r in log_rows(model_summary(self.model)) if r["width"] is not None or self.ctrl.xc.size]

    def after_period(self) -> None:
        """The controller state's forward-Euler update after the period (``estimator_update="euler"``)."""
        if self.sc.estimator_update == "euler":
            self.ctrl.advance(self.h)


def run_python_loop(dyn, sc, ctrl, x, q0, noise, estimate, log, n, h):
    """The reference closed loop in Python: ``n`` control periods of ``h`` s from plant state ``x`` with
    the sensor ``noise`` table, writing each period into ``log`` (:func:`new_logs`); the diagram's blocks
    interpreted by :class:`PythonStages`, the same numbers as the C loop to rounding."""
    loop = PythonStages(dyn, sc, ctrl, x, q0, estimate, h)
    rows = [(name, log[name], source) for name, source in loop.log_sources() if name in log]

    def write(s):
        k = loop.k
        for name, out, source in rows:
            v = np.ravel(source(s))
            if v.size < out.shape[1]:  # never broadcast: a source without its entries is a bug here
                raise ValueError(f"the log {name!r} has {out.shape[1]} columns, its source gave {v.size}")
            out[k] = v[:out.shape[1]]  # a source's first entries (q_d: of the reference's 4 rows)

    for k in range(n):
        loop.k = k
        try:
            s = loop.run_period(noise[k], write)
        except KinematicsError as exc:
            return k, f"stopped at t = {k * h:.4f} s: {exc}"
        if not np.all(np.isfinite(loop.x)) or not np.all(np.isfinite(ctrl.xc)):
            return k + 1, _describe(loop.x, s.t + h, ctrl, ctrl.xc, s.u)
    return n, None


def _result(sc, controller, ctrl, log, k, theta0, gamma0, theta_true, gamma_true, wall):
    def est(name, default):
        s = ctrl.slices.get(name)
        default = np.atleast_1d(np.array(default, float))  # a copy: the view below must not share the model's
        # a value the controller does not estimate is constant: a read-only view of it, not k copies
        return log["xc"][:k, s] if s is not None else np.broadcast_to(default, (k, default.size))

    def rows(r):  # a log of one column is a vector over the run
        return log[r.name][:k, 0] if r.size == (1,) else log[r.name][:k]

    model = ctrl.model
    # the loop's logs (hydrogen.loop_logs): each its result's field, or by name in ``signals``; the
    # controller's state is its blocks' (``states``, the estimates)
    named = {r.result: rows(r) for r in LOGS if r.result}
    # the others by name: the table's rows without a field of their own, a rig part's sensor's reading
    outputs = [b.name for b in plant_outputs(plant_layout(model))]  # the plant's: in ``plant``
    own = {r.name for r in LOGS if r.result or "NXC" in r.size} | set(outputs)
    res = SimulationResult(
        scenario=sc, controller=controller, **named,
        signals={name: v[:k] for name, v in log.items() if name not in own},  # the controller's state: states
        theta_hat=est("theta_hat", theta0), gamma1_hat=est("gamma1_hat", gamma0[0]),
        gamma2_hat=est("gamma2_hat", gamma0[1]),
        theta_true=theta_true, gamma_true=gamma_true, amplitude=sc.reference.amplitude(),
        metric_start=sc.metric_start, coordinates=tuple(model.coordinate_names), units=model.coordinate_units,
        theta_names=tuple(model.theta_names), estimated=estimated_blocks(ctrl), wall_time_s=wall, loop_wall_s=wall,
        u_max=float(ctrl.values["u_max"][0]) if "u_max" in ctrl.values else 0.0,
        actuators=tuple(c.name for c in model.cylinders),
        states={b.name: log["xc"][:k, ctrl.slices[b.name]] for b in ctrl.layout},
        plant={name: log[name][:k] for name in outputs},
        supply_pressure=log[SUPPLY_LOG][:k, 0] if SUPPLY_LOG in log else None, model_name=model.name)
    if k:
        res.compute_metrics()
    return res


def _ratio(M):
    ev = np.linalg.eigvalsh(0.5 * (M + M.T))
    return float(max(ev[0], 0.0) / ev[-1]) if ev[-1] > 0 else 0.0


def _least_excited(M, names, most: int = 3) -> dict:
    """The parameters that make up the least-excited direction of M (its eigenvector of λmin): the
    ``most`` largest weights, name -> signed weight (unit norm)."""
    ev, vec = np.linalg.eigh(0.5 * (M + M.T))
    v = vec[:, 0]
    order = np.argsort(-np.abs(v))[:most]
    return {names[i]: float(v[i]) for i in order}


def excitation(dyn, res, ctrl=None) -> dict:
    """How well a run excites the adapted parameters: λmin/λmax of the normalised information matrices
    accumulated over the run (1 = every direction equally, 0 = a direction not excited at all).

    * ``theta_least_excited``: the parameters of the least-excited direction, with their weights.
    * ``theta``: M = Σ h (Y Θ)ᵀ S⁻¹ (Y Θ), Y = Y(q, q̇, q̇, q̈) along the run (velocities and
      accelerations by central differences of the logged pose), Θ = diag(|θ|) (the columns in units
      of each parameter's own magnitude), S = the per-coordinate inertia scale (rows of different
      units made commensurate).
    * ``gamma``: per cylinder, M_i = Σ h φ_iᵀ φ_i with φ_i = [β f0, βc g0(u, p_c)] the regressor of
      ḟ = γ1 f0 + γ2 g0 (59) along the run (l̇ by central differences, u and p_c as applied).
    """
    from .control import gain_scale

    model = dyn.model
    t, q = res.t, res.q
    if len(t) < 3:
        return {}
    h = float(t[1] - t[0])
    qd = np.gradient(q, h, axis=0)
    qdd = np.gradient(qd, h, axis=0)
    Theta = np.abs(model.theta)
    S_inv = 1.0 / gain_scale(dyn)
    # one batched call for the whole run (k n rows of p), not a call per period; the sums over k and the
    # coordinates as one matrix product (an einsum of three operands is an unblocked loop, 10x slower),
    # Θ applied to the p x p result: (YΘ)ᵀ S⁻¹ (YΘ) = Θ (Yᵀ S⁻¹ Y) Θ
    Y = np.asarray(dyn.regressor(q, qd, qd, qdd)).reshape(len(t), model.n, model.n_theta)
    Yw = (Y * S_inv[:, None]).reshape(-1, model.n_theta)
    M = h * (Yw.T @ Y.reshape(-1, model.n_theta)) * np.outer(Theta, Theta)
    out = {"theta": _ratio(M), "theta_least_excited": _least_excited(M, model.theta_names)}
    l, u, pc = res.leg_lengths, res.u, res.pressures
    ld = np.gradient(l, h, axis=0)
    g1, g2 = model.gamma
    f0, g0 = np.empty_like(l), np.empty_like(l)
    blocks = pressures.blocks(model)
    kinds = {}
    for i, c in enumerate(model.cylinders):
        kinds.setdefault(c.kind, []).append(i)
    for name, idx in kinds.items():  # the cylinders of a kind at once: its numeric laws broadcast over them
        kind = actuator(name)
        each = [kind.parameters(model.cylinders[i].table) for i in idx]
        P = {k: np.array([e[k] for e in each], float) for k in each[0]}
        parts = tuple(pc[:, [blocks[i][0] + j for i in idx]] for j in range(blocks[idx[0]][1] - blocks[idx[0]][0]))
        f0[:, idx] = kind.Numeric.f0(l[:, idx], ld[:, idx], parts, P)
        g0[:, idx] = kind.Numeric.g0(l[:, idx], parts, u[:, idx], P)
    phi = np.stack([(g1 * f0).T, (g2 * g0).T], axis=1)  # (m, 2, k): φ_i over the run
    Mg = (phi @ phi.transpose(0, 2, 1)) * h
    out["gamma"] = [_ratio(Mi) for Mi in Mg]
    out["gamma_cylinders"] = [c.name for c in model.cylinders]
    return out


def _check_reference(dyn, sc, n, h):
    """Reject a reference that leaves an actuator's travel range (a cylinder's stroke in m, a vane's
    angle range in rad: its kind's TRAVEL) or a joint's limits at any control period, naming the time
    and the actuator or joint (one compiled call for the whole trajectory)."""
    m = dyn.model
    t = np.arange(n) * h
    q_ref = sc.reference.positions(t)  # once: the stroke and the joint-limit checks read it
    legs = dyn.leg_lengths_many(q_ref)
    bad = (legs < m.leg_min) | (legs > m.leg_max)
    if bad.any():
        k, i = (int(v[0]) for v in np.nonzero(bad))
        c, travel = m.cylinders[i], m.cylinders[i].travel
        raise KinematicsError(
            f"reference of scenario '{sc.name}' leaves the workspace at t = {k * h:.3f} s: actuator "
            f"'{c.name}' would be at {travel.value(legs[k, i])}, outside its {travel.span(m.leg_min[i], m.leg_max[i])}"
            f" ({m.source})")
    lim = m.coordinate_limits()
    units = m.coordinate_units
    for what, values, lo, hi in (("position", q_ref, lim["lower"], lim["upper"]),
                                 ("velocity", np.abs(sc.reference.velocities(t)), -np.inf, lim["velocity"])):
        bad = (values < lo) | (values > hi)
        if bad.any():
            k, i = (int(v[0]) for v in np.nonzero(bad))
            unit = units[i] if what == "position" else units[i] + "/s"
            bound = f"[{lo[i]}, {hi[i]}] {unit}" if what == "position" else f"{hi[i]} {unit}"
            raise KinematicsError(
                f"reference of scenario '{sc.name}' passes the {what} limit of joint '{m.coordinate_joint(i)}' at "
                f"t = {k * h:.3f} s: coordinate '{m.coordinate_names[i]}' {what} {values[k, i]:.4f} {unit}, "
                f"limit {bound} ({m.source})")


class Stepper:
    """The closed loop one control period per call, for users who write their own loop in Python.

    Each :meth:`step` is one direct call into the compiled loop driver (sensors,
    forward kinematics, controller, plant sub-steps), with every buffer made
    once here. Read the state through the properties between steps.

    Examples
    --------
    >>> st = hydrogen.stepper("paper-sim", "adaptive-robust")
    >>> for _ in range(1000):
    ...     st.step()
    >>> st.t, st.q
    """

    def __init__(self, dyn, scenario="paper-sim", controller="adaptive-robust", *, gains=None,
                 duration=None, check_workspace=True, **overrides):
        p = prepare_run(dyn, scenario, controller, gains, duration, check_workspace, overrides, keep_logs=False)
        self.scenario, self.controller, self.h, self.n_max = p.sc, p.ctrl, p.h, p.n
        self._noise = p.noise
        self._runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
        self._step = self._runner.stepper(self._noise)
        self._state = self._runner.state

    def step(self) -> None:
        """Advance one control period (raises SimulationError on divergence)."""
        k = self._state.k
        if k >= self.n_max:
            raise RunEndedError(f"scenario '{self.scenario.name}' has {self.n_max} periods; pass a longer "
                                "duration")
        code = self._step(k)
        if code:
            ctrl = self.controller
            cause = diverged_block(ctrl, self.xc, self.t) if ctrl.xc.size else None
            lead = f": {cause}; then it" if cause else ""
            raise SimulationError(f"simulation '{self.scenario.name}' with '{ctrl.kind}'{lead} "
                                  f"{_loop_failure(code, self._runner, self.h)}")

    @property
    def t(self) -> float:
        """Time of the next period, s."""
        return self._state.t

    @property
    def x(self) -> np.ndarray:
        """Plant state x, its parts in :func:`hydrogen.plant.plant_layout`'s order (each block's states:
        q, q̇, the pressures, spool, spool rate, the supply pressure where it is a state, ...)."""
        return self._runner.plant_state

    @property
    def q(self) -> np.ndarray:
        """True coordinates (n,)."""
        return self._runner.plant_state[slot(plant_layout(self.controller.model), "q").slice]

    @property
    def u(self) -> np.ndarray:
        """Last spool command (m,), m."""
        return self.controller.fn.output(0)

    @property
    def xc(self) -> np.ndarray:
        """Controller state (observer and estimates)."""
        return self._runner.xc[: self.controller.xc.size].copy()
