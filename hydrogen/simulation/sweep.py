"""Many simulations through one call, spread over the cores (or any concurrent.futures.Executor)."""
from __future__ import annotations

from concurrent.futures import Executor

# the pool's limits and chunks keep their public path here; the workers are the simulator's
from .pool import CHUNKS_PER_WORKER, MAX_CHUNK, MAX_WORKERS_PER_CORE, check_workers, chunks, run_sweep  # noqa: F401
from .simulator import _estimator_designs, _run_chunk, _run_one  # noqa: F401

__all__ = ["sweep", "check_workers", "MAX_WORKERS_PER_CORE"]


def sweep(runs, *, executor: Executor | None = None, max_workers: int | None = None, model=None,
          progress: bool = False, seeds=None, results: bool = False, numbers: str | None = None) -> list:
    """Run each of ``runs`` (dicts of :func:`hydrogen.simulate` arguments: scenario, controller,
    gains, duration, scenario overrides) and return their metrics in order.

    ``seeds`` (a count N: seeds 0..N-1, or a list; :mod:`hydrogen.simulation.seeds`): each entry runs
    once per noise seed (its scenario field ``seed``; an entry may then not set ``seed``), every run
    in the one pool, and gives :func:`~hydrogen.simulation.seeds.summarize` of its runs in its place
    (per-seed metrics, median/min/max per coordinate, the median seed; ``"error"`` only when every
    seed failed). ``results``: give each run's SimulationResult (its ``metrics`` with
    ``u_saturation_frac``) instead of its metrics (not with ``seeds``); a failed run still gives
    ``{"error": message}``. ``numbers``: how the workers build the model (:func:`hydrogen.build`'s
    ``numbers``; None: its default).

    A run that fails (it diverges, or its entry is not valid: not a dict, an unknown key, a bad
    value) gives ``{"error": message}`` in its place and the others still run. Only a malformed
    call raises (``runs`` not a list of entries, a bad ``executor``, ``max_workers`` or ``model``), and so
    do worker processes that cannot be started or die (:class:`~hydrogen.errors.WorkerError`: their
    runs would otherwise look like failed simulations); the pool is then shut down, never left hanging.
    ``executor`` may be any :class:`concurrent.futures.Executor` (a Dask or Ray
    executor spreads the sweep past one machine); by default a local process pool
    with ``max_workers`` (default: the core count) processes.

    Each task of the executor is a chunk of consecutive runs (:func:`chunks`); in it the runs that
    differ only in gains and seed share one :class:`~hydrogen.simulation.simulator.Batch` (the scenario
    resolved and checked once, a controller per gain set), and the parent solves each scenario's
    estimator design (the Kalman gain) once for all the workers. Every run's metrics are those of the run alone, to the bit.
    The compiled loop releases the GIL, so a ``ThreadPoolExecutor`` runs the chunks side by side in
    this process, with no worker start-up.
    """
    return run_sweep(runs, _run_chunk, _estimator_designs, executor=executor, max_workers=max_workers, model=model,
                     progress=progress, seeds=seeds, results=results, numbers=numbers)
