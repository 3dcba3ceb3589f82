"""The human summary of a run: tracking errors per coordinate in its own unit and in % of the
reference amplitude, and the estimates of the controllers that adapt.

Shared by ``hydrogen simulate`` and the exported C program (which prints the same figures), so the
two read alike. Lengths are shown in mm, angles in mrad (the model's coordinate units, SI m or rad,
times 1000).
"""
from __future__ import annotations

import numpy as np

from .controllers import ESTIMATE_BLOCKS  # the estimate blocks of a controller's state, defined there

__all__ = ["display_unit", "error_lines", "estimated_blocks", "estimate_lines", "excitation_lines", "saturation_lines", "SATURATION", "SATURATED_AT",
           "ESTIMATE_BLOCKS", "PCT_WIDTH", "POOR_EXCITATION"]

#: λmin/λmax of a run's normalised information matrix below which the summary says the run does not
#: excite the adapted parameters enough to identify them (a gradient law then moves the least-excited
#: direction at least 1e4 times slower than the best-excited one).
POOR_EXCITATION = 1.0e-4

#: Width of the "% of amplitude" column ("  12.34 %"; "-" right-aligned in the same width).
PCT_WIDTH = 9


def display_unit(si_unit: str) -> str:
    """The unit a coordinate's error is shown in: "mrad" for "rad", "mm" for "m" (scale 1000)."""
    return "mrad" if si_unit == "rad" else "mm"


def _pct(pct) -> str:
    return f"{'-':>{PCT_WIDTH}}" if pct is None else f"{pct:{PCT_WIDTH - 2}.2f} %"


def error_lines(coordinates, units, max_error, max_error_pct) -> list:
    """One aligned line per coordinate: name, max error in % of its reference amplitude ("-" when the
    reference does not move it), and the max absolute error in mm or mrad. ``max_error`` and
    ``max_error_pct`` map coordinate -> value (SI; % or None), as in ``SimulationResult.metrics``."""
    width = max([12] + [len(c) for c in coordinates])
    lines = []
    for i, c in enumerate(coordinates):
        unit = display_unit(units[i] if i < len(units) else "m")
        lines.append(f"  {c:>{width}}: {_pct(max_error_pct[c])}   {max_error[c] * 1e3:9.4f} {unit}")
    return lines


def seed_error_lines(coordinates, units, metrics) -> list:
    """Like :func:`error_lines` for runs over seeds (``metrics``: their
    :func:`~hydrogen.simulation.seeds.summarize`): the median max error in % and its range [min - max]
    over the seeds, then the median absolute max error in mm or mrad."""
    width = max([12] + [len(c) for c in coordinates])
    med, lo, hi = (metrics[k]["max_error_pct"] for k in ("median", "min", "max"))
    abs_med = metrics["median"]["max_error"]
    lines = []
    for i, c in enumerate(coordinates):
        unit = display_unit(units[i] if i < len(units) else "m")
        spread = f"  [{lo[c]:.2f} - {hi[c]:.2f} %]" if med[c] is not None else " " * 19
        lines.append(f"  {c:>{width}}: {_pct(med[c])}{spread:>19}   {abs_med[c] * 1e3:9.4f} {unit}")
    return lines


#: A valve counts as saturated in a period when its command |u| is at least this fraction of u_max
#: (the controllers clip it at u_max; the margin takes rounding).
SATURATED_AT = 0.999
#: Fraction of a run's periods a valve may spend saturated: above it the summary says so, per
#: actuator, with what to change, and the documented gain search refuses the point
#: (:mod:`hydrogen.simulation.tuning`).
SATURATION = 0.01


def saturation_lines(res) -> list:
    """One line per actuator whose valve was saturated (|u| at u_max) in more than
    :data:`SATURATION` of the run's periods
    (``metrics["u_saturation_frac_by_actuator"]``), with what to change: the controller's gains that
    drive the valve (its spec's ``command_gains``), the reference, or the valve. None: no line."""
    from .controllers import CONTROLLERS, spec

    by = (res.metrics or {}).get("u_saturation_frac_by_actuator") or {}
    gains = ", ".join(spec(res.controller).command_gains) if res.controller in CONTROLLERS else "the gains"
    return [f"valve of {name} saturated {100 * frac:.1f} % of the time (|u| at u_max = {res.u_max * 1e3:g} mm, "
            f"more than {100 * SATURATION:g} %): lower the gains ({gains}), slow the reference, or raise u_max / "
            "a larger valve"
            for name, frac in by.items() if frac > SATURATION]


def estimated_blocks(ctrl) -> tuple:
    """The estimate blocks (of :data:`ESTIMATE_BLOCKS`) that controller ``ctrl`` declares in its state:
    empty for the controllers that adapt nothing (they estimate nothing to report)."""
    slices = getattr(ctrl, "slices", None) or {}
    return tuple(b for b in ESTIMATE_BLOCKS if b in slices)


def estimate_lines(res) -> list:
    """The final estimates of a run, for the blocks its controller declares (none: no line)."""
    m = res.metrics
    blocks = res.estimated
    lines = []
    if "theta_hat" in blocks:
        lines.append("theta_hat final: " + ", ".join(
            f"{n} {v:.4g} ({e:+.1f} %)" if e is not None else f"{n} {v:.4g} (true 0: error {a:+.3g})"
            for n, v, e, a in zip(res.theta_names, m["theta_hat_final"], m["theta_error_pct_final"],
                                  m["theta_error_final"])))
    if "gamma1_hat" in blocks or "gamma2_hat" in blocks:
        err = [100 * np.mean(np.asarray(h) / np.asarray(t) - 1) for h, t in zip(m["gamma_hat_final"], m["gamma_true"])]
        parts = [f"beta {err[0]:+.1f} %" if "gamma1_hat" in blocks else None,
                 f"beta*c {err[1]:+.1f} %" if "gamma2_hat" in blocks else None]
        lines.append("gamma_hat final (mean error over cylinders): " + ", ".join(p for p in parts if p))
    return lines




def _unmoved(start, end, true, names):
    """(names with their errors, whether any drifted away) for the estimates that closed less than
    half of their starting error (of at least 1 %)."""
    out, away = [], False
    for n, a, b, t in zip(names, np.ravel(start), np.ravel(end), np.ravel(true)):
        e0, e1 = abs(a - t), abs(b - t)
        if t != 0 and e0 > 0.01 * abs(t) and e1 > 0.5 * e0:
            out.append(f"{n} {100 * (a - t) / t:+.1f} % -> {100 * (b - t) / t:+.1f} %")
            away = away or e1 > e0
    return out, away


_DRIFT = ("some moved away from the true values: the run's noise, delay and valve lag drive the gradient law "
          "(a projection bound then holds them); lower the rate, or use the composite law")


def excitation_lines(res) -> list:
    """Notes for a run whose estimates did not converge: which (error at the start and at the end),
    how well the run excites them (``metrics["excitation"]``, λmin/λmax of the normalised information
    matrix) and what to do. Empty when every estimate closed at least half of its starting error."""
    ex = res.metrics.get("excitation") or {}
    lines = []
    if "theta_hat" in res.estimated and len(res.theta_hat):
        bad, away = _unmoved(res.theta_hat[0], res.theta_hat[-1], res.theta_true, res.theta_names)
        if bad:
            measured = ex.get("theta", np.nan)  # none: fewer than 3 samples
            why = ("the run is too short to tell how well it excites theta (no information matrix): run longer"
                   if not np.isfinite(measured) else
                   f"the run barely excites theta (lambda_min/lambda_max {ex['theta']:.2g} < {POOR_EXCITATION:g}; "
                   f"least excited: {', '.join(ex.get('theta_least_excited') or {})}): use a reference that moves "
                   "every coordinate at several frequencies, or a longer run"
                   if measured < POOR_EXCITATION else _DRIFT + " (rate_ls_theta)" if away else
                   f"the run excites theta (lambda_min/lambda_max {measured:.2g}), so the "
                   "adaptation is slow: raise rate_theta by octaves, or use the composite law (rate_ls_theta)")
            lines.append(f"note: theta estimates did not converge ({'; '.join(bad[:4])}"
                         f"{'; ...' if len(bad) > 4 else ''}): {why}")
    names = ex.get("gamma_cylinders") or [str(i) for i in range(np.shape(res.gamma_true)[1])]
    for row, block, label in ((0, "gamma1_hat", "beta"), (1, "gamma2_hat", "beta c")):
        hat = getattr(res, block, None)
        if block not in res.estimated or hat is None or not len(hat):
            continue
        bad, away = _unmoved(hat[0], hat[-1], res.gamma_true[row], [f"{label} {c}" for c in names])
        if bad:
            why = _DRIFT + " (rate_ls_gamma)" if away else (
                f"raise rate_gamma{row + 1} by octaves or use the composite law (rate_ls_gamma); the valve must "
                "open both ways while the cylinder moves")
            lines.append(f"note: {label} estimates did not converge ({'; '.join(bad[:3])}"
                         f"{'; ...' if len(bad) > 3 else ''}): {why}")
    return lines
