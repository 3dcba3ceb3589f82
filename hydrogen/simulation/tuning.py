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
   to the next, so the verdict does not hinge on these constants.

**Tuned** (:func:`tune`). The grid is geometric with 4 points per octave, so 2 g is on it. A gain is
*admissible* when every grid gain in [g, 2 g] is stable on every scenario: a gain margin of at least 2
(6 dB, the classical requirement) on the grid. The tuned gain is the admissible gain with the
smallest worst-case max error (% of amplitude, over the scenarios' moving coordinates), over every
K_τ tried; the P error only falls with K, so for P it is the largest admissible gain. When no gain
is admissible (the loop rings at every gain of the grid), the search says so (``margin_ok`` False)
and falls back to the smallest worst-case error among the points that complete every scenario
with at most 1 % saturation: the least bad, not a tuned, controller.

**Margin** (:func:`margins`). For each controller and scenario, the factor c by which the main gain
of the robot's gains can grow while the run stays stable: c = 1, 2, 4, ... until unstable (at most
``MARGIN_MAX``), then bisection (geometric, ``MARGIN_STEPS`` halvings). It assumes, as the search does,
that a loop stable at c is stable at every smaller factor above 1.
"""
from __future__ import annotations

import numpy as np

__all__ = ["tune", "tune_p", "margins", "rig_scenarios", "require_rig_scenarios", "family", "main_gain",
           "default_grid", "secondary_grid",
           "SATURATION", "OSCILLATION", "HF_FLOOR", "HF_CAP"]

SATURATION = 0.01    # largest fraction of periods with a saturated valve
OSCILLATION = 2.0    # high-frequency error may grow to this multiple of its reference value
HF_FLOOR = 0.005     # x the largest reference amplitude: below it, no oscillation is declared
HF_CAP = 0.05        # x the largest reference amplitude: above it, always an oscillation
MARGIN_MAX = 16.0
MARGIN_STEPS = 5
PER_OCTAVE = 4


def _load(model):
    import hydrogen
    return model if isinstance(model, hydrogen.Model) else hydrogen.load_model(model)


def rig_scenarios(model=None) -> dict:
    """{scenario name: (moving coordinate names)} for the rig scenarios with a periodic reference."""
    from .reference import MultiSine
    from .scenarios import scenario, scenario_names

    model = _load(model)
    out = {}
    for name in scenario_names(model):
        if not (model.scenarios[name] or {}).get("rig"):
            continue
        sc = scenario(name, model)
        if isinstance(sc.reference, MultiSine):
            amp = sc.reference.amplitude()
            moving = tuple(c for c, a in zip(model.coordinate_names, amp) if a > 0)
            if moving:  # every amplitude 0: nothing to judge the tracking of
                out[name] = moving
    return out


def _why_not_rig(model, name) -> str:
    """Why the model's scenario ``name`` is not a rig scenario with a periodic reference."""
    spec = model.scenarios[name] or {}
    if not spec.get("rig"):
        return "no rig = true"
    ref = spec.get("reference")
    kind = next(iter(ref), "none") if isinstance(ref, dict) and ref else "none"
    return f"reference.{kind}, not reference.sines" if kind != "sines" else "every amplitude 0"


def require_rig_scenarios(model, what: str = "tuning") -> dict:
    """:func:`rig_scenarios` of ``model``; a :class:`~hydrogen.errors.ScenarioError` saying what to add
    to the description when it has none (``what``: the command, for the message)."""
    from ..errors import ScenarioError
    from .scenarios import scenario_names

    found = rig_scenarios(model)
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
    (default: the controller's own defaults for the model)."""
    from ..controllers import spec
    sp = spec(controller)
    if sp.main_gain_shared:
        return {sp.main_gain: float(g)}
    base = base or _base_gains(dyn, controller, robot=False)
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


def _hf(m) -> float:
    """Largest high-frequency error RMS over the coordinates, as a fraction of the largest amplitude."""
    amp = max((v for v in (m.get("amplitude") or {}).values()), default=0.0)
    hf = max((v for v in (m.get("hf_error_rms") or {}).values()), default=0.0)
    return hf / amp if amp > 0 else 0.0


def _judge(m, hf_ref):
    """(stable, reason) of one run's metrics, against the reference high-frequency error."""
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
    return True, ""


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


def tune(controller, grid=None, *, model=None, scenarios=None, secondary=None, executor=None,
         max_workers=None, progress: bool = False) -> dict:
    """The documented search for ``controller`` on ``model``'s rig scenarios (module doc).

    ``grid``: main-gain values (default :func:`default_grid`); ``secondary``: {gain: values} searched
    alongside it (default :func:`secondary_grid`; the margin rule applies along the main gain for each
    of its values). Returns {"controller", "main_gain", "grid", "table": [row per scenario, secondary
    value and gain], "best": g or None, "best_gains": the gains dict at the tuned point,
    "best_errors": {scenario: worst max error %}, "largest_stable": the largest main gain stable on
    every scenario (at the tuned secondary value), "margin_ok": whether "best" has a gain margin of 2
    (else it is the fallback of the module doc)}.
    """
    import itertools

    import hydrogen
    from .sweep import check_workers, sweep

    model = _load(model)
    if executor is None:
        check_workers(max_workers)
    scen = dict(scenarios) if scenarios else require_rig_scenarios(model, f"tune --controller {controller}")
    dyn = hydrogen.build(model)
    grid = np.sort(np.asarray(default_grid(controller) if grid is None else grid, float))
    sec = secondary_grid(dyn, controller) if secondary is None else dict(secondary)
    sec_points = [dict(zip(sec, v)) for v in itertools.product(*sec.values())] or [{}]

    def gains(g, extra):
        out = family(dyn, controller, g)
        out.update(_secondary(dyn, controller, extra))
        return out

    runs = [dict(scenario=s, controller=controller, gains=gains(g, x))
            for x in sec_points for s in scen for g in grid]
    out = iter(sweep(runs, executor=executor, max_workers=max_workers, model=model, progress=progress))
    name = main_gain(controller)
    gs = list(map(float, grid))
    table, candidates, fallback = [], [], []
    for j, x in enumerate(sec_points):
        ok, worst = {g: True for g in gs}, {g: 0.0 for g in gs}
        bounded = {g: True for g in gs}
        for s, moving in scen.items():
            hf_min = np.inf
            for g in gs:
                m = next(out)
                if "error" not in m:
                    hf_min = min(hf_min, _hf(m))
                stable, reason = _judge(m, hf_min)
                row = {"scenario": s, name: g, "gain": g, **x, "stable": stable, "reason": reason}
                if "error" not in m:
                    row.update(max_error_pct=_worst(m, moving), hf_error=_hf(m), saturation=m["u_saturation_frac"],
                               errors={c: m["max_error_pct"][c] for c in moving})
                    worst[g] = max(worst[g], row["max_error_pct"])
                    bounded[g] = bounded[g] and m["u_saturation_frac"] <= SATURATION
                else:
                    worst[g] = np.inf
                    bounded[g] = False
                ok[g] = ok[g] and stable
                table.append(row)
        for g in gs:
            if 2 * g <= gs[-1] * (1 + 1e-9) and all(ok[h] for h in gs if g <= h <= 2 * g * (1 + 1e-9)):
                candidates.append((worst[g], -g, j, g))
        fallback += [(worst[g], -g, j, g) for g in gs if bounded[g]]
        largest = max((g for g in gs if ok[g]), default=None)
        sec_points[j] = (x, largest)
    margin_ok = bool(candidates)
    pick = min(candidates) if candidates else (min(fallback) if fallback else None)
    if pick is not None:
        _, _, j, best = pick
        x, largest = sec_points[j]
    else:
        best, x, largest = None, {}, None
    return {
        "controller": controller, "model": model.name, "main_gain": name, "grid": gs, "secondary": sec,
        "table": table, "best": best, "best_secondary": x, "margin_ok": margin_ok,
        "best_gains": gains(best, x) if best is not None else None,
        "best_errors": {r["scenario"]: r.get("max_error_pct") for r in table
                        if r["gain"] == best and all(r.get(k) == v for k, v in x.items())},
        "largest_stable": largest,
    }


def tune_p(gains=None, scenarios=None, *, executor=None, max_workers=None, model=None,
           progress: bool = False) -> dict:
    """:func:`tune` for the baseline P controller (its rows also carry its main gain)."""
    from ..controllers import baseline
    return tune(baseline(), gains, model=model, scenarios=scenarios, executor=executor, max_workers=max_workers,
                progress=progress)


def margins(controllers=None, *, model=None, scenarios=None, executor=None, max_workers=None,
            progress: bool = False) -> dict:
    """Stability margin of each controller's main gain on each rig scenario (module doc), from the
    robot's gains. Returns {"model", "rows": [{controller, scenario, main_gain, gain, margin,
    limit_reason}]}; ``margin`` is the largest factor found stable (≥ MARGIN_MAX: ``margin_capped``)."""
    import hydrogen
    from ..controllers import CONTROLLERS
    from .sweep import check_workers, sweep

    model = _load(model)
    if executor is None:
        check_workers(max_workers)
    scen = list(scenarios) if scenarios else list(require_rig_scenarios(model, "margins"))
    dyn = hydrogen.build(model)
    cases = [(c, s) for c in (controllers or CONTROLLERS) for s in scen]
    base = {c: _base_gains(dyn, c, robot=True) for c, _ in cases}
    g0 = {c: float(np.mean(base[c][main_gain(c)])) for c, _ in cases}

    def run(factors):
        runs = [dict(scenario=s, controller=c, gains=family(dyn, c, g0[c] * f, base[c]))
                for (c, s), f in zip(cases, factors)]
        return sweep(runs, executor=executor, max_workers=max_workers, model=model, progress=progress)

    ref = run([1.0] * len(cases))
    hf_ref = [_hf(m) if "error" not in m else np.inf for m in ref]
    lo = [1.0 if _judge(m, h)[0] else 0.0 for m, h in zip(ref, hf_ref)]
    hi = [None] * len(cases)
    why = [None if lo[i] else _judge(ref[i], hf_ref[i])[1] for i in range(len(cases))]
    f = 2.0
    while f <= MARGIN_MAX:  # doubling until unstable
        todo = [i for i in range(len(cases)) if lo[i] and hi[i] is None]
        if not todo:
            break
        res = run([f if i in todo else 1.0 for i in range(len(cases))])
        for i in todo:
            stable, reason = _judge(res[i], hf_ref[i])
            if stable:
                lo[i] = f
            else:
                hi[i], why[i] = f, reason
        f *= 2
    for _ in range(MARGIN_STEPS):  # geometric bisection between the last stable and the first unstable
        todo = [i for i in range(len(cases)) if lo[i] and hi[i] is not None]
        if not todo:
            break
        mids = [np.sqrt(lo[i] * hi[i]) if i in todo else 1.0 for i in range(len(cases))]
        res = run(mids)
        for i in todo:
            stable, reason = _judge(res[i], hf_ref[i])
            if stable:
                lo[i] = mids[i]
            else:
                hi[i], why[i] = mids[i], reason
    rows = [{"controller": c, "scenario": s, "main_gain": main_gain(c), "gain": g0[c], "margin": float(lo[i]),
             "margin_capped": hi[i] is None and lo[i] > 0, "limit_reason": why[i] or ""}
            for i, (c, s) in enumerate(cases)]
    return {"model": model.name, "rows": rows}
