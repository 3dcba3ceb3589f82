"""The human summary of a run: tracking errors per coordinate in its own unit and in % of the
reference amplitude, and the estimates of the controllers that adapt.

Shared by ``hydrogen simulate`` and the exported C program (which prints the same figures), so the
two read alike. Lengths are shown in mm, angles in mrad (the model's coordinate units, SI m or rad,
times 1000).
"""
from __future__ import annotations

import numpy as np

__all__ = ["display_unit", "error_lines", "estimated_blocks", "estimate_lines", "ESTIMATE_BLOCKS", "PCT_WIDTH"]

#: The controller-state blocks that hold parameter estimates, in the order they are reported.
ESTIMATE_BLOCKS = ("theta_hat", "gamma1_hat", "gamma2_hat")
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
            f"{n} {v:.4g} ({e:+.1f} %)" for n, v, e in
            zip(res.theta_names, m["theta_hat_final"], m["theta_error_pct_final"])))
    if "gamma1_hat" in blocks or "gamma2_hat" in blocks:
        err = [100 * np.mean(np.asarray(h) / np.asarray(t) - 1) for h, t in zip(m["gamma_hat_final"], m["gamma_true"])]
        parts = [f"beta {err[0]:+.1f} %" if "gamma1_hat" in blocks else None,
                 f"beta*c {err[1]:+.1f} %" if "gamma2_hat" in blocks else None]
        lines.append("gamma_hat final (mean error over cylinders): " + ", ".join(p for p in parts if p))
    return lines
