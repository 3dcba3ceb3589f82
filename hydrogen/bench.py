"""``hydrogen bench``: run the benchmark suite of ``benchmarks/`` in one process and one run.

The suite lives beside the package in a source checkout (``benchmarks/``); each module has
``run(quick) -> dict`` and ``print_table(dict)``. The figures are reported; the project's own
release targets (bounds against the previous release, generation-time targets) are checked only
with ``release_checks`` (``hydrogen bench --release-checks``, for the project's developers), by the
modules whose ``print_table`` takes ``checks``.
"""
from __future__ import annotations

import importlib
import inspect
import json
import sys
from pathlib import Path

from .errors import HydrogenError
from .fileio import atomic_write

__all__ = ["run_suite", "SUITE", "merge_results"]

#: (module, what it measures)
SUITE = (
    ("bench_loop", "paper-sim loop per control period: lambdify, CasADi, stepping API, C loop; sweeps"),
    ("bench_functions", "C-only cost of each generated function"),
    ("bench_calls", "per call from Python by route (extension, ctypes, CasADi, Pinocchio) and batches, "
                    "against the C cost"),
    ("bench_build", "generation and compilation times; SymPy vs CasADi-AD instruction counts"),
    ("bench_flags", "compiler flags: compile time and loop cost"),
    ("bench_sweep", "sweep throughput on 2 workers: process pool and Dask LocalCluster; identification time"),
    ("bench_release", "side by side with the previous release: trajectories, instruction counts, loop, generation"),
    ("bench_scaling", "how cost grows with the robot: planar chains of n = 2 ... 7 links"),
    ("bench_predictor", "the delay predictor's cost per control period and in instructions, every controller"),
    ("bench_folding", "the description's numbers folded into the C against runtime inputs: instructions, ns per call"),
    ("bench_edit", "a numeric edit of the description to the next run: numbers as inputs against folded"),
    ("bench_cold", "a structural edit to the first run, empty cache: shipped robots, a spatial leg, a 7-link chain, "
                   "a URDF-born leg by both routes"),
    ("bench_structural", "a structural edit of each shipped robot (a fixed link added, a joint axis reversed) to "
                         "its first run, on a cache holding the shipped build"),
    ("bench_code_edit", "an edit of hydrogen's code (a rig part added, the loop template edited) to each shipped "
                        "robot's first run: the part that uses it generated alone, against a whole generation"),
    ("bench_recursive", "the rigid body against Featherstone's ABA, RNEA and CRBA on SX: instructions, n = 2 ... 16, folded and numbers as inputs"),
    ("bench_period", "per-period cost of every scenario's C loop and per-call cost from Python against an earlier commit"),
    ("bench_shared_step", "the semi-implicit step with the controller inlined against calling it: per call, "
                          "per period, compile"),
    ("bench_integrator", "the rig's plant sub-steps (and the predictor's) against a reference over noise seeds: "
                         "errors and cost per period"),
    ("bench_local_error", "the rig's runs replayed open loop at each plant sub-step count against a reference: "
                          "the integration's own error"),
    ("bench_rig_period", "the rig's control period at the shipped plant integration against the former one: cost "
                         "and reported errors against a reference, side by side"),
    ("bench_delay", "the rig's tracking error against the computation delay, 0 to 1 control period, every "
                    "controller over noise seeds; its figure"),
    ("bench_sensitivity", "the rig's tracking error against its friction level and valve bandwidth, every controller "
                          "over noise seeds; its figure"),
    ("supply_limits", "the excavator arm and the loader crane on their pumps, in a scenario whose flow runs out: every "
                      "controller with the measured supply pressure against the same assuming a constant supply"),
)


def _print(mod, res: dict, release_checks: bool) -> None:
    if "checks" in inspect.signature(mod.print_table).parameters:
        mod.print_table(res, checks=release_checks)
    else:
        mod.print_table(res)


def _figures_only(res):
    """A module's results without its pass/fail against the release targets (``checks``, ``met``, each row's ``bound`` and ``status``)."""
    if isinstance(res, dict):
        return {k: _figures_only(v) for k, v in res.items() if k not in ("checks", "met", "bound", "status")}
    return res


def check_results_file(path: Path) -> None:
    """Nothing, when ``bench`` may write its results to ``path``: no file there, or one it wrote (a
    JSON object whose keys are the suite's modules); else an OutputPathError naming the file."""
    from .errors import OutputPathError

    path = Path(path)
    if not (path.exists() or path.is_symlink()):
        return
    why = None
    if path.is_symlink() or not path.is_file():
        why = "not a regular file"
    else:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            data = None
        modules = {n for n, _ in SUITE}
        if not (isinstance(data, dict) and set(data) <= modules):
            why = "not results 'hydrogen bench' wrote (a JSON object of its modules' results)"
    if why:
        raise OutputPathError(f"{path}: {why}, and 'hydrogen bench' would write its results over it: move that "
                              "file, or give --json another name")


def merge_results(path, sections: dict) -> None:
    """Write ``sections`` ({module: results}) into the results file ``path`` atomically: those
    modules' sections of the results bench wrote there are replaced, the others kept in their
    order; no file there, the sections alone. An OutputPathError when ``path`` holds anything
    else (:func:`check_results_file`)."""
    path = Path(path)
    check_results_file(path)
    merged = json.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
    merged.update(sections)
    atomic_write(path, json.dumps(merged, indent=2, default=str) + "\n")


def run_suite(quick: bool = False, json_path: str | None = None, only=None, progress: bool = True,
              release_checks: bool = False) -> dict:
    """Run the suite's modules (all, or those named in ``only``) in this process, print each one's
    table, and return {module: results}. With ``json_path`` the results are written there as JSON
    (with ``only``, into the results already there: :func:`merge_results`, the other modules'
    sections kept) and rendered to ``benchmarks.md`` beside it
    (:func:`hydrogen.pages.write_benchmarks_page`); with
    ``release_checks`` (developers) each module's checks against the release targets are printed and kept."""
    unknown = sorted(set(only or ()) - {n for n, _ in SUITE})
    if unknown:
        raise HydrogenError(f"unknown benchmark module(s) {unknown}; the suite has {', '.join(n for n, _ in SUITE)}")
    if json_path:
        from .pages import check_benchmarks_page
        check_benchmarks_page(json_path)  # before minutes of benchmarks, not after
        for path in (Path(json_path), Path(json_path).with_suffix(".partial.json")):
            check_results_file(path)
    folder = Path(__file__).resolve().parents[1] / "benchmarks"
    if not folder.is_dir():
        raise HydrogenError(f"{folder}: no benchmarks folder; run 'hydrogen bench' from a source checkout")
    sys.path.insert(0, str(folder))
    from tqdm import tqdm

    results, failed = {}, {}
    todo = [(n, w) for n, w in SUITE if not only or n in only]
    bar = tqdm(total=len(todo), desc="bench", unit="module", disable=None if progress else True)
    for name, what in todo:
        bar.set_postfix_str(name)
        mod = importlib.import_module(name)
        try:
            results[name] = mod.run(quick=quick)
        except Exception as exc:  # one module's failure must not lose what the others measured
            failed[name] = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            bar.update()
            tqdm.write(f"\n== {name}: failed: {failed[name]}")
            continue
        bar.update()
        tqdm.write(f"\n== {name}: {what}")
        _print(mod, results[name], release_checks)
    bar.close()
    if failed:
        # the figures of the modules that ran go beside the file asked for, never over it: a page
        # rendered from them would drop the failed modules' sections
        kept = ""
        if json_path and results:
            partial = Path(json_path).with_suffix(".partial.json")
            atomic_write(partial, json.dumps(results if release_checks else _figures_only(results),
                                             indent=2, default=str) + "\n")
            kept = f"; the other modules' results are in {partial}"
        raise HydrogenError("benchmark module(s) failed: " + "; ".join(f"{k}: {v}" for k, v in failed.items())
                            + kept)
    if json_path:
        written = results if release_checks else _figures_only(results)
        if only:  # a few modules run again: the sections of the others stay
            merge_results(json_path, written)
        else:
            atomic_write(Path(json_path), json.dumps(written, indent=2, default=str) + "\n")
        print(f"\nresults written to {json_path}")
        from .pages import write_benchmarks_page  # the benchmarks page, from the JSON just written
        print(f"page written to {write_benchmarks_page(json_path)}")
    return results
