"""Runs spread over the cores (or any concurrent.futures.Executor), in chunks: the machinery of
:func:`hydrogen.simulation.sweep.sweep` and of :func:`~hydrogen.simulation.simulator.simulate` over
seeds, which give it their workers (:mod:`hydrogen.simulation.simulator`'s chunk worker)."""
from __future__ import annotations

import multiprocessing
import os
from collections.abc import Mapping
from concurrent.futures import BrokenExecutor, Executor, ProcessPoolExecutor

__all__ = ["run_sweep", "check_workers", "chunks", "entry_problem", "MAX_WORKERS_PER_CORE", "CHUNKS_PER_WORKER",
           "MAX_CHUNK"]

#: More worker processes than this many per core only compete for the cores (and the process limit).
MAX_WORKERS_PER_CORE = 4

#: Keys an entry may hold besides the Scenario fields.
_ENTRY_KEYS = ("scenario", "controller", "gains", "duration", "check_workspace", "engine")


def entry_problem(run) -> str | None:
    """Why one sweep entry cannot run (None when it can): not a dict, an unknown key, or ``model``/
    ``dyn`` set per entry (the model is one per sweep: ``sweep(..., model=...)``)."""
    from .scenarios import Scenario

    if not isinstance(run, Mapping):
        return f"entry must be a dict of simulate() arguments, got {type(run).__name__} {str(run)[:100]!r}"
    for key in ("model", "dyn"):
        if key in run:
            return f"entry sets '{key}'; a sweep runs one model, pass it as sweep(..., model=...)"
    unknown = sorted(str(k) for k in run if k not in _ENTRY_KEYS and k not in Scenario.__dataclass_fields__)
    if unknown:
        return (f"entry has unknown key(s) {unknown}; keys are {', '.join(_ENTRY_KEYS)} and the scenario "
                f"fields {', '.join(sorted(Scenario.__dataclass_fields__))}")
    return None


def _error(exc) -> dict:
    """A failed run's place in the results: its message (and the time it stopped, when it ran)."""
    from ..errors import HydrogenError

    if isinstance(exc, HydrogenError):
        out = {"error": str(exc).splitlines()[0][:500]}
        if getattr(exc, "result", None) is not None and len(exc.result.t):
            out["failed_at_s"] = float(exc.result.t[-1])
        return out
    return {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0][:500] if str(exc) else ''}"}


def _outcome(res, keep):
    m = dict(res.metrics)  # u_saturation_frac among them (SimulationResult.compute_metrics)
    if keep:
        res.metrics = m
        return res
    return m


#: Chunks per worker a sweep is cut into: enough for the workers to share the load when runs differ
#: in length, few enough that each chunk runs many runs of one Batch.
CHUNKS_PER_WORKER = 4
#: The most runs one chunk holds (its results travel back together).
MAX_CHUNK = 32


def chunks(n_runs: int, workers: int, group: int = 1) -> list:
    """Consecutive index ranges cutting ``n_runs`` runs into chunks for ``workers`` workers. ``group``:
    the runs come in groups of that many that share a controller (the seeds of one sweep entry):
    where a chunk holds a group or more, it holds whole groups (the largest multiple of ``group`` not
    above the size it would otherwise have), so that a worker makes one controller per group, not one
    more for each group a chunk's edge cuts; smaller chunks keep their size (cut to parts of a group
    they would only be more chunks, each a controller)."""
    size = max(1, min(MAX_CHUNK, -(-n_runs // (CHUNKS_PER_WORKER * max(workers, 1)))))
    if 1 < group <= size:
        size -= size % group
    return [range(i, min(i + size, n_runs)) for i in range(0, n_runs, size)]


def run_sweep(runs, chunk_worker, filters_of, *, executor: Executor | None = None, max_workers: int | None = None,
              model=None, progress: bool = False, seeds=None, results: bool = False,
              numbers: str | None = None, _group: int = 1) -> list:
    """:func:`hydrogen.simulation.sweep.sweep` (its arguments and results), the work given by its
    caller: ``chunk_worker`` (a module-level function, for the worker processes) runs one chunk's job
    ``(model, runs, keep, numbers, filters)`` and gives one result per run; ``filters_of(model, runs)``
    gives ``filters``, what the parent solves once for every worker."""
    from ..errors import ScenarioError, WorkerError
    from ..runtime.build import as_model
    from .seeds import seed_list, summarize

    if isinstance(runs, (str, bytes, Mapping)) or not hasattr(runs, "__iter__"):
        raise ScenarioError(f"sweep: runs must be a list of dicts (one per run), got {type(runs).__name__}")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise ScenarioError(f"sweep: executor must be a concurrent.futures.Executor, got {executor!r}")
    if executor is None:
        check_workers(max_workers)
    if seeds is not None:
        if results:
            raise ScenarioError("sweep: results=True gives one SimulationResult per run; with seeds= each "
                                "entry gives the distribution of its runs (use results without seeds)")
        seeds = seed_list(seeds, "sweep: seeds")
        runs = list(runs)
        clash = "entry sets 'seed' and the sweep runs seeds=; give one of the two"
        mine = [i for i, r in enumerate(runs) if not (isinstance(r, Mapping) and "seed" in r)]
        flat = [dict(runs[i], seed=s) if isinstance(runs[i], Mapping) else runs[i] for i in mine for s in seeds]
        done = iter(run_sweep(flat, chunk_worker, filters_of, executor=executor, max_workers=max_workers, model=model,
                              progress=progress, numbers=numbers, _group=len(seeds)))
        per = {i: [next(done) for _ in seeds] for i in mine}
        return [summarize(seeds, per.get(i) or [{"error": clash}] * len(seeds)) for i in range(len(runs))]
    # The Model itself goes to the workers (not its file name): in-memory edits are kept.
    model = as_model(model)
    from tqdm import tqdm

    if numbers is not None:
        from ..codegen.generate import check_numbers_mode
        check_numbers_mode(numbers)  # once here, not once per run in the workers
    from .scenarios import current_name
    # a former variant name resolved here: its note shown once, by this process, not by each worker
    runs = [dict(r, scenario=current_name(r["scenario"], model)) if isinstance(r, Mapping)
            and isinstance(r.get("scenario"), str) else r for r in runs]
    keep = bool(results)
    parts = chunks(len(runs), max_workers or os.cpu_count() or 1, _group)
    filters = filters_of(model, runs)

    def submit(ex, part):
        return part, ex.submit(chunk_worker, (model, [runs[i] for i in part], keep, numbers, filters))

    def collect(ex, workers):
        futures = []  # (runs of the chunk, its future or the exception submitting it raised)
        for part in parts:
            try:
                futures.append(submit(ex, part))
            except (OSError, BrokenExecutor) as exc:  # the executor, not the entry: no run can be trusted
                _cancel(futures)
                raise WorkerError(_start_failure(exc, workers)) from None
            except Exception as exc:  # noqa: BLE001 - e.g. an entry that cannot be pickled: result() sorts it out
                futures.append((part, exc))

        def result(part, f):
            try:
                if isinstance(f, Exception):
                    raise f
                done = f.result()
                if not isinstance(done, list) or len(done) != len(part):
                    raise RuntimeError(f"a worker gave {type(done).__name__} for a chunk of {len(part)} runs")
                return done
            except BrokenExecutor as exc:  # a worker died: every pending run fails with it, not one entry
                _cancel(futures)
                raise WorkerError(f"sweep: a worker process died abruptly while run {part[0] + 1} of {len(runs)} "
                                  f"was pending ({type(exc).__name__}: {str(exc)[:200]}): killed by the system "
                                  f"(out of memory?) or a crash in compiled code; no result of the sweep is "
                                  f"reported. Run the entries alone with hydrogen.simulate to find the one that "
                                  f"crashes, or use fewer workers") from None
            except Exception as exc:  # noqa: BLE001 - these entries' error, in their place
                if len(part) == 1:
                    return [{"error": f"{type(exc).__name__}: {str(exc)[:500]}"}]
            # one entry may spoil its chunk (a process pool pickles it after submit): the runs one by one
            single = []
            for i in part:
                try:
                    single.append(submit(ex, range(i, i + 1)))
                except (OSError, BrokenExecutor) as exc:
                    _cancel(futures)
                    raise WorkerError(_start_failure(exc, workers)) from None
                except Exception as exc:  # noqa: BLE001 - this entry's error, in its place
                    single.append((range(i, i + 1), exc))
            return [m for one, g in single for m in result(one, g)]

        out = []
        with tqdm(total=len(runs), desc="sweep", unit="run", disable=None if progress else True) as bar:
            for part, f in futures:
                out += result(part, f)
                bar.update(len(part))
        return out

    if executor is not None:
        return collect(executor, max_workers)
    workers = max_workers or os.cpu_count() or 1
    before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(max_workers=workers)
    try:
        out = collect(pool, workers)
    except BaseException:
        _abandon(pool, before)
        raise
    pool.shutdown(wait=True)
    return out


def check_workers(max_workers) -> None:
    """Refuse a worker count that is not an integer >= 1 or is above MAX_WORKERS_PER_CORE x the cores."""
    from ..errors import ScenarioError

    if max_workers is None:
        return
    if isinstance(max_workers, bool) or not isinstance(max_workers, int) or max_workers < 1:
        raise ScenarioError(f"sweep: max_workers must be an integer >= 1, got {max_workers!r}")
    cores = os.cpu_count() or 1
    if max_workers > MAX_WORKERS_PER_CORE * cores:
        raise ScenarioError(f"max_workers (--workers) {max_workers} for {cores} core(s): at most "
                            f"{MAX_WORKERS_PER_CORE * cores} "
                            f"({MAX_WORKERS_PER_CORE} per core; more only compete for the cores and the process "
                            f"limit); the default is the core count")


def _start_failure(exc, workers) -> str:
    return (f"sweep: could not start {workers or 'the'} worker processes ({type(exc).__name__}: "
            f"{str(exc)[:200]}): the system refuses more processes (its per-user process limit, ulimit -u, or "
            f"memory); run with fewer workers (--workers / max_workers, e.g. 1) or end some processes")


def _cancel(futures) -> None:
    for _, f in futures:
        if not isinstance(f, Exception):
            f.cancel()


def _abandon(pool, before) -> None:
    """Shut a failed pool down without waiting, and end the worker processes it started: a worker
    that never gets its stop signal would keep the interpreter from exiting (it joins its children)."""
    pool.shutdown(wait=False, cancel_futures=True)
    started = [p for p in multiprocessing.active_children() if p not in before]
    for p in started:
        p.terminate()
    for p in started:
        p.join(timeout=5)
        if p.is_alive():
            p.kill()
            p.join(timeout=5)
