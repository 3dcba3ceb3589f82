"""Documented gain searches and stability margins, for any controller on any robot's rig.

**Scenarios.** The robot's rig scenarios (``rig = true`` in its description) with a periodic
reference (``reference.sines``); the coordinates a scenario *moves* are those with a non-zero
amplitude, the others are *off-axis*. :func:`rig_scenarios` lists them; a model with none is refused
(:func:`require_rig_scenarios` says what to add to its description).

**Main gain.** One scalar per controller, :func:`family`:

- ``p``: K (``Kleg``, m of spool per m of cylinder-length error);
- the model-based controllers: Λ of s = ė + Λ e (one value for every coordinate). τ_d holds
  −K_d s − K_p e = −K_d ė − (K_d Λ + K_p) e, so the position loop's stiffness grows in proportion
  to Λ (K_d Λ ≫ K_p) at a fixed damping: a factor on Λ is a gain margin of that loop. The search
  also tries, as secondary gains (:func:`secondary_grid`), the damping K_d (with K_p in proportion,
  ``Kd_scale`` × the controller's defaults 60 / 300 × scale) at 1/8, 1/4, 1/2, 1 and 2, and the force loop's
  K_τ at 1/4, 1/2 and 1 times its default; Γ_τ⁻¹, the observer and the adaptation keep the robot's
  gains.

**Stable.** A run at gain g on a scenario is *stable* when

1. it completes (no divergence, forward kinematics converges);
2. the valves saturate in at most 1 % of the periods (``SATURATION``);
3. no oscillation has started: the error's content above 5 × the reference's highest frequency
   (``hf_error_rms``, RMS, largest over the coordinates, m or rad), relative to the scenario's
   largest reference amplitude A, stays within twice a reference value (``OSCILLATION``) or below
   ``HF_FLOOR`` = 0.5 % of A (the noise-driven jitter), and never exceeds ``HF_CAP`` = 5 % of A. The
   reference value is, for the search, the smallest value at any gain up to g on the grid (the
   error first falls with the gain, then rises once the loop rings); for the margins, the value at
   the robot's gains. At the onset of an oscillation this content grows 5-10× from one grid point
   to the next, so the verdict does not hinge on these constants;
4. no burst: an oscillation that comes and goes (0.2-0.4 s of a 20-30 Hz ripple on the Stewart
   rig) moves the 4 s average little, so the same content's worst short window is judged too
   (``hf_error_burst``: its largest RMS over any window of 2 periods of the cut-off, 0.4 s at a
   1 Hz reference; :meth:`~hydrogen.simulation.simulator.SimulationResult.high_frequency_burst`),
   relative to the largest amplitude. It must stay within twice the reference worst window
   (``OSCILLATION``) or below ``BURST_FLOOR`` = 0.25 % of A, and never exceed ``BURST_CAP`` = 10 % of
   A. Its reference is the *median over the seeds* of the reference runs' worst windows (for the
   search, of each seed's smallest value at any gain up to g; for the margins, at the robot's
   gains), not the seed's own: a burst is an event of one seed, which its own reference run would
   already hold and so hide. The worst window of a steady run exceeds its 4 s RMS by a third or so
   and varies little from seed to seed (0.11-0.22 % of A over 50 seeds of adaptive-robust on the
   rig's z-1hz), so twice the median is clear of it; the floor sits above that steady jitter,
   half the average's, as the window is ten times shorter than the average's but holds several
   cycles of the ripple; the cap is twice the average's, an oscillation on any run.

**Seeds.** On the rig the adaptive loops are chaotic (a change of 10^-15 in the noise parts two
runs within seconds), so one noise seed is one draw of a distribution. Every run of the search and
of the margins is run for each of ``seeds`` noise seeds (default :data:`SEEDS` = 10: seeds 0..9),
each seed judged against its own reference value, and a gain is *stable* on a scenario only when
the run is stable for **every** seed. A row reports the median over the seeds of the max error and
its range (min, max); the tuned gain is chosen on the median.

**Tuned** (:func:`tune`). The grid is geometric with 4 points per octave, so 2 g is on it. A gain is
*admissible* when every grid gain from g up to the first at or past m g is stable on every scenario,
m the required margin (``margin``, default :data:`MARGIN` = 2: 6 dB, the classical requirement) on
the grid; a margin between grid points is rounded up to the next one. The tuned gain is the
admissible gain with the smallest worst-case max error (% of amplitude, over the scenarios' moving
coordinates), over every K_τ tried; the P error only falls with K, so for P it is the largest admissible gain. When no gain
is admissible (the loop rings at every gain of the grid), the search says so (``margin_ok`` False)
and falls back to the smallest worst-case error among the points that complete every scenario
with at most 1 % saturation: the least bad, not a tuned, controller.

**Headroom.** Bisection on other seeds finds a margin a little off the grid's 2 (1.8-2.0 where the
tuning seeds' own margin is 2.0-2.2): the grid cannot tell 2.0 from 2.37. Where the checking seeds
(``benchmarks/margins_checking.py``, seeds 100-119) find a margin below 2, the controller is
searched again on the same tuning seeds with ``margin`` = :data:`HEADROOM`, every grid gain up to
the next grid point past 2 g (2^(5/4) g = 2.38 g) stable, and checked again on the checking seeds.

**Margin** (:func:`margins`). For each controller and scenario, the factor c by which the main gain
of the robot's gains can grow while the run stays stable: c = 1, 2, 4, ... until unstable (at most
``MARGIN_MAX``), then bisection (geometric, ``MARGIN_STEPS`` halvings). It assumes, as the search does,
that a loop stable at c is stable at every smaller factor above 1.
"""
from __future__ import annotations

import numpy as np

from ..errors import HydrogenError, ScenarioError
from .seeds import DEFAULT_SEEDS, seed_list
from .simulator import SATURATION  # largest fraction of periods with a saturated valve

__all__ = ["tune", "tune_p", "margins", "rig_scenarios", "require_rig_scenarios", "family", "main_gain",
           "default_grid", "secondary_grid", "adaptation_grid", "judge_seeds", "burst_reference",
           "SATURATION", "OSCILLATION", "HF_FLOOR", "HF_CAP", "BURST_FLOOR", "BURST_CAP", "SEEDS", "MARGIN",
           "HEADROOM"]

OSCILLATION = 2.0    # high-frequency error may grow to this multiple of its reference value
HF_FLOOR = 0.005     # x the largest reference amplitude: below it, no oscillation is declared
HF_CAP = 0.05        # x the largest reference amplitude: above it, always an oscillation
BURST_FLOOR = 0.0025  # x the largest reference amplitude: a worst window below it is never a burst
BURST_CAP = 0.10      # x the largest reference amplitude: a worst window above it is always one
MARGIN_MAX = 16.0
MARGIN_STEPS = 5
PER_OCTAVE = 4
MARGIN = 2.0          # gain margin a tuned point holds on the grid (6 dB)
HEADROOM = 2.0 ** (1 + 1 / PER_OCTAVE)  # the next grid point past 2: room for seeds the search never saw
GRID_TOLERANCE = 1e-3  # relative: a grid gain within it of margin x g counts as reached (2.378: 2^(5/4))
SEEDS = DEFAULT_SEEDS  # noise seeds (0 .. SEEDS-1) every gain is judged over


def _load(model):
    from ..runtime.build import as_model
    return as_model(model)


def rig_scenarios(model=None, variant: str | None = None, untuned: bool = False) -> dict:
    """{scenario name: (moving coordinate names)} for the rig scenarios with a periodic reference;
    with ``variant`` (a ``[variants.<name>]`` of the description), each as ``<scenario>.<variant>``.
    A scenario whose table says ``tuned = false`` (no gain is chosen for it) is left out unless
    ``untuned``."""
    from ..errors import ScenarioError
    from .scenarios import scenario, scenario_names, variant_name, variant_names

    model = _load(model)
    if variant is not None and variant_name(variant, model) is None:
        known = ", ".join(variant_names(model)) or "none: add [variants.<name>] tables to its description"
        raise ScenarioError(f"unknown variant {variant!r} for model '{model.name}'; variants: {known}")
    variant = None if variant is None else variant_name(variant, model)  # a former name: the current one
    out = {}
    for name in scenario_names(model):
        table = model.scenarios[name] or {}
        if not table.get("rig") or (table.get("tuned") is False and not untuned):
            continue
        sc = scenario(name, model)
        if sc.reference.frequencies():  # periodic: its tracking is what a gain search judges
            amp = sc.reference.amplitude()
            moving = tuple(c for c, a in zip(model.coordinate_names, amp) if a > 0)
            if moving:  # every amplitude 0: nothing to judge the tracking of
                out[name if variant is None else f"{name}.{variant}"] = moving
    return out


def _why_not_rig(model, name) -> str:
    """Why the model's scenario ``name`` is not a rig scenario with a periodic reference."""
    spec = model.scenarios[name] or {}
    if not spec.get("rig"):
        return "no rig = true"
    ref = spec.get("reference")
    kind = next(iter(ref), "none") if isinstance(ref, dict) and ref else "none"
    return f"reference.{kind}, not reference.sines" if kind != "sines" else "every amplitude 0"


def require_rig_scenarios(model, what: str = "tuning", variant: str | None = None) -> dict:
    """:func:`rig_scenarios` of ``model`` (at ``variant``); a :class:`~hydrogen.errors.ScenarioError`
    saying what to add to the description when it has none (``what``: the command, for the message)."""
    from ..errors import ScenarioError
    from .scenarios import scenario_names

    found = rig_scenarios(model, variant)
    if found:
        return found
    names = scenario_names(model)
    have = ("; its scenarios: " + ", ".join(f"{n} ({_why_not_rig(model, n)})" for n in names)) if names else \
        "; it has no [scenarios] table"
    c = model.coordinate_names[0]
    raise ScenarioError(
        f"{what} needs a rig scenario with a periodic reference, and model '{model.name}' ({model.source}) has none"
        f"{have}. Add to the description a table [scenarios.<name>] with rig = true and reference.sines = "
        f"[[coordinate, amplitude, Hz], ...] (e.g. [[\"{c}\", {0.02 if model.coordinate_units[0] == 'm' else 0.05}, "
        f"1.0]], an offset from the neutral pose); rig = true starts the scenario from the description's [rig] "
        f"table of the rig's settings, "
        + ("which it has" if (model.scenarios or {}).get("rig") else
           "which it lacks: add [rig] with at least duration, control_rate, substeps and t_adapt")
        + " (any Scenario field may be set there or in the scenario)")


def _base_gains(dyn, controller, robot: bool):
    """The controller's defaults for the model (``robot``: with the robot's [gains] tables)."""
    from ..controllers import controller as controller_module
    from .control import default_gains, gain_scale

    if robot:
        return default_gains(dyn, controller)
    return controller_module(controller).default_gains(dyn.model, gain_scale(dyn))


def main_gain(controller) -> str:
    """Name of the controller's main gain (its spec's)."""
    from ..controllers import spec
    return spec(controller).main_gain


def family(dyn, controller, g, base=None) -> dict:
    """Gains with main gain ``g`` (see the module doc); ``base``: gains whose proportions are kept
    (default: the controller's own defaults for the model, or the description's gains where the
    controller's spec keeps the description's proportions)."""
    from ..controllers import spec
    sp = spec(controller)
    if sp.main_gain_shared:
        return {sp.main_gain: float(g)}
    base = base or _base_gains(dyn, controller, robot=sp.search_description_proportions)
    lam = np.asarray(base[sp.main_gain], float)
    return {sp.main_gain: (lam * (g / float(np.mean(lam)))).tolist()}


def _secondary(dyn, controller, point: dict) -> dict:
    """Gains of a secondary grid point: ``Kd_scale`` scales the defaults' K_d and K_p, others are gains."""
    out = {}
    for k, v in point.items():
        if k == "Kd_scale":
            base = _base_gains(dyn, controller, robot=False)
            out["Kd"] = (np.asarray(base["Kd"], float) * v).tolist()
            out["Kp"] = (np.asarray(base["Kp"], float) * v).tolist()
        else:
            out[k] = float(v)
    return out


def default_grid(controller) -> np.ndarray:
    """The documented grid: 4 points per octave over six octaves from the controller's ``grid_low``
    (its spec: 0.005-0.32 for P's K, 5-320 1/s for Λ)."""
    from ..controllers import spec
    lo = spec(controller).grid_low
    return lo * 2.0 ** (np.arange(6 * PER_OCTAVE + 1) / PER_OCTAVE)


def _hf(m, key: str = "hf_error_rms") -> float:
    """Largest high-frequency error over the coordinates (``key``: the 4 s RMS, ``hf_error_burst``: the
    worst short window's), as a fraction of the largest amplitude; 0 where the metrics lack it."""
    amp = max((v for v in (m.get("amplitude") or {}).values()), default=0.0)
    hf = max((v for v in (m.get(key) or {}).values()), default=0.0)
    return hf / amp if amp > 0 else 0.0


def _burst(m) -> float:
    """The worst short window's high-frequency error (:func:`_hf` of ``hf_error_burst``)."""
    return _hf(m, "hf_error_burst")


def _burst_at(m) -> float:
    """When (s) the worst window of the coordinate with the largest burst starts."""
    burst = m.get("hf_error_burst") or {}
    c = max(burst, key=burst.get)
    return float(m["hf_error_burst_t"][c])


def burst_reference(per_seed) -> float:
    """The burst rule's reference: the median over the completed runs of ``per_seed`` (metrics, one
    per seed) of their worst window (:func:`_burst`); 0 when none completed."""
    done = [_burst(m) for m in per_seed if "error" not in m]
    return float(np.median(done)) if done else 0.0


def _judge(m, hf_ref, burst_ref=0.0):
    """(stable, reason) of one run's metrics, against the reference high-frequency error (4 s RMS)
    ``hf_ref`` and the reference worst window ``burst_ref`` (fractions of the largest amplitude)."""
    if "error" in m:
        return False, "diverged: " + m["error"][:80]
    if m["u_saturation_frac"] > SATURATION:
        return False, f"saturates {100 * m['u_saturation_frac']:.1f} % of periods"
    hf = _hf(m)
    if hf > HF_CAP:
        return False, f"oscillation: high-frequency error {100 * hf:.2f} % of amplitude > {100 * HF_CAP:g} %"
    if hf > max(OSCILLATION * hf_ref, HF_FLOOR):
        return False, (f"oscillation: high-frequency error {100 * hf:.2f} % of amplitude > "
                       f"{OSCILLATION:g} x {100 * hf_ref:.2f} %")
    burst = _burst(m)
    if burst > BURST_CAP or burst > max(OSCILLATION * burst_ref, BURST_FLOOR):
        bound = f"{100 * BURST_CAP:g} %" if burst > BURST_CAP else f"{OSCILLATION:g} x {100 * burst_ref:.2f} %"
        return False, (f"burst: high-frequency error {100 * burst:.2f} % of amplitude over the worst short "
                       f"window (from t = {_burst_at(m):.2f} s) > {bound}")
    return True, ""


def judge_seeds(summary, hf_refs, burst_ref=0.0) -> tuple:
    """(stable, reason, unstable seeds) of one sweep entry run over seeds (its
    :func:`~hydrogen.simulation.seeds.summarize`): stable only when every seed's run is, each against
    its own reference high-frequency error ``hf_refs[i]`` and all against the reference worst window
    ``burst_ref`` (:func:`burst_reference`; 0: only BURST_FLOOR and BURST_CAP bound it); the reason
    names the first seed that fails."""
    bad = []
    for s, m, ref in zip(summary["seeds"], summary["per_seed"], hf_refs):
        stable, reason = _judge(m, ref, burst_ref)
        if not stable:
            bad.append((s, reason))
    if not bad:
        return True, "", []
    n = len(summary["seeds"])
    return False, f"{bad[0][1]} (seed {bad[0][0]}; unstable on {len(bad)} of {n} seeds)", [s for s, _ in bad]


def _spread(values) -> dict:
    a = np.asarray(values, float)
    return {"median": float(np.median(a)), "min": float(a.min()), "max": float(a.max())}


def _worst(m, moving) -> float:
    return max(m["max_error_pct"][c] for c in moving)


def secondary_grid(dyn, controller) -> dict:
    """The gains searched with the main one (model-based controllers; none for P): ``Kd_scale`` (K_d
    and K_p × 1/8 ... 2 the defaults, by octaves) and K_τ at 1/4, 1/2 and 1 times its default."""
    from ..controllers import spec
    if not spec(controller).secondary_search:
        return {}
    k0 = float(np.mean(_base_gains(dyn, controller, robot=False)["Ktau"]))
    return {"Kd_scale": [0.125, 0.25, 0.5, 1.0, 2.0], "Ktau": [k0 * f for f in (0.25, 0.5, 1.0)]}


def _margin_points(gs, g, margin) -> list:
    """The grid gains a margin of ``margin`` at ``g`` needs stable: from g up to the first grid gain at
    or past margin x g (within GRID_TOLERANCE: 2.378 reaches 2^(5/4) g); none when the grid ends below."""
    top = next((h for h in gs if h >= margin * g * (1 - GRID_TOLERANCE)), None)
    return [] if top is None else [h for h in gs if g <= h <= top]


def _check_margin(margin) -> None:
    """A :class:`HydrogenError` unless ``margin`` is a finite number >= 1."""
    if isinstance(margin, bool) or not isinstance(margin, (int, float, np.floating)) or not np.isfinite(margin) \
            or margin < 1.0:
        raise HydrogenError(f"the required gain margin must be a finite number >= 1, not {margin!r}")


def _check_controller(controller) -> None:
    from ..controllers import CONTROLLERS

    if controller not in CONTROLLERS:
        raise ScenarioError(f"tune: no controller {controller!r}; controllers: {', '.join(CONTROLLERS)}")


def _gain_values(what: str, values, adaptation: bool = False) -> np.ndarray:
    """``values`` of a searched gain: a non-empty list of finite numbers > 0 (an adaptation gain's: >= 0,
    0 the paper's law, or NaN where the controller derives the gain, as its spec's search has them),
    else a ScenarioError."""
    try:
        if np.asarray(values).dtype == bool:
            raise ValueError
        out = np.asarray(values, float).reshape(-1)
    except (TypeError, ValueError):
        out = None
    ok = None if out is None else (np.isnan(out) | (out >= 0)) if adaptation else np.isfinite(out) & (out > 0)
    if out is None or not out.size or not np.all(ok) or np.any(np.isinf(out)):
        rule = "gains >= 0 (or NaN: derived)" if adaptation else "finite gains > 0"
        raise ScenarioError(f"tune: {what} must be a non-empty list of {rule}, got {values!r}"[:300])
    return out


def _gain_grid(what: str, grid, dyn, controller) -> dict:
    """A ``secondary`` or ``adaptation`` search, {gain: values}: each gain one of the controller's (or
    ``Kd_scale`` for the secondary search), its values as :func:`_gain_values` takes them."""
    if not hasattr(grid, "items"):
        raise ScenarioError(f"tune: {what} must map gain names to lists of values, got {grid!r}"[:300])
    known = set(_base_gains(dyn, controller, robot=True)) | ({"Kd_scale"} if what == "secondary" else set())
    unknown = sorted(str(k) for k in grid if k not in known)
    if unknown:
        raise ScenarioError(f"tune: {what} names no gain of '{controller}': {', '.join(unknown)}; its gains: "
                            f"{', '.join(sorted(known))}")
    return {k: _gain_values(f"{what} {k}", v, what == "adaptation") for k, v in grid.items()}


def _scenarios(scenarios, model) -> dict:
    """``scenarios`` as :func:`rig_scenarios` gives them, {name: (coordinates judged)}: given so, or as
    names of ``model``'s scenarios (each judged on the coordinates its reference moves)."""
    from .scenarios import scenario

    def bad():
        return ScenarioError(f"tune: scenarios must be names of the model's scenarios or {{name: (coordinates "
                             f"judged)}}, got {scenarios!r}"[:300])
    if isinstance(scenarios, (str, bytes)) or not hasattr(scenarios, "__iter__"):
        raise bad()
    if hasattr(scenarios, "items"):
        out = {}
        for name, coords in scenarios.items():
            coords = (coords,) if isinstance(coords, str) else tuple(coords) if hasattr(coords, "__iter__") else ()
            unknown = [c for c in coords if c not in model.coordinate_names]
            if not coords or unknown:
                raise ScenarioError(f"tune: scenario {name!r} is judged on coordinates {coords!r}; the model's "
                                    f"coordinates: {', '.join(model.coordinate_names)}")
            out[name] = coords
        return out
    if not all(isinstance(name, str) for name in scenarios):
        raise bad()
    out = {}
    for name in scenarios:
        amp = scenario(name, model).reference.amplitude()
        out[name] = tuple(c for c, a in zip(model.coordinate_names, amp) if a > 0)
        if not out[name]:
            raise ScenarioError(f"tune: scenario {name!r}'s reference moves no coordinate: nothing to judge")
    return out


def tune(controller, grid=None, *, model=None, scenarios=None, secondary=None, adaptation=None,
         executor=None, max_workers=None, progress: bool = False, seeds=None,
         variant: str | None = None, numbers: str | None = None, margin: float = MARGIN) -> dict:
    """The documented search for ``controller`` on ``model``'s rig scenarios (module doc).

    ``grid``: main-gain values (default :func:`default_grid`); ``secondary``: {gain: values} searched
    alongside it (default :func:`secondary_grid`; the margin rule applies along the main gain for each
    of its values); ``adaptation``: {gain: values} of the second stage, tried one gain at a time at
    the chosen point, each over the whole main grid (default :func:`adaptation_grid`, the
    controller's spec; ``{}``: none); ``seeds``: the noise seeds every point is judged over (a count N: 0..N-1, or a
    list; default :data:`SEEDS`); ``variant``: the rig scenarios at that variant of the description
    (``<scenario>.<variant>``); ``numbers``: how the model is built (:func:`hydrogen.build`'s; None: its
    default); ``margin``: the gain margin a tuned point must hold on the grid (default :data:`MARGIN` = 2;
    :data:`HEADROOM` = 2^(5/4), the next grid point, where the checking seeds find less than 2). Returns
    {"controller", "main_gain", "grid", "seeds", "margin", "table": [row
    per scenario, secondary value and gain: "max_error_pct" the median over the seeds of the worst
    moving coordinate's max error %, "max_error_range" [min, max], "errors" {coordinate: {median, min,
    max}}, "unstable_seeds"], "best": g or None, "best_gains": the gains dict at the tuned point,
    "gains_used": those over the rest of the set its runs used (the robot's gains, under a variant's),
    "best_errors": {scenario: median worst max error %}, "best_error_ranges": {scenario: [min, max]},
    "largest_stable": the largest main gain stable on every scenario and seed (at the tuned secondary
    value), "margin_ok": whether "best" has a gain margin of ``margin`` (else it is the fallback of the
    module doc), "grid_spans_margin": whether the grid is wide enough for any gain to show it}.
    """
    import itertools

    from ..runtime.build import build
    from .sweep import check_workers, sweep

    _check_controller(controller)
    grid = np.sort(_gain_values("grid", default_grid(controller) if grid is None else grid))
    _check_margin(margin)
    model = _load(model)
    if executor is None:
        check_workers(max_workers)
    scen = _scenarios(scenarios, model) if scenarios else \
        require_rig_scenarios(model, f"tune --controller {controller}", variant)
    seeds = seed_list(DEFAULT_SEEDS if seeds is None else seeds)
    report = _build_report(progress)
    options = {} if numbers is None else {"numbers": numbers}
    dyn = build(model, controllers=(controller,), progress=report, **options)
    sec = secondary_grid(dyn, controller) if secondary is None else _gain_grid("secondary", secondary, dyn, controller)
    sec_points = [dict(zip(sec, v)) for v in itertools.product(*sec.values())] or [{}]
    setters = [k for k in sec if main_gain(controller) in _secondary(dyn, controller, {k: sec[k][0]})]
    if setters:  # every secondary point would overwrite the main gain: each grid column the same run
        sets = "; ".join(f"{k} sets " + ", ".join(sorted(_secondary(dyn, controller, {k: sec[k][0]})))
                         for k in setters)
        raise ScenarioError(
            f"tune: controller '{controller}''s main gain '{main_gain(controller)}' is also set by the secondary "
            f"search: {sets}; choose another main gain in its spec, or pass secondary= without "
            + ", ".join(setters))
    own = _own_gains(dyn, controller, next(iter(scen)), model)
    stages = adaptation_grid(dyn, controller, own) if adaptation is None else \
        [(k, vs.tolist()) for k, vs in _gain_grid("adaptation", adaptation, dyn, controller).items()]
    # every variant the runs will use (lean or full), compiled here with its progress shown, not by
    # one worker on its first run while the others wait on the build lock, saying nothing
    for g in _variant_gains(own, sec_points, stages):
        build(model, controllers=(controller,), gains={controller: g}, progress=report, **options)
    name = main_gain(controller)
    gs = list(map(float, grid))

    def gains(g, extra):
        out = family(dyn, controller, g)
        out.update(_secondary(dyn, controller, extra))
        return out

    table = []

    def search(points):
        """Every point over the main grid: per point (key, g, point, largest), key ranking its best g."""
        runs = [dict(scenario=s, controller=controller, gains=gains(g, x))
                for x in points for s in scen for g in grid]
        out = iter(sweep(runs, executor=executor, max_workers=max_workers, model=model, progress=progress,
                         seeds=seeds, numbers=numbers))
        picks = []
        for x in points:
            ok, worst, bounded = _judge_point(out, scen, gs, seeds, name, x, table)
            admissible = [(worst[g], -g, g) for g in gs
                          if (need := _margin_points(gs, g, margin)) and all(ok[h] for h in need)]
            fallback = [(worst[g], -g, g) for g in gs if bounded[g]]
            largest = max((g for g in gs if ok[g]), default=None)
            # A point with the margin beats every point without one; then the smaller error.
            best = (0, *min(admissible)) if admissible else ((1, *min(fallback)) if fallback else None)
            if best is not None:
                picks.append(((best[0], best[1], best[2]), best[3], x, largest))
        return picks

    picks = search(sec_points)
    pick = min(picks, key=lambda p: p[0]) if picks else None
    searched = {}
    for k, values in stages:  # the second stage: one adaptation gain at a time, the rest kept
        at = pick[2] if pick is not None else sec_points[0]
        now = at.get(k, float(np.mean(own[k])))
        searched[k] = list(values)
        found = search([{**at, k: v} for v in values if not _same(v, now)])
        if found and (pick is None or min(found, key=lambda p: p[0])[0] < pick[0]):
            pick = min(found, key=lambda p: p[0])
    margin_ok = pick is not None and pick[0][0] == 0
    best, x, largest = (pick[1], pick[2], pick[3]) if pick is not None else (None, {}, None)
    here = [r for r in table if best is not None and r["gain"] == best and _at(r, x)]
    tuned = gains(best, x) if best is not None else None
    return {
        "controller": controller, "model": model.name, "main_gain": name, "grid": gs, "secondary": sec,
        "adaptation": searched, "seeds": seeds, "margin": float(margin),
        # no gain of a grid spanning less than the margin can show it: not a ringing loop
        "grid_spans_margin": bool(_margin_points(gs, gs[0], margin)),
        "table": table, "best": best, "best_secondary": x, "margin_ok": margin_ok,
        "best_gains": tuned,
        # the whole set the runs at the tuned point used: the search's, over the robot's (under a variant's)
        "gains_used": {**own, **tuned} if tuned is not None else None,
        "best_errors": {r["scenario"]: r.get("max_error_pct") for r in here},
        "best_error_ranges": {r["scenario"]: r.get("max_error_range") for r in here},
        "largest_stable": largest,
    }


def _build_report(progress: bool):
    """The build's progress callback of a search run with ``progress``: one line on stderr per stage of
    a generation or compile (:func:`hydrogen.progress.print_event`); None without."""
    from ..progress import print_event
    return print_event if progress else None


def _variant_gains(own: dict, points: list, stages: list) -> list:
    """One set of gains per controller variant (lean, full) the search's runs use: its first stage at
    each of ``points`` over the run's own gains ``own``, its second stage with each value of each of
    ``stages`` ([(gain, values)]) over those (a composite rate set non-zero runs the full variant)."""
    from ..controllers.common import runs_lean
    sets = [{**own, **x} for x in points]
    sets += [{**s, k: v} for s in sets[:1] for k, values in stages for v in values]
    out = {}
    for g in sets:
        out.setdefault(runs_lean(g), g)
    return list(out.values())


def _same(a, b) -> bool:
    a, b = float(a), float(b)
    return (np.isnan(a) and np.isnan(b)) or a == b


def _at(row, point) -> bool:
    """Whether a table row was run at the secondary/adaptation ``point``, and at nothing else."""
    return all(_same(row.get(k, np.nan), v) for k, v in point.items()) and \
        all(k in point for k in row.get("searched", ()))


def _judge_point(out, scen, gs, seeds, name, x, table):
    """Judge one secondary point's runs (the next of ``out``, scenario by scenario along the grid),
    appending a row per scenario and gain to ``table``; ({g: stable}, {g: worst error}, {g: bounded})."""
    ok, worst = {g: True for g in gs}, {g: 0.0 for g in gs}
    bounded = {g: True for g in gs}
    for s, moving in scen.items():
        hf_min = [np.inf] * len(seeds)  # per seed: its smallest value at any gain up to g
        burst_min = [np.inf] * len(seeds)  # the same of the worst window
        for g in gs:
            m = next(out)
            per = m["per_seed"]
            hf_min = [h if "error" in r else min(h, _hf(r)) for h, r in zip(hf_min, per)]
            burst_min = [b if "error" in r else min(b, _burst(r)) for b, r in zip(burst_min, per)]
            done = [b for b in burst_min if np.isfinite(b)]
            stable, reason, unstable = judge_seeds(m, hf_min, float(np.median(done)) if done else 0.0)
            row = {"scenario": s, name: g, "gain": g, **x, "searched": tuple(x), "stable": stable,
                   "reason": reason, "unstable_seeds": unstable}
            done = [r for r in per if "error" not in r]
            if done:
                w = _spread([_worst(r, moving) for r in done])
                row.update(max_error_pct=w["median"], max_error_range=[w["min"], w["max"]],
                           hf_error=float(np.median([_hf(r) for r in done])),
                           saturation=max(r["u_saturation_frac"] for r in done),
                           errors={c: _spread([r["max_error_pct"][c] for r in done]) for c in moving})
            if len(done) == len(per):
                worst[g] = max(worst[g], row["max_error_pct"])
                bounded[g] = bounded[g] and row["saturation"] <= SATURATION
            else:  # a seed diverged: no error to rank this point by
                worst[g] = np.inf
                bounded[g] = False
            ok[g] = ok[g] and stable
            table.append(row)
    return ok, worst, bounded


def _own_gains(dyn, controller, scenario_name, model) -> dict:
    """The gains a run of ``scenario_name`` uses where the search sets none: the robot's, under the
    scenario's own (a variant's)."""
    from .scenarios import scenario
    own = _base_gains(dyn, controller, robot=True)
    own.update(scenario(scenario_name, model).gains.get(controller, {}))
    return own


def adaptation_grid(dyn, controller, own=None) -> list:
    """The second stage's [(gain, values)] for ``controller`` (its spec's ``adaptation_search``), the
    factors ("x") made values from ``own`` (default: the robot's gains), the gain the runs use."""
    from ..controllers import spec
    own = _base_gains(dyn, controller, robot=True) if own is None else own
    return [(k, [float(np.mean(own[k])) * f for f in values] if how == "x" else [float(v) for v in values])
            for k, how, values in spec(controller).adaptation_search]


def tune_p(gains=None, scenarios=None, *, executor=None, max_workers=None, model=None,
           progress: bool = False, seeds=None, variant: str | None = None, numbers: str | None = None) -> dict:
    """:func:`tune` for the baseline P controller (its rows also carry its main gain)."""
    from ..controllers import baseline
    return tune(baseline(), gains, model=model, scenarios=scenarios, executor=executor, max_workers=max_workers,
                progress=progress, seeds=seeds, variant=variant, numbers=numbers)


def margins(controllers=None, *, model=None, scenarios=None, executor=None, max_workers=None,
            progress: bool = False, seeds=None, variant: str | None = None, numbers: str | None = None) -> dict:
    """Stability margin of each controller's main gain on each rig scenario (module doc), from the
    robot's gains, judged over ``seeds`` (a count N: 0..N-1, or a list; default :data:`SEEDS`): a
    factor is stable only when every seed's run is; ``variant``, ``numbers``: as :func:`tune`. Returns {"model", "seeds", "rows": [{controller,
    scenario, main_gain, gain, margin, margin_capped, limit_reason, errors: {moving coordinate:
    {median, min, max} of the max error % at the robot's gains}, median_seed, unstable_seeds: the
    seeds unstable at the first unstable factor}]}; ``margin`` is the largest factor found stable
    (>= MARGIN_MAX: ``margin_capped``), 0 when the robot's gains themselves fail on a seed."""
    from ..runtime.build import build
    from .sweep import check_workers, sweep

    model = _load(model)
    if executor is None:
        check_workers(max_workers)
    scen = list(scenarios) if scenarios else list(require_rig_scenarios(model, "margins", variant))
    seeds = seed_list(DEFAULT_SEEDS if seeds is None else seeds)
    cases = [(c, s) for c in (controllers or model.controllers) for s in scen]
    dyn = build(model, controllers=tuple(dict.fromkeys(c for c, _ in cases)), progress=_build_report(progress),
                **({} if numbers is None else {"numbers": numbers}))
    # The gains each case runs with: the robot's, under the scenario's own (a variant's gains).
    base = [_own_gains(dyn, c, s, model) for c, s in cases]
    g0 = [float(np.mean(b[main_gain(c)])) for b, (c, _) in zip(base, cases)]

    def run(factors: dict) -> dict:
        """{case index: factor} -> {case index: its runs over the seeds}; only those cases run."""
        todo = sorted(factors)
        runs = [dict(scenario=cases[i][1], controller=cases[i][0],
                     gains=family(dyn, cases[i][0], g0[i] * factors[i], base[i])) for i in todo]
        out = sweep(runs, executor=executor, max_workers=max_workers, model=model, progress=progress, seeds=seeds,
                    numbers=numbers)
        return dict(zip(todo, out))

    ref = run({i: 1.0 for i in range(len(cases))})
    hf_ref = [[_hf(m) if "error" not in m else np.inf for m in ref[i]["per_seed"]] for i in range(len(cases))]
    burst_ref = [burst_reference(ref[i]["per_seed"]) for i in range(len(cases))]
    first = [judge_seeds(ref[i], hf_ref[i], burst_ref[i]) for i in range(len(cases))]
    lo = [1.0 if v[0] else 0.0 for v in first]
    hi = [None] * len(cases)
    why = [None if v[0] else v[1] for v in first]
    unstable = [v[2] for v in first]

    def judge(i, m, f):
        stable, reason, bad = judge_seeds(m, hf_ref[i], burst_ref[i])
        if stable:
            lo[i] = f
        else:
            hi[i], why[i], unstable[i] = f, reason, bad

    f = 2.0
    while f <= MARGIN_MAX:  # doubling until unstable
        todo = [i for i in range(len(cases)) if lo[i] and hi[i] is None]
        if not todo:
            break
        for i, m in run({i: f for i in todo}).items():
            judge(i, m, f)
        f *= 2
    for _ in range(MARGIN_STEPS):  # geometric bisection between the last stable and the first unstable
        todo = [i for i in range(len(cases)) if lo[i] and hi[i] is not None]
        if not todo:
            break
        mids = {i: float(np.sqrt(lo[i] * hi[i])) for i in todo}
        for i, m in run(mids).items():
            judge(i, m, mids[i])
    rows = []
    for i, (c, s) in enumerate(cases):
        pct = ref[i]["median"].get("max_error_pct") or {}
        errors = {k: {"median": v, "min": ref[i]["min"]["max_error_pct"][k], "max": ref[i]["max"]["max_error_pct"][k]}
                  for k, v in pct.items() if v is not None}
        rows.append({"controller": c, "scenario": s, "main_gain": main_gain(c), "gain": g0[i], "margin": float(lo[i]),
                     "margin_capped": hi[i] is None and lo[i] > 0, "limit_reason": why[i] or "",
                     "errors": errors, "median_seed": ref[i]["median_seed"], "unstable_seeds": unstable[i],
                     "estimates": estimates(model, c, ref[i]["seeds"], ref[i]["per_seed"])})
    return {"model": model.name, "seeds": seeds, "rows": rows}


#: An estimate within this fraction of its projection interval's width of a bound is at the bound.
AT_BOUND = 1e-6


def estimates(model, controller, seeds, per_seed) -> dict | None:
    """The adaptive estimates at the end of the runs over seeds (None for a controller that does not
    adapt): "theta_error_pct", "gamma_error_pct" the median over the seeds of the largest final error
    of each family (|θ̂ − θ|/|θ|, parameters with θ ≠ 0; |γ̂ − γ|/γ over the cylinders and γ1, γ2),
    % of the true value, and "at_bound" ["<estimate> (seed s)"] the estimates a run ends at a
    projection bound with (``AT_BOUND``)."""
    from .checks import adapts
    if not adapts(controller, model):
        return None
    th_err, ga_err, at = [], [], []
    for s, m in zip(seeds, per_seed):
        if "error" in m:
            continue
        th, tt = np.asarray(m["theta_hat_final"], float), np.asarray(m["theta_true"], float)
        g, gt = np.asarray(m["gamma_hat_final"], float), np.asarray(m["gamma_true"], float)
        nz = tt != 0
        th_err.append(float(np.max(np.abs(th[nz] - tt[nz]) / np.abs(tt[nz]))) * 100 if nz.any() else 0.0)
        ga_err.append(float(np.max(np.abs(g - gt) / np.abs(gt))) * 100)
        bounds = [(n, v, lo, hi) for n, v, lo, hi in zip(m["theta_names"], th, model.theta_min, model.theta_max)]
        for k, (lo, hi) in enumerate([(model.gamma1_min, model.gamma1_max), (model.gamma2_min, model.gamma2_max)]):
            bounds += [(f"gamma{k + 1}[{j}]", v, lo, hi) for j, v in enumerate(g[k])]
        at += [f"{n} (seed {s})" for n, v, lo, hi in bounds
               if min(v - lo, hi - v) <= AT_BOUND * (hi - lo)]
    if not th_err:
        return None
    return {"theta_error_pct": float(np.median(th_err)), "gamma_error_pct": float(np.median(ga_err)),
            "at_bound": at}
