"""Counterparts of the paper's figures (Figs. 2, 3, 5-8) and its comparison table, from simulation results.

Every plotting function takes :class:`~hydrogen.simulation.simulator.SimulationResult`
objects and an output path, writes a PNG atomically (temporary file in the same
folder, then ``os.replace``) and closes its figure. Matplotlib runs on the
non-interactive Agg backend, selected here before pyplot is imported.
"""
from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .fileio import atomic_write  # noqa: E402
from .simulation.simulator import COORDS  # noqa: E402

__all__ = ["plot_tracking_errors", "plot_parameter_errors", "plot_experiment", "plot_step",
           "comparison_table", "make_all", "PAPER_MAX_ERROR_PCT"]

#: Units and scale (SI → plotted) per coordinate: mm for positions, mrad for angles.
_UNITS = {c: ("mm" if c in ("x", "y", "z") else "mrad") for c in COORDS}
_SCALE = 1e3
_LABELS = {"x": "x", "y": "y", "z": "z", "psi": r"\psi", "theta": r"\theta", "phi": r"\phi"}
_THETA_NAMES = (r"$M_p$", r"$I_x$", r"$I_y$", r"$I_z$")
_DPI = 110

#: Maximum tracking errors (% of the reference amplitude) reported in section VI of the paper:
#: scenario → (coordinate, nonlinear controller, P controller).
PAPER_MAX_ERROR_PCT = {
    "z-1hz": ("z", 4.0, 43.0),
    "z-2hz": ("z", 14.0, 69.0),
    "psi-1hz": ("psi", 4.0, 41.0),
}


def _coord_index(coord: str) -> int:
    if coord not in COORDS:
        raise KeyError(f"unknown coordinate '{coord}'; choose one of {', '.join(COORDS)}")
    return COORDS.index(coord)


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


def _max_pct(result, coord: str):
    """The run's max error for ``coord`` in % of the reference amplitude, or None if unknown."""
    metrics = result.metrics or (result.compute_metrics() if len(result.t) else {})
    val = metrics.get("max_error_pct", {}).get(coord)
    return None if val is None or not np.isfinite(val) else float(val)


def _fmt_pct(val) -> str:
    return "n/a" if val is None else f"{val:.1f}%"


def plot_tracking_errors(result, path, *, t_adapt=None) -> Path:
    """Tracking error per coordinate against time (counterpart of Fig. 2).

    Parameters
    ----------
    result : SimulationResult
        A run; uses ``t`` (s) and ``error`` = q − q_d (m, rad).
    path : str or Path
        Output PNG file.
    t_adapt : float, optional
        Time (s) at which parameter adaptation switches on; drawn as a vertical
        dashed line in every subplot. None (default) draws no line.

    Returns
    -------
    Path
        ``path``. Six stacked subplots: x, y, z errors in mm, ψ, θ, φ errors in mrad.
    """
    t, err = np.asarray(result.t, float), np.asarray(result.error, float)
    fig, axes = plt.subplots(6, 1, sharex=True, figsize=(7.0, 9.0))
    for i, (ax, c) in enumerate(zip(axes, COORDS)):
        ax.plot(t, _SCALE * err[:, i], lw=0.9, color="C0")
        ax.axhline(0.0, color="0.6", lw=0.5)
        if t_adapt is not None:
            ax.axvline(t_adapt, color="k", ls="--", lw=0.8,
                       label="adaptation on" if i == 0 else None)
        ax.set_ylabel(f"$e_{{{_LABELS[c]}}}$ ({_UNITS[c]})")
        ax.grid(True, alpha=0.3)
    if t_adapt is not None:
        axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(f"Tracking errors: {result.controller} on {result.scenario}")
    fig.tight_layout()
    return _save(fig, path)


def plot_parameter_errors(result, path) -> Path:
    """Parameter estimation errors against time, in % of the true values (counterpart of Fig. 3).

    Parameters
    ----------
    result : SimulationResult
        A run; uses ``t`` (s), ``theta_hat`` (n, 4) estimates of [M_p kg, I_x, I_y, I_z kg m²],
        ``theta_true`` (4,), ``gamma1_hat``, ``gamma2_hat`` (n, 6) per-leg estimates of
        γ1 = β (Pa) and γ2 = βc, and ``gamma_true`` (2,).
    path : str or Path
        Output PNG file.

    Returns
    -------
    Path
        ``path``. Top: 100 (θ̂ − θ)/θ (%) for the four rigid-body parameters.
        Bottom: 100 (mean over legs of γ̂_j / γ_j − 1) (%) for j = 1, 2.
    """
    t = np.asarray(result.t, float)
    th_hat, th = np.asarray(result.theta_hat, float), np.asarray(result.theta_true, float)
    g_true = np.asarray(result.gamma_true, float)
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7.0, 6.0))
    th_err = 100.0 * (th_hat - th) / th
    for j, name in enumerate(_THETA_NAMES):
        ax1.plot(t, th_err[:, j], lw=1.0, label=name)
    ax1.set_ylabel("rigid-body error (%)")
    ax1.legend(loc="upper right", fontsize=8, ncol=4)
    for j, (g_hat, name) in enumerate(((result.gamma1_hat, r"$\gamma_1$"), (result.gamma2_hat, r"$\gamma_2$"))):
        ratio = np.mean(np.asarray(g_hat, float) / g_true[j], axis=1)
        ax2.plot(t, 100.0 * (ratio - 1.0), lw=1.0, label=name + " (mean over legs)")
    ax2.set_ylabel("hydraulic error (%)")
    ax2.legend(loc="upper right", fontsize=8)
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.grid(True, alpha=0.3)
    ax1.set_title(f"Parameter estimation errors: {result.controller} on {result.scenario}")
    fig.tight_layout()
    return _save(fig, path)


def plot_experiment(nonlinear, p, coord, path, title=None) -> Path:
    """Sinusoidal tracking along one coordinate, nonlinear vs P controller (counterpart of Figs. 5-7).

    Parameters
    ----------
    nonlinear, p : SimulationResult
        Runs of the same scenario with the nonlinear (adaptive-robust) and the P controller.
    coord : str
        One of x, y, z, psi, theta, phi.
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
    i = _coord_index(coord)
    unit = _UNITS[coord]
    bias = float(np.mean(nonlinear.q_d[:, i])) if len(nonlinear.t) else 0.0
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7.0, 6.0))
    ax1.plot(nonlinear.t, _SCALE * (nonlinear.q_d[:, i] - bias), "k--", lw=1.0, label="reference")
    runs = ((nonlinear, "nonlinear", "C0"), (p, "P", "C3"))
    for res, name, color in runs:
        lab = f"{name} (max error {_fmt_pct(_max_pct(res, coord))})"
        ax1.plot(res.t, _SCALE * (res.q[:, i] - bias), color=color, lw=1.0, label=lab)
        ax2.plot(res.t, _SCALE * res.error[:, i], color=color, lw=1.0, label=lab)
    sym = _LABELS[coord]
    ax1.set_ylabel(f"${sym} - \\bar{{{sym}}}_d$ ({unit})")
    ax2.set_ylabel(f"$e_{{{sym}}}$ ({unit})")
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    ax1.set_title(title if title is not None else f"{nonlinear.scenario}: {coord} tracking")
    fig.tight_layout()
    return _save(fig, path)


def plot_step(nonlinear, p, path, title=None) -> Path:
    """Step response along z, nonlinear vs P controller (counterpart of Fig. 8).

    Parameters
    ----------
    nonlinear, p : SimulationResult
        Runs of the z-step scenario with the nonlinear and the P controller.
    path : str or Path
        Output PNG file.
    title : str, optional
        Figure title; defaults to "<scenario>: z step response".

    Returns
    -------
    Path
        ``path``. Reference and both z responses in mm, as offsets from the
        reference's initial value.
    """
    i = _coord_index("z")
    z0 = float(nonlinear.q_d[0, i]) if len(nonlinear.t) else 0.0
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    ax.plot(nonlinear.t, _SCALE * (nonlinear.q_d[:, i] - z0), "k--", lw=1.0, label="reference")
    ax.plot(nonlinear.t, _SCALE * (nonlinear.q[:, i] - z0), color="C0", lw=1.0, label="nonlinear")
    ax.plot(p.t, _SCALE * (p.q[:, i] - z0), color="C3", lw=1.0, label="P")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(r"$z - z_d(0)$ (mm)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title if title is not None else f"{nonlinear.scenario}: z step response")
    fig.tight_layout()
    return _save(fig, path)


def comparison_table(rows) -> str:
    """Markdown table comparing simulated and published maximum tracking errors.

    Parameters
    ----------
    rows : iterable of tuple
        (scenario label, coordinate, nonlinear max error %, P max error %,
        paper nonlinear %, paper P %). Percentages are of the reference
        amplitude; None (or NaN) is shown as "n/a".

    Returns
    -------
    str
        A Markdown table ending with a newline.
    """
    def cell(v):
        if v is None:
            return "n/a"
        try:
            v = float(v)
        except (TypeError, ValueError):
            return str(v)
        return "n/a" if not np.isfinite(v) else f"{v:.1f}"

    lines = ["| scenario | coordinate | nonlinear max error (%) | P max error (%) "
             "| paper nonlinear (%) | paper P (%) |",
             "|---|---|---:|---:|---:|---:|"]
    for label, coord, nl, pp, paper_nl, paper_p in rows:
        lines.append(f"| {label} | {coord} | {cell(nl)} | {cell(pp)} | {cell(paper_nl)} | {cell(paper_p)} |")
    return "\n".join(lines) + "\n"


def make_all(dyn, out_dir, quiet=True, *, durations=None, gains=None) -> dict:
    """Run the paper's scenarios and write every figure and the comparison table into ``out_dir``.

    Runs paper-sim with the adaptive-robust controller (Figs. 2, 3), and z-1hz,
    z-2hz, psi-1hz and z-step with both the adaptive-robust and the P
    controller (Figs. 5-8). A diverging run raises
    :class:`~hydrogen.errors.SimulationError` (its ``result`` holds the partial run).

    Parameters
    ----------
    dyn : Dynamics
        Compiled dynamics from :func:`hydrogen.build`.
    out_dir : str or Path
        Output folder (created if missing).
    quiet : bool
        If False, print one line per run.
    durations : dict, optional
        {scenario name: duration s} overriding the scenarios' durations (e.g. short runs in tests).
    gains : dict, optional
        {controller name: gains dict} passed to ``simulate(..., gains=...)``.

    Returns
    -------
    dict
        {"fig2", "fig3", "fig5", "fig6", "fig7", "fig8", "table"} → Path of the written file.
    """
    from .simulation.scenarios import scenario as named_scenario
    from .simulation.simulator import simulate

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    durations, gains = dict(durations or {}), dict(gains or {})
    from tqdm import tqdm

    # A bar on a terminal only (disable=None), never with quiet.
    bar = tqdm(total=9, desc="figures", unit="run", disable=True if quiet else None)

    def run(name, controller):
        bar.set_postfix_str(f"{name} {controller}")
        res = simulate(dyn, name, controller, gains=gains.get(controller), duration=durations.get(name))
        bar.update()
        return res

    paths = {}
    sim = run("paper-sim", "adaptive-robust")
    t_adapt = named_scenario("paper-sim", dyn.model).t_adapt
    paths["fig2"] = plot_tracking_errors(sim, out / "fig2_tracking_errors.png", t_adapt=t_adapt)
    paths["fig3"] = plot_parameter_errors(sim, out / "fig3_parameters.png")

    rows = []
    experiments = (("fig5", "z-1hz", "fig5_z_1hz.png", "Fig. 5: z, 1 Hz"),
                   ("fig6", "z-2hz", "fig6_z_2hz.png", "Fig. 6: z, 2 Hz"),
                   ("fig7", "psi-1hz", "fig7_psi_1hz.png", "Fig. 7: psi, 1 Hz"))
    for key, name, fname, label in experiments:
        coord, paper_nl, paper_p = PAPER_MAX_ERROR_PCT[name]
        nl, pp = run(name, "adaptive-robust"), run(name, "p")
        paths[key] = plot_experiment(nl, pp, coord, out / fname,
                                     title=f"{label} tracking, nonlinear vs P (simulation)")
        rows.append((label, coord, _max_pct(nl, coord), _max_pct(pp, coord), paper_nl, paper_p))

    nl, pp = run("z-step", "adaptive-robust"), run("z-step", "p")
    paths["fig8"] = plot_step(nl, pp, out / "fig8_z_step.png",
                              title="Fig. 8: z step response, nonlinear vs P (simulation)")

    table = ("Maximum tracking error in % of the reference amplitude, simulation vs paper (section VI).\n\n"
             + comparison_table(rows))
    paths["table"] = out / "table.md"
    atomic_write(paths["table"], table)
    bar.close()
    return paths
