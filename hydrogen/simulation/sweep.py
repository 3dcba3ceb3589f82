"""Many simulations through one call, spread over the cores (or any concurrent.futures.Executor)."""
from __future__ import annotations

import os
from concurrent.futures import Executor, ProcessPoolExecutor

__all__ = ["sweep"]

def _run_one(job):
    """Worker: build (once per process) and run one simulation; return its metrics or its error."""
    import hydrogen
    from ..errors import HydrogenError

    model, run = job
    run = dict(run)
    scenario = run.pop("scenario", "paper-sim")
    controller = run.pop("controller", "adaptive-robust")
    try:
        res = hydrogen.simulate(scenario, controller, model=model, **run)
    except HydrogenError as exc:
        out = {"error": str(exc).splitlines()[0][:500]}
        if getattr(exc, "result", None) is not None and len(exc.result.t):
            out["failed_at_s"] = float(exc.result.t[-1])
        return out
    m = dict(res.metrics)
    m["u_saturation_frac"] = float((abs(res.u) >= 0.999 * res.u_max).mean()) if res.u_max else 0.0
    return m


def sweep(runs, *, executor: Executor | None = None, max_workers: int | None = None, model=None,
          progress: bool = False) -> list:
    """Run each of ``runs`` (dicts of :func:`hydrogen.simulate` arguments: scenario, controller,
    gains, duration, scenario overrides) and return their metrics in order.

    A run that diverges gives ``{"error": message}`` instead of stopping the sweep.
    ``executor`` may be any :class:`concurrent.futures.Executor` (a Dask or Ray
    executor spreads the sweep past one machine); by default a local process pool
    with ``max_workers`` (default: the core count) processes.
    """
    import hydrogen
    # The Model itself goes to the workers (not its file name): in-memory edits are kept.
    model = model if isinstance(model, hydrogen.Model) else hydrogen.load_model(model)
    from tqdm import tqdm

    jobs = [(model, r) for r in runs]

    def collect(ex):
        return list(tqdm(ex.map(_run_one, jobs), total=len(jobs), desc="sweep", unit="run",
                         disable=None if progress else True))

    if executor is not None:
        return collect(executor)
    with ProcessPoolExecutor(max_workers=max_workers or os.cpu_count() or 1) as pool:
        return collect(pool)
