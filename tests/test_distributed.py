"""Sweeps past one machine: hydrogen.sweep on a Dask distributed cluster (the optional extra ``distributed``)."""
import pytest

import hydrogen

distributed = pytest.importorskip("distributed")

#: Metrics that are timings, so differ from run to run.
_TIMINGS = {"wall_time_s", "loop_wall_s"}


def test_dask_cluster_sweep_equals_the_process_pool(dyn, cache, monkeypatch):
    monkeypatch.setenv("HYDROGEN_CACHE_DIR", str(cache))  # the workers load the library this session built
    runs = [dict(scenario="z-1hz", controller="p", gains={"Kleg": k}, duration=1.0) for k in (0.02, 0.04)]
    runs += [dict(scenario="paper-sim", controller=c, duration=1.0) for c in ("adaptive-robust", "adaptive-observer")]
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cl, \
            distributed.Client(cl) as client:
        on_dask = hydrogen.sweep(runs, executor=client.get_executor())
        workers = client.run(lambda: __import__("os").getpid())
    pool = hydrogen.sweep(runs, max_workers=2)
    assert len(workers) == 2 and len(on_dask) == len(runs)
    for d, p in zip(on_dask, pool):
        assert {k: v for k, v in d.items() if k not in _TIMINGS} == {k: v for k, v in p.items() if k not in _TIMINGS}
