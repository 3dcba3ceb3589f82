"""Runs over noise seeds: a rig scenario's result is a distribution, not one number.

On the rig (sensor noise, quantised encoders, a delay) the adaptive loops are sensitive to the last
bit of their inputs: two runs whose noise differs by one part in 10^15 part ways after a few
seconds (tests/test_rig.py). A metric of one noise seed is one draw; :func:`summarize` gives, per
coordinate, the median, min and max over the seeds, and which seed is the *median run*.

**Seeds.** ``seeds=N`` (an integer >= 1) means the seeds 0, 1, ..., N-1 (the scenario field
``seed`` of each run); a list means those seeds. :data:`DEFAULT_SEEDS` is the count the documented
gain search and the margins judge over. A call runs at most :data:`MAX_SEED_COUNT` seeds, each at
most :data:`MAX_SEED` (both refused before anything is allocated or run).

**Median run.** The seed whose worst max error (% of amplitude, over the coordinates the reference
moves) is the lower median of the completed runs: a run that exists (with an even count, the
smaller of the two middle ones), so its time series can be shown. The per-coordinate ``median``
statistics are the usual medians (the mean of the two middle values for an even count).
"""
from __future__ import annotations

import itertools
import math
import numbers
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..setting import is_number

__all__ = ["DEFAULT_SEEDS", "MAX_SEED_COUNT", "MAX_SEED", "check_seed", "seed_list", "parse_seeds", "summarize", "median_seed", "SeedResults"]

#: Noise seeds (0 .. DEFAULT_SEEDS - 1) the documented search (tune) and the margins judge over.
DEFAULT_SEEDS = 10
#: The most seeds one call runs: each is a full simulation, so more is a typo (10**9 would fill the
#: memory with its list of runs before the first one starts).
MAX_SEED_COUNT = 10_000
#: The largest seed: a signed 64-bit integer, what NumPy arrays, TOML and JSON readers hold exactly
#: (NumPy's generator would take a larger one, the summaries and files of the runs would not).
MAX_SEED = 2**63 - 1


def check_seed(seed, what: str = "seed") -> int:
    """``seed`` as an int if it is an integer in 0 .. MAX_SEED, else a ScenarioError naming ``what``."""
    from ..errors import ScenarioError

    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral) or not 0 <= seed <= MAX_SEED:
        raise ScenarioError(f"{what}: seed {_short(seed)} is not an integer in 0 .. {MAX_SEED} (2**63 - 1)")
    return int(seed)


def _short(value) -> str:
    """``repr(value)`` cut to 40 characters (an integer of 10**5000 has no repr in Python >= 3.11)."""
    try:
        text = repr(value)
    except ValueError:
        return f"of {value.bit_length()} bits" if isinstance(value, numbers.Integral) else type(value).__name__
    return text if len(text) <= 40 else text[:37] + "..."


def seed_list(seeds, what: str = "seeds") -> list:
    """The seeds ``seeds`` stands for: an integer N in 1 .. MAX_SEED_COUNT -> [0, ..., N-1]; a list of
    at most MAX_SEED_COUNT distinct integers in 0 .. MAX_SEED -> that list. Anything else: a
    ScenarioError naming ``what``."""
    from ..errors import ScenarioError

    if isinstance(seeds, (bool, np.bool_)):
        raise ScenarioError(f"{what} must be a count (an integer >= 1) or a list of seeds, got {seeds!r}")
    if isinstance(seeds, numbers.Integral):
        if seeds < 1:
            raise ScenarioError(f"{what} = {seeds}: a count of seeds must be >= 1 (seeds 0 .. N-1)")
        if seeds > MAX_SEED_COUNT:
            raise ScenarioError(f"{what} = {_short(seeds)}: at most {MAX_SEED_COUNT} seeds (each is one simulation)")
        return list(range(int(seeds)))
    if isinstance(seeds, (str, bytes, Mapping)) or not hasattr(seeds, "__iter__"):
        raise ScenarioError(f"{what} must be a count (an integer >= 1) or a list of seeds, got "
                            f"{type(seeds).__name__} {seeds!r}"[:200])
    out = list(itertools.islice(seeds, MAX_SEED_COUNT + 1))  # a huge iterable is never listed whole
    if not out:
        raise ScenarioError(f"{what} is an empty list; give at least one seed")
    if len(out) > MAX_SEED_COUNT:
        raise ScenarioError(f"{what}: more than {MAX_SEED_COUNT} seeds (each is one simulation)")
    out = [check_seed(s, what) for s in out]
    dup = sorted(s for s, k in Counter(out).items() if k > 1)
    if dup:
        raise ScenarioError(f"{what}: seed(s) {dup} given twice; each seed is one run")
    return out


def parse_seeds(text: str):
    """``--seeds`` of the command line: ``10`` -> 10 (seeds 0..9), ``0,3,7`` -> [0, 3, 7]. Raises
    argparse.ArgumentTypeError (argparse names the option and exits with status 2)."""
    import argparse

    from ..errors import ScenarioError

    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) == 1:
            value = int(parts[0])
        else:
            value = [int(p) for p in parts if p]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a count of seeds (e.g. 10: seeds 0..9) or a "
                                         f"comma-separated list of seeds (e.g. 0,3,7)") from None
    try:
        seed_list(value, "--seeds")
    except ScenarioError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return value


def _stats(values):
    """(median, min, max) of a list of numbers; None when one of them is None (no amplitude)."""
    if any(v is None for v in values):
        return None, None, None
    a = np.asarray(values, float)
    return float(np.median(a)), float(a.min()), float(a.max())


def _worst(m) -> float:
    """Largest max error (% of amplitude) over the coordinates the reference moves."""
    vals = [v for v in (m.get("max_error_pct") or {}).values() if v is not None]
    return max(vals) if vals else math.nan


def median_seed(seeds, per_seed):
    """The seed of the median run (module doc) among the completed runs of ``per_seed`` (metrics
    dicts, one per seed; a failed run is {"error": ...}); None when none completed."""
    done = sorted((_worst(m), s) for s, m in zip(seeds, per_seed) if "error" not in m)
    return done[(len(done) - 1) // 2][1] if done else None


def summarize(seeds, per_seed) -> dict:
    """The distribution of the metrics of one run over seeds: {"seeds", "per_seed", "failed":
    [{"seed", "error"[, "failed_at_s"]}], "completed", "median_seed", "median", "min", "max"}.

    ``median``/``min``/``max`` hold, over the completed runs, every metric that is a number (e.g.
    ``u_saturation_frac``, ``sim_time_s``) or a {coordinate: number or None} dict (``max_error_pct``,
    ``max_error``, ``rms_error``, ``hf_error_rms``, ``amplitude``); None where the coordinate has none.
    When no seed completed, ``"error"`` says so with the first seed's message."""
    seeds = list(seeds)
    failed = [dict(seed=s, **m) for s, m in zip(seeds, per_seed) if "error" in m]
    done = [m for m in per_seed if "error" not in m]
    out = {"seeds": seeds, "per_seed": list(per_seed), "failed": failed, "completed": len(done),
           "median_seed": median_seed(seeds, per_seed), "median": {}, "min": {}, "max": {}}
    if not done:
        out["error"] = f"every seed failed (seed {failed[0]['seed']}: {failed[0]['error']})"
        return out
    for key, v in done[0].items():
        if not all(key in m for m in done):
            continue
        if is_number(v):
            if all(is_number(m[key]) for m in done):
                for name, x in zip(("median", "min", "max"), _stats([m[key] for m in done])):
                    out[name][key] = x
        elif isinstance(v, Mapping) and v and all(x is None or is_number(x) for x in v.values()):
            if not all(isinstance(m[key], Mapping) and m[key].keys() == v.keys() for m in done):
                continue
            cols = {c: _stats([m[key][c] for m in done]) for c in v}
            for j, name in enumerate(("median", "min", "max")):
                out[name][key] = {c: s[j] for c, s in cols.items()}
    return out


@dataclass
class SeedResults:
    """The runs of one scenario and controller over noise seeds (:func:`hydrogen.simulate` with
    ``seeds=``). ``results[i]`` is the :class:`~hydrogen.simulation.simulator.SimulationResult` of
    ``seeds[i]`` (None when that run failed: its message in ``failures``); ``metrics`` is
    :func:`summarize` of their metrics (median, min, max per coordinate; ``median_seed``)."""

    seeds: list
    results: list
    failures: dict = field(default_factory=dict)  # {seed: message} of the runs that failed
    metrics: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        """One line: the run, the seeds, the failures and each coordinate's median max error (%),
        not every array of every run."""
        done = self.completed
        what = f"{done[0].scenario_name!r}, {done[0].controller!r}, " if done else ""
        pct = (self.metrics.get("median") or {}).get("max_error_pct") or {}
        shown = ", ".join(f"{c} {v:.3g} %" for c, v in pct.items() if v is not None)
        return (f"SeedResults({what}seeds={list(self.seeds)}, completed {len(done)}, failed "
                f"{sorted(self.failures) or 'none'}{f'; median max error {shown}' if shown else ''})")

    @property
    def completed(self) -> list:
        """The results of the runs that completed, in seed order."""
        return [r for r in self.results if r is not None]

    @property
    def median_run(self):
        """The SimulationResult of the median run (module doc); None when no run completed."""
        s = self.metrics.get("median_seed")
        return None if s is None else self.results[self.seeds.index(s)]

    def _first(self):
        done = self.completed
        if not done:
            from ..errors import SimulationError
            raise SimulationError(f"no seed of {self.seeds} completed: "
                                  + "; ".join(f"seed {s}: {m}" for s, m in self.failures.items())[:500])
        return done[0]

    @property
    def scenario(self):
        """The Scenario run (the same for every seed but its seed)."""
        return self._first().scenario

    @property
    def scenario_name(self) -> str:
        """The scenario's name."""
        return self._first().scenario_name

    @property
    def controller(self) -> str:
        """The controller run."""
        return self._first().controller

    @property
    def coordinates(self) -> tuple:
        """The model's coordinate names."""
        return self._first().coordinates

    @property
    def units(self) -> tuple:
        """Each coordinate's SI unit (m or rad)."""
        return self._first().units

    def band(self, signal: str = "error"):
        """(t, low, high): the min-max envelope over the completed seeds of ``signal`` (an (k, n)
        array of the results: "error" = q − q_d, "q", ...), on the periods every run reached."""
        done = self.completed or [self._first()]
        k = min(len(r.t) for r in done)
        stack = np.stack([np.asarray(getattr(r, signal), float)[:k] for r in done])
        return np.asarray(done[0].t[:k], float), stack.min(axis=0), stack.max(axis=0)

    def to_json(self) -> str:
        """The metrics (median, min, max over the seeds) as JSON text."""
        import json
        return json.dumps(self.metrics, indent=2, sort_keys=True, default=float)
