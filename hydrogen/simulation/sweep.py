"""Many simulations through one call, spread over the cores (or any concurrent.futures.Executor)."""
from __future__ import annotations

import multiprocessing
import os
from collections.abc import Mapping
from concurrent.futures import BrokenExecutor, Executor, ProcessPoolExecutor

__all__ = ["sweep", "check_workers", "MAX_WORKERS_PER_CORE"]

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


def _run_one(job):
    """Worker: build (once per process) and run one simulation alone, as :func:`hydrogen.simulate`
    does; return its metrics (its SimulationResult when ``keep``, the metrics completed the same way)
    or its error."""
    from ..runtime.build import default_dynamics
    from .simulator import simulate

    model, run, keep, numbers = job
    problem = entry_problem(run)
    if problem:
        return {"error": problem}
    run = dict(run)
    scenario = run.pop("scenario", "paper-sim")
    controller = run.pop("controller", "adaptive-robust")
    try:
        dyn = default_dynamics(model, controller=controller, numbers=numbers)
        res = simulate(dyn, scenario, controller, **run)
    except Exception as exc:  # noqa: BLE001 - one bad entry must not cost the others their results
        return _error(exc)
    return _outcome(res, keep)


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


#: Entry keys a run of a batch takes one by one; the rest (scenario, controller, duration, check_workspace
#: and the scenario fields) decide which runs share one Batch.
_PER_RUN = ("gains", "seed")


def _run_chunk(job):
    """Worker: the runs of a chunk of entries (``job``: model, entries, keep, numbers, the Kalman gains
    the parent solved for their scenarios: :func:`_filter_gains`), in order, each
    as :func:`_run_one` would give it. Entries that differ only in gains and seed share one
    :class:`~hydrogen.simulation.simulator.Batch` (the scenario resolved and checked once, a controller
    per gain set). Whatever fails before a run's loop starts is run again alone, so that its message is
    exactly the one the run alone gives."""
    import pickle

    from ..runtime.build import default_dynamics
    from .simulator import SCENARIO_SEED, Batch, remember_filter_gains, run_prepared

    model, runs, keep, numbers, filters = job
    remember_filter_gains(filters)
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
                dyn = default_dynamics(model, controller=controller, numbers=numbers)
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


def _filter_gains(model, runs) -> dict:
    """The Kalman gains of the runs' scenarios, solved once here for the whole sweep: each worker
    would otherwise import SciPy and solve the same Riccati equation (a third of a second of CPU per
    worker process). An entry whose scenario does not resolve is left to its run to report."""
    import pickle

    from .scenarios import Scenario, scenario as named_scenario
    from .simulator import filter_gains, filter_setting

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
            if sc.kalman:
                settings.append(filter_setting(sc, 1.0 / sc.control_rate))
        except Exception:  # noqa: BLE001 - the run reports it with its own message
            continue
    return filter_gains(settings)


#: Chunks per worker a sweep is cut into: enough for the workers to share the load when runs differ
#: in length, few enough that each chunk runs many runs of one Batch.
CHUNKS_PER_WORKER = 4
#: The most runs one chunk holds (its results travel back together).
MAX_CHUNK = 32


def chunks(n_runs: int, workers: int) -> list:
    """Consecutive index ranges cutting ``n_runs`` runs into chunks for ``workers`` workers."""
    size = max(1, min(MAX_CHUNK, -(-n_runs // (CHUNKS_PER_WORKER * max(workers, 1)))))
    return [range(i, min(i + size, n_runs)) for i in range(0, n_runs, size)]


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
    Kalman gain once for all the workers. Every run's metrics are those of the run alone, to the bit.
    The compiled loop releases the GIL, so a ``ThreadPoolExecutor`` runs the chunks side by side in
    this process, with no worker start-up.
    """
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
        done = iter(sweep(flat, executor=executor, max_workers=max_workers, model=model, progress=progress,
                          numbers=numbers))
        per = {i: [next(done) for _ in seeds] for i in mine}
        return [summarize(seeds, per.get(i) or [{"error": clash}] * len(seeds)) for i in range(len(runs))]
    # The Model itself goes to the workers (not its file name): in-memory edits are kept.
    model = as_model(model)
    from tqdm import tqdm

    if numbers is not None:
        from ..codegen.generate import check_numbers_mode
        check_numbers_mode(numbers)  # once here, not once per run in the workers
    runs = list(runs)
    keep = bool(results)
    parts = chunks(len(runs), max_workers or os.cpu_count() or 1)
    filters = _filter_gains(model, runs)

    def submit(ex, part):
        return part, ex.submit(_run_chunk, (model, [runs[i] for i in part], keep, numbers, filters))

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
