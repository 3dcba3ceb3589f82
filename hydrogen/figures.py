"""Counterparts of the paper's figures (Figs. 2, 3, 5-8) and its comparison table, for any model.

Every plotting function takes :class:`~hydrogen.simulation.simulator.SimulationResult`
objects (or, for the rig's runs over noise seeds, :class:`~hydrogen.simulation.seeds.SeedResults`:
the median run is drawn, with the min-max band of the seeds around it) and an output path,
writes a PNG atomically (temporary file in the same folder, then ``os.replace``) and closes its figure. Matplotlib runs on the
non-interactive Agg backend, selected here before pyplot is imported.
"""
from __future__ import annotations

import io
from pathlib import Path

from .outputs import require_matplotlib

matplotlib = require_matplotlib("figures")

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .estimators import selected  # noqa: E402 - a scenario with an estimator is a rig run
from .fileio import atomic_write  # noqa: E402

__all__ = ["plot_tracking_errors", "plot_parameter_errors", "plot_experiment", "plot_step",
           "comparison_table", "make_all"]

_SCALE = 1e3  # SI → mm or mrad
_GREEK = {"psi": r"\psi", "theta": r"\theta", "phi": r"\phi"}
_DPI = 110


def _unit(result, i) -> str:
    units = result.units or ()
    return "mrad" if i < len(units) and units[i] == "rad" else "mm"


def _label(coord: str) -> str:
    return _GREEK.get(coord, r"\mathrm{" + coord.replace("_", r"\_") + "}")


def _coord_index(result, coord: str) -> int:
    if coord not in result.coordinates:
        raise KeyError(f"unknown coordinate '{coord}'; choose one of {', '.join(result.coordinates)}")
    return result.coordinates.index(coord)


def _save(fig, path) -> Path:
    """Render ``fig`` into ``path`` atomically, in the format its extension names (PNG without one), and
    close it; returns the path. An extension matplotlib cannot write raises OutputPathError."""
    path = Path(path)
    try:
        fmt = path.suffix[1:].lower() or "png"
        if fmt not in fig.canvas.get_supported_filetypes():
            from .outputs import check_plot_path
            check_plot_path(path)  # raises, naming the formats there are
        buf = io.BytesIO()
        fig.savefig(buf, format=fmt, dpi=_DPI)
        atomic_write(path, buf.getvalue())
    finally:
        plt.close(fig)
    return path


def _seeded(result) -> bool:
    """Whether ``result`` holds runs over seeds (a SeedResults) rather than one run."""
    from .simulation.seeds import SeedResults
    return isinstance(result, SeedResults)


def _run(result):
    """The run to draw: ``result`` itself, or the median run of runs over seeds; anything else (a
    scenario's name where the run belongs) is a ScenarioError naming what was given."""
    run = result.median_run if _seeded(result) else result
    if not all(hasattr(run, k) for k in ("t", "error", "coordinates")):
        from .errors import ScenarioError
        raise ScenarioError(f"a figure draws a run (hydrogen.simulate's result), got {type(result).__name__} "
                            f"{result!r}"[:300])
    return run


def _max_pct(result, coord: str):
    """The run's max error for ``coord`` in % of the reference amplitude, or None if unknown; for runs
    over seeds, (median, min, max) over the seeds."""
    if _seeded(result):
        m = result.metrics
        stats = tuple((m.get(k) or {}).get("max_error_pct", {}).get(coord) for k in ("median", "min", "max"))
        return None if any(v is None or not np.isfinite(v) for v in stats) else tuple(map(float, stats))
    metrics = result.metrics or (result.compute_metrics() if len(result.t) else {})
    val = metrics.get("max_error_pct", {}).get(coord)
    return None if val is None or not np.isfinite(val) else float(val)


def _fmt_pct(val) -> str:
    if isinstance(val, tuple):
        return f"median {val[0]:.1f}%, range {val[1]:.1f}-{val[2]:.1f}%"
    return "n/a" if val is None else f"{val:.1f}%"


def _band(ax, result, i, signal="error", offset=0.0, color="C0", name=""):
    """Shade the min-max envelope over the seeds of column ``i`` of ``signal`` (runs over seeds only)."""
    if not _seeded(result) or len(result.completed) < 2:
        return
    t, lo, hi = result.band(signal)
    ax.fill_between(t, _SCALE * (lo[:, i] - offset), _SCALE * (hi[:, i] - offset), color=color, alpha=0.25, lw=0,
                    label=f"{name + ': ' if name else ''}range of {len(result.completed)} seeds, median run drawn")


def _seed_note(result) -> str:
    if not _seeded(result):
        return ""
    return f", median of {len(result.completed)} seeds (seed {result.metrics['median_seed']})"


def plot_tracking_errors(result, path, *, t_adapt=None) -> Path:
    """Tracking error per coordinate against time (counterpart of Fig. 2).

    Parameters
    ----------
    result : SimulationResult or SeedResults
        A run; uses ``t`` (s) and ``error`` = q − q_d (m, rad). Runs over seeds: the median run, and
        the min-max band of the seeds shaded.
    path : str or Path
        Output PNG file.
    t_adapt : float, optional
        Time (s) at which parameter adaptation switches on; drawn as a vertical
        dashed line in every subplot. None (default) draws no line.

    Returns
    -------
    Path
        ``path``. One stacked subplot per coordinate: lengths in mm, angles in mrad.
    """
    seeds, result = result, _run(result)
    t, err = np.asarray(result.t, float), np.asarray(result.error, float)
    n = err.shape[1]
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(7.0, 1.5 * n + 1.0), squeeze=False)
    axes = axes[:, 0]
    for i, (ax, c) in enumerate(zip(axes, result.coordinates)):
        _band(ax, seeds, i)
        ax.plot(t, _SCALE * err[:, i], lw=0.9, color="C0")
        ax.axhline(0.0, color="0.6", lw=0.5)
        if t_adapt is not None:
            ax.axvline(t_adapt, color="k", ls="--", lw=0.8,
                       label="adaptation on" if i == 0 else None)
        ax.set_ylabel(f"$e_{{{_label(c)}}}$ ({_unit(result, i)})")
        ax.grid(True, alpha=0.3)
    if t_adapt is not None or _seeded(seeds):
        axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(f"Tracking errors: {result.controller} on {result.scenario_name}{_seed_note(seeds)}")
    fig.tight_layout()
    return _save(fig, path)


def plot_parameter_errors(result, path) -> Path:
    """Parameter estimation errors against time, in % of the true values (counterpart of Fig. 3).

    Parameters
    ----------
    result : SimulationResult
        A run; uses ``t`` (s), ``theta_hat`` (k, p) estimates of the adapted parameters
        (``theta_names``), ``theta_true`` (p,), ``gamma1_hat``, ``gamma2_hat`` (k, m) per-cylinder
        estimates of γ1 = β (Pa) and γ2 = βc, and ``gamma_true`` (2, m).
    path : str or Path
        Output PNG file.

    Returns
    -------
    Path
        ``path``. Top: 100 (θ̂ − θ)/|θ| (%) for each rigid-body parameter.
        Bottom: 100 (mean over cylinders of γ̂_j / γ_j − 1) (%) for j = 1, 2.
    """
    t = np.asarray(result.t, float)
    th_hat, th = np.asarray(result.theta_hat, float), np.asarray(result.theta_true, float)
    g_true = np.asarray(result.gamma_true, float)
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7.0, 6.0))
    th_err = 100.0 * (th_hat - th) / np.abs(th)
    names = result.theta_names or tuple(f"theta{j}" for j in range(th.size))
    for j, name in enumerate(names):
        ax1.plot(t, th_err[:, j], lw=1.0, label=name)
    ax1.set_ylabel("rigid-body error (%)")
    ax1.legend(loc="upper right", fontsize=7, ncol=min(4, len(names)))
    g_true = g_true.reshape(2, -1)
    for j, (g_hat, name) in enumerate(((result.gamma1_hat, r"$\gamma_1$"), (result.gamma2_hat, r"$\gamma_2$"))):
        ratio = np.mean(np.asarray(g_hat, float) / g_true[j], axis=1)
        ax2.plot(t, 100.0 * (ratio - 1.0), lw=1.0, label=name + " (mean over cylinders)")
    ax2.set_ylabel("hydraulic error (%)")
    ax2.legend(loc="upper right", fontsize=8)
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.grid(True, alpha=0.3)
    ax1.set_title(f"Parameter estimation errors: {result.controller} on {result.scenario_name}")
    fig.tight_layout()
    return _save(fig, path)


def plot_experiment(nonlinear, p, coord, path, title=None) -> Path:
    """Sinusoidal tracking along one coordinate, nonlinear vs P controller (counterpart of Figs. 5-7).

    Parameters
    ----------
    nonlinear, p : SimulationResult or SeedResults
        Runs of the same scenario with the nonlinear controller (the legend names it) and the P controller;
        runs over seeds are drawn as their median run, the bottom panel shading the min-max band of
        the error over the seeds, the legend giving the median max error and its range.
    coord : str
        A coordinate name of the model.
    path : str or Path
        Output PNG file.
    title : str, optional
        Figure title; defaults to "<scenario>: <coord> tracking".

    Returns
    -------
    Path
        ``path``. Top: reference and both responses as offsets from the mean of the
        nonlinear run's reference (the bias is not shown), mm or mrad. Bottom: both
        tracking errors (mm or mrad). Legends give each run's max error in % of the
        reference amplitude (``metrics["max_error_pct"][coord]``).
    """
    given = ((nonlinear, f"nonlinear ({_run(nonlinear).controller})", "C0"), (p, "P", "C3"))
    nonlinear = _run(nonlinear)
    i = _coord_index(nonlinear, coord)
    unit = _unit(nonlinear, i)
    bias = float(np.mean(nonlinear.q_d[:, i])) if len(nonlinear.t) else 0.0
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7.0, 6.0))
    ax1.plot(nonlinear.t, _SCALE * (nonlinear.q_d[:, i] - bias), "k--", lw=1.0, label="reference")
    for runs, name, color in given:
        res = _run(runs)
        lab = f"{name} (max error {_fmt_pct(_max_pct(runs, coord))})"
        ax1.plot(res.t, _SCALE * (res.q[:, i] - bias), color=color, lw=1.0, label=lab)
        _band(ax2, runs, i, color=color, name=name)
        ax2.plot(res.t, _SCALE * res.error[:, i], color=color, lw=1.0, label=lab)
    sym = _label(coord)
    ax1.set_ylabel(f"${sym} - \\bar{{{sym}}}_d$ ({unit})")
    ax2.set_ylabel(f"$e_{{{sym}}}$ ({unit})")
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    ax1.set_title(title if title is not None else f"{nonlinear.scenario_name}: {coord} tracking")
    fig.tight_layout()
    return _save(fig, path)


def plot_step(nonlinear, p, path, title=None, coord=None) -> Path:
    """Step response along one coordinate, nonlinear vs P controller (counterpart of Fig. 8).

    Parameters
    ----------
    nonlinear, p : SimulationResult or SeedResults
        Runs of a step scenario with the nonlinear and the P controller (runs over seeds: the median
        run, with the min-max band of the response over the seeds shaded).
    path : str or Path
        Output PNG file.
    title : str, optional
        Figure title; defaults to "<scenario>: <coordinate> step response".
    coord : str, optional
        The stepped coordinate (default: the one whose reference moves most).

    Returns
    -------
    Path
        ``path``. Reference and both responses (mm or mrad), as offsets from the
        reference's initial value.
    """
    nl_runs, p_runs = nonlinear, p
    nonlinear, p = _run(nonlinear), _run(p)
    if coord is None:
        coord = nonlinear.coordinates[int(np.argmax(np.ptp(nonlinear.q_d, axis=0)))]
    i = _coord_index(nonlinear, coord)
    unit, sym = _unit(nonlinear, i), _label(coord)
    z0 = float(nonlinear.q_d[0, i]) if len(nonlinear.t) else 0.0
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    ax.plot(nonlinear.t, _SCALE * (nonlinear.q_d[:, i] - z0), "k--", lw=1.0, label="reference")

    def label(res, name):
        m = step_metrics(res, i)
        return (f"{name}: 90 % at {m['rise_s']:.2f} s, overshoot {m['overshoot_pct']:.0f} %" if m["rise_s"] is not None
                else f"{name}: never reaches 90 %")
    _band(ax, nl_runs, i, "q", z0, "C0", "nonlinear")
    ax.plot(nonlinear.t, _SCALE * (nonlinear.q[:, i] - z0), color="C0", lw=1.0,
            label=label(nonlinear, f"nonlinear ({nonlinear.controller})"))
    _band(ax, p_runs, i, "q", z0, "C3", "P")
    ax.plot(p.t, _SCALE * (p.q[:, i] - z0), color="C3", lw=1.0, label=label(p, p.controller))
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"${sym} - {sym}_d(0)$ ({unit})")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title if title is not None else f"{nonlinear.scenario_name}: {coord} step response")
    fig.tight_layout()
    return _save(fig, path)


def step_metrics(res, i: int) -> dict:
    """Rise time and overshoot of coordinate ``i``'s response to the step of ``res``'s reference (the
    largest jump of q_d): "rise_s", s from the step to the first sample at 90 % of its height (None if
    never), and "overshoot_pct", the largest excursion past the height after the step, % of the height
    (0 if none)."""
    qd, q, t = res.q_d[:, i], res.q[:, i], res.t
    k = int(np.argmax(np.abs(np.diff(qd)))) + 1 if len(qd) > 1 else 0
    height, start = float(qd[k] - qd[k - 1]) if k else 0.0, float(qd[k - 1]) if k else 0.0
    if height == 0.0:
        return {"rise_s": None, "overshoot_pct": 0.0}
    progress = (q[k:] - start) / height
    reached = np.nonzero(progress >= 0.9)[0]
    return {"rise_s": float(t[k + reached[0]] - t[k]) if reached.size else None,
            "overshoot_pct": float(max(progress.max() - 1.0, 0.0) * 100)}


def comparison_table(rows) -> str:
    """Markdown table comparing simulated and published maximum tracking errors.

    Parameters
    ----------
    rows : iterable of tuple
        (scenario label, coordinate, nonlinear max error %, P max error %,
        paper nonlinear %, paper P %[, backstepping max error %]). Percentages are of the reference
        amplitude; None (or NaN) is shown as "n/a"; a (median, min, max) tuple (runs over noise
        seeds) as "median (min-max)". The last column (backstepping with the true
        parameters: the nonlinear design without estimation) appears when a row has it.

    Returns
    -------
    str
        A Markdown table ending with a newline.
    """
    def cell(v):
        if v is None:
            return "n/a"
        if isinstance(v, (tuple, list)):
            return f"{cell(v[0])} ({cell(v[1])}-{cell(v[2])})" if len(v) == 3 else "n/a"
        try:
            v = float(v)
        except (TypeError, ValueError):
            return str(v)
        return "n/a" if not np.isfinite(v) else f"{v:.1f}"

    rows = [tuple(r) for r in rows]
    extra = any(len(r) > 6 for r in rows)
    paper = any(v is not None for r in rows for v in r[4:6])  # the paper's columns only where it has numbers
    lines = ["| scenario | coordinate | nonlinear max error (%) | P max error (%) |"
             + (" paper nonlinear (%) | paper P (%) |" if paper else "")
             + (" backstepping, true parameters (%) |" if extra else ""),
             "|---|---|---:|---:|" + ("---:|---:|" if paper else "") + ("---:|" if extra else "")]
    for r in rows:
        label, coord, nl, pp, paper_nl, paper_p = r[:6]
        line = f"| {label} | {coord} | {cell(nl)} | {cell(pp)} |" + (
            f" {cell(paper_nl)} | {cell(paper_p)} |" if paper else "")
        if extra:
            line += f" {cell(r[6] if len(r) > 6 else None)} |"
        lines.append(line)
    return "\n".join(lines) + "\n"


def make_all(dyn, out_dir, quiet=True, *, durations=None, gains=None, nonlinear=None, seeds=None,
             max_workers=None) -> dict:
    """Run the model's scenarios and write every figure and the comparison table into ``out_dir``.

    Driven by the description's scenarios: each scenario without the rig (the paper's section V
    simulation, an arm's arm-sim) gives the tracking-error and parameter figures (Figs. 2, 3) with
    the ``nonlinear`` controller; each rig scenario runs ``nonlinear`` and the P controller and gives
    a tracking figure per moving coordinate (Figs. 5-7) or, for a step, a step response (Fig. 8),
    and a table row per moving coordinate (with the paper's figures where the description gives
    them, and backstepping with the true parameters for reference). A rig scenario is run over
    ``seeds`` noise seeds (its result is a distribution: the adaptive loops are chaotic there): the
    figures show the median run and the min-max band of the seeds, the table the median and the
    range. A diverging run (on any seed) raises :class:`~hydrogen.errors.SimulationError`.

    Parameters
    ----------
    dyn : Dynamics
        Compiled dynamics from :func:`hydrogen.build`.
    out_dir : str or Path
        Output folder (created if missing).
    quiet : bool
        If False, show a progress bar on a terminal.
    durations : dict, optional
        {scenario name: duration s} overriding the scenarios' durations (e.g. short runs in tests).
    gains : dict, optional
        {controller name: gains dict} passed to ``simulate(..., gains=...)``.
    nonlinear : str, optional
        The controller of the figures' and the table's "nonlinear" runs; default the model's
        ``[figures] nonlinear`` (adaptive-robust unless the description says otherwise). The table's
        caption names it.
    seeds : int or list, optional
        Noise seeds of the rig scenarios (a count N: 0..N-1, or a list; default
        :data:`~hydrogen.simulation.seeds.DEFAULT_SEEDS`), run in a pool of ``max_workers`` processes.

    Returns
    -------
    dict
        {"<scenario>[_<coordinate>]" or "<scenario>_parameters" or "table" or "results"} → Path of the
        written file; ``results`` is the Markdown page of the table and figures
        (:func:`hydrogen.pages.write_results_page`).
    """
    from .errors import ScenarioError
    from .simulation.scenarios import scenario as named_scenario, scenario_names
    from .simulation.simulator import simulate

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    durations, gains = dict(durations or {}), dict(gains or {})
    from tqdm import tqdm

    model = dyn.model
    nonlinear = model.figures_nonlinear if nonlinear is None else nonlinear
    from .controllers import baseline, spec
    base = baseline()
    listed = model.controllers  # the controllers generated for this robot
    known = [c for c in listed if spec(c).knows_true_parameters]  # the reference column
    compared = [c for c in listed if spec(c).compared and c != nonlinear] or [base]  # "P": the better
    if nonlinear not in listed or nonlinear == base:
        raise ScenarioError(f"{model.source}: the figures' nonlinear controller must be one of "
                            f"{', '.join(c for c in listed if c != base)}, got {nonlinear!r}")
    if base not in listed:
        raise ScenarioError(model.not_listed(base) + " (the figures compare with it)")
    scenarios = [named_scenario(nm, model) for nm in scenario_names(model)]
    total = sum(1 if sc.friction[0] == 0 and selected(sc) is None and not sc.reference.STEP_RESPONSE
                else (2 if sc.reference.STEP_RESPONSE else 2 + len(compared)) for sc in scenarios)
    # A bar on a terminal only (disable=None), never with quiet.
    bar = tqdm(total=total, desc="figures", unit="run", disable=True if quiet else None)

    from .errors import SimulationError
    from .simulation.seeds import DEFAULT_SEEDS, seed_list
    from .simulation.sweep import check_workers

    seeds = seed_list(DEFAULT_SEEDS if seeds is None else seeds)
    check_workers(max_workers)

    def run(name, controller, over_seeds=False):
        bar.set_postfix_str(f"{name} {controller}")
        kw = dict(gains=gains.get(controller), duration=durations.get(name))
        if over_seeds:
            res = simulate(dyn, name, controller, seeds=seeds, max_workers=max_workers, **kw)
            if res.failures:
                raise SimulationError(f"scenario '{name}' with '{controller}': "
                                      + "; ".join(f"seed {s}: {e}" for s, e in res.failures.items())[:1000])
        else:
            res = simulate(dyn, name, controller, **kw)
        bar.update()
        return res

    paths, rows, chosen = {}, [], []
    # the steps last: their P is the one the tracking scenarios found better (the figures compare alike)
    for sc in sorted(scenarios, key=lambda sc: sc.reference.STEP_RESPONSE):
        rig = selected(sc) is not None or sc.friction[0] > 0 or sc.noise_l > 0
        if not rig and not sc.reference.STEP_RESPONSE:
            sim = run(sc.name, nonlinear)
            paths[sc.name] = plot_tracking_errors(sim, out / f"{sc.name}_errors.png", t_adapt=sc.t_adapt)
            paths[f"{sc.name}_parameters"] = plot_parameter_errors(sim, out / f"{sc.name}_parameters.png")
            continue
        nl = run(sc.name, nonlinear, True)
        moving = [c for c, a in zip(model.coordinate_names, sc.reference.amplitude()) if a > 0]
        # the better fixed-gain P on this scenario: the smallest worst median error over the moving axes;
        # on a step, the one the tracking scenarios chose most often (the baseline if none ran)
        step_p = max(compared, key=chosen.count) if chosen else base
        candidates = {c: run(sc.name, c, True) for c in ([step_p] if sc.reference.STEP_RESPONSE else compared)}
        p_name = min(candidates, key=lambda c: max((_max_pct(candidates[c], k) or (np.inf,))[0] for k in moving))
        pp = candidates[p_name]
        if not sc.reference.STEP_RESPONSE:
            chosen.append(p_name)
        if sc.reference.STEP_RESPONSE:
            paths[sc.name] = plot_step(nl, pp, out / f"{sc.name}.png", coord=moving[0],
                                       title=f"{sc.label}: step response, nonlinear vs P (simulation)")
            continue
        bs = (run(sc.name, known[0], True) if nonlinear != known[0] else nl) if known else None
        for coord in moving:
            key = sc.name if len(moving) == 1 else f"{sc.name}_{coord}"
            paths[key] = plot_experiment(nl, pp, coord, out / f"{key}.png",
                                         title=f"{sc.label}: {coord} tracking, nonlinear vs P (simulation)")
            paper = sc.paper.get(coord, (None, None))
            rows.append((f"{sc.label} (P: {p_name})" if len(compared) > 1 else sc.label, coord, _max_pct(nl, coord),
                         _max_pct(pp, coord), paper[0], paper[1], _max_pct(bs, coord) if bs is not None else None))

    versus = (" vs paper (section VI) where it reports one" if any(v is not None for r in rows for v in r[4:6])
              else " (the paper reports no numbers for this robot)")
    table = (f"Maximum tracking error in % of the reference amplitude, model {model.name}: simulation{versus}. "
             f"\"nonlinear\" is the {nonlinear} controller; \"P\" the better of {', '.join(compared)} on each "
             f"scenario (named with it). Each simulated cell is the median (min-max) over "
             f"{len(seeds)} sensor-noise seeds: on the rig the result is a distribution.\n\n"
             + comparison_table(rows))
    paths["table"] = out / "table.md"
    atomic_write(paths["table"], table)
    bar.close()
    from .pages import write_results_page  # the results page, from the table and figures just written
    paths["results"] = write_results_page(model, out)
    return paths
