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

Run: ``python benchmarks/bench_sweep.py [--quick] [--json FILE]``
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import hydrogen

try:  # imported as benchmarks.bench_sweep
    from . import common
except ImportError:  # run as a script, or loaded from its path
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import common

WORKERS = 2

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


if __name__ == "__main__":
    sys.exit(common.script_main(__doc__, run, print_table))
