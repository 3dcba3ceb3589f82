"""Sweep throughput on 2 workers: the default process pool, a persistent process pool and a Dask
LocalCluster, side by side in one run; and identification time for the paper-sim log.

Sweeps run in a fresh Python process, as a user's script calls them (``bench_loop`` explains why):
8 P-gain runs of z-1hz, the median of ``repeats`` sweeps per route, the routes interleaved (so a
change in the machine's load reaches all alike), after one warm-up sweep on the persistent
executors (the workers import hydrogen and load the library once):

* ``pool_new``: ``hydrogen.sweep(runs, max_workers=2)``, the default: a new process pool per call,
  so every sweep pays the workers' start-up;
* ``pool_persistent``: one ``ProcessPoolExecutor(2)`` passed as ``executor=`` to every sweep;
* ``dask``: ``executor=client.get_executor()`` on a ``LocalCluster(n_workers=2, processes=True,
  threads_per_worker=1)`` started once (its start-up time is reported apart).

Identification: ``hydrogen.identify`` on paper-sim's 10 s log (10,001 samples) with the rig's
sensor noise, median of ``repeats`` calls, with its stages.

Batched sweeps against the C loop (``--batch`` runs this part alone): 100 runs of z-1hz with P
(10 gain sets x 10 noise seeds, ``sweep(runs, seeds=10)``), in runs per CPU-second (the parent's CPU
time and its joined workers', so a worker's start-up counts), the routes interleaved, median of
``repeats``:

* ``c_loop``: the bare C loop (``LoopRunner.run``) of the same 100 runs, timed alone in one process:
  the most any route can reach;
* ``per_run_former``: one run per task in a new 2-process pool, each run prepared alone (``_run_one``,
  the sweep's route before batching) at the rig's former plant integration (``bench_rig_period.FORMER``:
  8 sub-steps, the pressures clipped after each step): the sweep as it was before both;
* ``per_run``: the same at the scenario's own integration;
* ``batched``: ``hydrogen.sweep(runs, seeds=10, max_workers=2)``, the default: chunks of runs per task,
  one Batch per scenario in each;
* ``batched_threads``: the same on a ``ThreadPoolExecutor(2)`` (the C loop releases the GIL: no
  worker start-up, no pickling).

Then the same 100 runs through ``hydrogen.sweep(runs, seeds=10, max_workers=2)`` of commit
:data:`RELEASE` (extracted with ``git archive``, its own description and cache, in its own process
right after): the release the targets were set against, as its users ran it.

Run: ``python benchmarks/bench_sweep.py [--quick] [--batch] [--json FILE]``
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import hydrogen

try:  # imported as benchmarks.bench_sweep
    from . import common
    from .bench_rig_period import FORMER
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common
    from bench_rig_period import FORMER

WORKERS = 2
#: The release the batched sweep is compared with: the commit the throughput targets were set against.
RELEASE = "6480770"

_SWEEP = """
import statistics, time
from concurrent.futures import ProcessPoolExecutor
import numpy as np
import hydrogen
runs = [dict(scenario="z-1hz", controller="p", gains={{"Kleg": float(k)}}, duration={duration})
        for k in np.geomspace(0.02, 0.3, 8)]
hydrogen.simulate(**runs[0])  # build once, as any first call does

def timed(executor=None):
    t0 = time.perf_counter()
    hydrogen.sweep(runs, executor=executor, max_workers={workers})
    return len(runs) / (time.perf_counter() - t0)

if __name__ == "__main__":
    routes = {{"pool_new": None}}
    with ProcessPoolExecutor({workers}) as pool:
        hydrogen.sweep(runs[:{workers}], executor=pool)  # warm-up
        routes["pool_persistent"] = pool
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            print("dask_missing 1")
            cluster = None
        else:
            t0 = time.perf_counter()
            cluster = LocalCluster(n_workers={workers}, processes=True, threads_per_worker=1, dashboard_address=None)
            client = Client(cluster)
            print("dask_cluster_start_s", time.perf_counter() - t0)
            routes["dask"] = client.get_executor()
            t0 = time.perf_counter()
            hydrogen.sweep(runs[:{workers}], executor=routes["dask"])  # warm-up: import and load in each worker
            print("dask_first_sweep_s", time.perf_counter() - t0)
        # interleaved, so a change in the machine's load reaches every route alike
        rates = {{k: [] for k in routes}}
        for _ in range({repeats}):
            for k, ex in routes.items():
                rates[k].append(timed(ex))
        for k, v in rates.items():
            print(f"runs_per_s_{{k}}", statistics.median(v))
        if cluster is not None:
            client.close()
            cluster.close()
"""


_BATCH = """
import resource, statistics, time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
import numpy as np
import hydrogen
from hydrogen.runtime.build import as_model, default_dynamics
from hydrogen.simulation import simulator as S
from hydrogen.simulation.sweep import _run_one

DURATION, SEEDS, WORKERS, FORMER = {duration}, 10, {workers}, {former!r}
runs = [dict(scenario="z-1hz", controller="p", gains={{"Kleg": float(k)}}, duration=DURATION)
        for k in np.geomspace(0.02, 0.3, 10)]
flat = [dict(r, seed=s) for r in runs for s in range(SEEDS)]
model = as_model(None)
dyn = default_dynamics(model, controller="p")  # built and loaded once, as any first call does

def cpu():  # this process (its threads) and its children that were joined
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime

def c_loop():
    spent = 0.0
    for r in flat:
        p = S.prepare_run(dyn, r["scenario"], r["controller"], r["gains"], r["duration"], True, {{"seed": r["seed"]}})
        runner = S.make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
        log = S.new_logs(dyn.model, p.n, p.ctrl.xc.size)
        logs = {{k: v for k, v in log.items() if k != "xc" or p.ctrl.xc.size}}  # every log simulate keeps
        t0 = time.process_time()
        assert runner.run(p.n, p.noise, logs) == 0
        spent += time.process_time() - t0
    return spent

def per_run(runs=flat):
    with ProcessPoolExecutor(WORKERS) as pool:
        out = list(pool.map(_run_one, [(model, r, False, None) for r in runs]))
    assert not any("error" in m for m in out)

def per_run_former():
    per_run([dict(r, **FORMER) for r in flat])

def batched():
    out = hydrogen.sweep(runs, seeds=SEEDS, max_workers=WORKERS)
    assert all(o["completed"] == SEEDS for o in out)

def batched_threads():
    with ThreadPoolExecutor(WORKERS) as ex:
        out = hydrogen.sweep(runs, seeds=SEEDS, executor=ex)
    assert all(o["completed"] == SEEDS for o in out)

if __name__ == "__main__":
    routes = {{"per_run_former": per_run_former, "per_run": per_run, "batched": batched,
              "batched_threads": batched_threads}}
    rates = {{k: [] for k in ("c_loop", *routes)}}
    walls = {{k: [] for k in routes}}
    for _ in range({repeats}):  # interleaved, so a change in the machine's load reaches every route alike
        rates["c_loop"].append(len(flat) / c_loop())
        for k, f in routes.items():
            c0, w0 = cpu(), time.perf_counter()
            f()
            c, w = cpu() - c0, time.perf_counter() - w0
            rates[k].append(len(flat) / c)
            walls[k].append(len(flat) / w)
    for k, v in rates.items():
        print(f"runs_per_cpu_s_{{k}}", statistics.median(v))
    for k, v in walls.items():
        print(f"runs_per_wall_s_{{k}}", statistics.median(v))
"""


_RELEASE = """
import resource, statistics
import numpy as np
import hydrogen
print("hydrogen_file", 0, hydrogen.__file__)
runs = [dict(scenario="z-1hz", controller="p", gains={{"Kleg": float(k)}}, duration={duration})
        for k in np.geomspace(0.02, 0.3, 10)]

def cpu():
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime

if __name__ == "__main__":
    hydrogen.simulate(**runs[0])  # its library built and loaded once, as any first call does
    rates = []
    for _ in range({repeats}):
        c0 = cpu()
        out = hydrogen.sweep(runs, seeds={seeds}, max_workers={workers})
        rates.append(len(runs) * {seeds} / (cpu() - c0))
        assert all(o.get("completed") == {seeds} for o in out), out
    print("runs_per_cpu_s_release", statistics.median(rates))
"""


def release_throughput(duration: float, repeats: int, commit: str = RELEASE) -> dict:
    """The same sweep (100 z-1hz P runs: 10 gain sets x 10 seeds) in commit ``commit`` of this
    repository, its own code, description and plant integration: the sweep as that release ran it,
    runs per CPU-second of its parent and its joined workers; {"skipped": why} when the commit cannot
    be extracted."""
    import tempfile

    try:
        from .bench_release import Version, _extract_previous
    except ImportError:
        from bench_release import Version, _extract_previous

    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "release"
        why = _extract_previous(src, commit)
        if why:
            return {"skipped": why}
        version = Version(f"commit {commit}", src, Path(tmp) / "cache")
        stdout, _ = version.run(_RELEASE.format(duration=duration, repeats=repeats, seeds=10, workers=WORKERS))
    return {"commit": commit, "runs_per_cpu_s": common.parse_keyed(stdout).get("runs_per_cpu_s_release")}


def batch_throughput(quick: bool = False) -> dict:
    """The batched sweep against the per-run route and the bare C loop (module doc)."""
    repeats = 1 if quick else 3
    duration = 2.0 if quick else 6.0
    load_before = os.getloadavg()[0]
    stdout, _ = common.run_python(_BATCH.format(duration=duration, repeats=repeats, workers=WORKERS, former=FORMER),
                                  timeout=1800)
    k = common.parse_keyed(stdout)
    routes = ("c_loop", "per_run_former", "per_run", "batched", "batched_threads")
    out = {"runs": 100, "gain_sets": 10, "seeds": 10, "sim_duration_s": duration, "workers": WORKERS,
           "repeats": repeats, "runs_per_cpu_s": {r: k.get(f"runs_per_cpu_s_{r}") for r in routes},
           "runs_per_wall_s": {r: k.get(f"runs_per_wall_s_{r}") for r in routes[1:]}}
    c = out["runs_per_cpu_s"]
    out["of_c_loop"] = {r: c[r] / c["c_loop"] for r in routes[1:]}
    out["batched_over_per_run"] = c["batched"] / c["per_run"]
    out["batched_over_former"] = c["batched"] / c["per_run_former"]
    out["former"] = FORMER
    out["release"] = release_throughput(duration, repeats)
    rel = out["release"].get("runs_per_cpu_s")
    out["batched_over_release"] = c["batched"] / rel if rel else None
    out["load_avg_1min"] = [load_before, os.getloadavg()[0]]
    return out


def print_batch(res) -> None:
    print(f"batched sweep: {res['runs']} z-1hz P runs ({res['gain_sets']} gain sets x {res['seeds']} seeds, "
          f"{res['sim_duration_s']:.0f} s each), {res['workers']} workers, median of {res['repeats']} "
          f"(1-min load average {res['load_avg_1min'][0]:.1f} before, {res['load_avg_1min'][1]:.1f} after):")
    names = {"c_loop": "bare C loop (LoopRunner.run alone)",
             "per_run_former": "one run per task, former integration",
             "per_run": "one run per task (before batching)",
             "batched": "batched, process pool (default)", "batched_threads": "batched, thread pool"}
    for key, label in names.items():
        cpu = res["runs_per_cpu_s"][key]
        wall = res["runs_per_wall_s"].get(key)
        of = f"{res['of_c_loop'][key]:5.2f} of the C loop" if key in res["of_c_loop"] else ""
        print(f"  {label:38} {cpu:7.1f} runs/CPU-s {'' if wall is None else f'{wall:7.1f} runs/wall-s'}  {of}")
    print(f"  batched / one run per task: {res['batched_over_per_run']:.2f}x runs per CPU-second; against one run "
          f"per task at the former integration: {res['batched_over_former']:.2f}x")
    rel = res.get("release") or {}
    if rel.get("runs_per_cpu_s"):
        print(f"  the same sweep in commit {rel['commit']} (its own code and description): {rel['runs_per_cpu_s']:.1f} "
              f"runs/CPU-s; batched / that: {res['batched_over_release']:.2f}x")
    elif rel:
        print(f"  commit {RELEASE} not measured: {rel.get('skipped')}")


def identification_time(repeats: int) -> dict:
    from hydrogen.logs import log_from_result
    dyn = hydrogen.build()
    res = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn)
    log = log_from_result(res, noise_l=5e-6, noise_p=2e4, seed=0)
    hydrogen.identify(log, dyn=dyn)  # scipy imported, library loaded
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = hydrogen.identify(log, dyn=dyn)
        runs.append((time.perf_counter() - t0, out))
    wall, out = sorted(runs, key=lambda r: r[0])[len(runs) // 2]
    return {"samples": out.n_samples, "wall_s": wall, "stages_s": out.timings_s,
            "theta_error_pct": out.theta.error_pct.tolist(), "gamma_error_pct": out.gamma.error_pct.tolist()}


def run(quick: bool = False) -> dict:
    repeats = 3 if quick else 9
    load_before = os.getloadavg()[0]
    code = _SWEEP.format(duration=2.0 if quick else 6.0, repeats=repeats, workers=WORKERS)
    stdout, _ = common.run_python(code)
    k = common.parse_keyed(stdout)
    out = {"workers": WORKERS, "cores": os.cpu_count(), "runs": 8, "sim_duration_s": 2.0 if quick else 6.0,
           "runs_per_s": {r: k.get(f"runs_per_s_{r}") for r in ("pool_new", "pool_persistent", "dask")},
           "dask_cluster_start_s": k.get("dask_cluster_start_s"), "dask_first_sweep_s": k.get("dask_first_sweep_s"),
           "dask_installed": "dask_missing" not in k}
    out["identify_paper_sim"] = identification_time(repeats)
    out["batch"] = batch_throughput(quick)
    out["load_avg_1min"] = [load_before, os.getloadavg()[0]]  # other processes on the machine, before/after
    return out


def print_table(res):
    print(f"sweep of {res['runs']} z-1hz runs ({res['sim_duration_s']:.0f} s each) on {res['workers']} workers "
          f"({res['cores']} cores; 1-min load average {res['load_avg_1min'][0]:.1f} before, "
          f"{res['load_avg_1min'][1]:.1f} after), medians:")
    names = {"pool_new": "process pool, new per sweep (default)", "pool_persistent": "process pool, persistent",
             "dask": "Dask LocalCluster, 2 process workers"}
    for key, label in names.items():
        v = res["runs_per_s"][key]
        print(f"  {label:42} {'-' if v is None else f'{v:8.2f}'} runs/s")
    if res["dask_installed"]:
        print(f"  Dask cluster start {res['dask_cluster_start_s']:.2f} s; first sweep (workers import and load) "
              f"{res['dask_first_sweep_s']:.2f} s")
    else:
        print("  Dask not installed (pip install -e '.[distributed]')")
    ident = res["identify_paper_sim"]
    stages = ", ".join(f"{k} {v * 1e3:.0f} ms" for k, v in ident["stages_s"].items() if k != "total")
    print(f"identify on the paper-sim log ({ident['samples']} samples): {ident['wall_s']:.2f} s ({stages})")
    print_batch(res["batch"])


if __name__ == "__main__":
    if "--batch" in sys.argv:  # the batched-sweep part alone
        sys.argv.remove("--batch")
        sys.exit(common.script_main(__doc__, batch_throughput, print_batch))
    sys.exit(common.script_main(__doc__, run, print_table))
