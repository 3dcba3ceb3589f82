"""Helpers shared by the benchmark modules: paths, machine description, C drivers, plausible inputs,
the shipped robots and their scenarios.

Importable both as ``benchmarks.common`` (from the repository root or through ``hydrogen bench``)
and as ``common`` when a benchmark is run as a script from ``benchmarks/``.
"""
from __future__ import annotations

import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TEMPLATES = REPO / "templates"
#: Flags of every benchmark C driver (the generated code must build cleanly under them).
CFLAGS = ("-O2", "-std=c99", "-Wall", "-Wextra", "-Werror")

# ---------------------------------------------------------------------------------------------
# plausible input values, by input name, for any model (SI units)
# ---------------------------------------------------------------------------------------------
#: Fixed values of inputs that are not state-like.
FIXED = {"adapt": np.array([1.0]), "h": np.array([1e-3])}
#: The rig's friction on every actuator (Coulomb N, viscous N s/m, tanh speed m/s; no seal terms);
#: every other plant input of numbers at its block's ideal values (the ideal valve).
RIG_FRICTION = (100.0, 300.0, 1e-3)

#: Scale of the small random values of the remaining (state-like) inputs.
RANDOM_SCALE = {
    "qdot": 0.1, "qd1": 0.1, "qd2": 0.5, "qd3": 2.0, "v": 0.1, "w": 0.1, "a": 1.0,
    "u": 1e-3, "u_applied": 1e-3, "ldot": 0.05, "g0": 1.0, "z": 0.01,
}


def pose_offset(n: int) -> np.ndarray:
    """Offsets from the neutral pose (m or rad): every entry non-zero, away from symmetric poses."""
    k = np.arange(n)
    return 0.03 * np.sin(2.1 * k + 0.5)


class InputValues:
    """Plausible values of every generated function's inputs for the model of ``dyn``.

    The pose is the neutral pose plus :func:`pose_offset`; cylinder lengths follow from it;
    control pressures sit near half the supply pressure; θ and γ are the model's true values;
    a controller's gains, bounds, static inputs and initial state are what the simulator gives
    it (:func:`hydrogen.simulation.control.make_controller` with the true parameters).
    """

    def __init__(self, dyn):
        from hydrogen.controllers import function_name, rates_function_name, step_function_name
        from hydrogen.simulation.control import make_controller

        from hydrogen.plant import friction, plant_inputs

        self.dyn, self.model = dyn, dyn.model
        m = self.model
        self._plant_inputs = {i.name: np.array(i.ideal, float) for i in plant_inputs(m)}
        self._plant_inputs[friction.INPUT] = np.array(friction.row(*RIG_FRICTION)[:len(friction.input_parameters(m))])
        self.q = np.asarray(m.neutral_pose, float) + pose_offset(m.n)
        self.ctrl = {}
        for kind in m.controllers:  # the controllers the robot lists (those its build holds)
            self.ctrl[function_name(kind)] = make_controller(dyn, kind, None, m.theta, m.gamma)
            self.ctrl[rates_function_name(kind)] = self.ctrl[function_name(kind)]  # same inputs
            self.ctrl[step_function_name(kind)] = self.ctrl[function_name(kind)]  # same, then h and the bounds

    def value(self, fname: str, name: str, rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
        """Flat (column-major) values of input ``name`` (rows x cols) of function ``fname``."""
        from hydrogen.layout import NUMBERS
        from hydrogen.tree import cylinder_lengths

        m = self.model
        n, nc, size = m.n, m.n_cylinders, rows * cols
        small = lambda s=0.05, k=size: s * rng.uniform(-1.0, 1.0, k)  # noqa: E731
        ps = np.asarray(m.supply_pressure, float)
        pc = ps * (0.48 + 0.02 * rng.uniform(-1.0, 1.0, nc))
        q = self.q + small(0.005, n)
        ctrl = self.ctrl.get(fname)
        out = None
        if name in ("q", "qd0", "q_hat"):
            out = q
        elif name == "l":
            out = cylinder_lengths(m, q) + small(0.002, nc)
        elif name == "pc":
            out = pc
        elif name == "x":  # plant state [q, qdot, pc, spool, spool rate]
            out = np.concatenate([q, small(0.1, n), pc, small(1e-3, nc), small(1e-2, nc)])
        elif name == "xc" and ctrl is not None:
            ctrl.reset(q, small(RANDOM_SCALE["z"], n))
            out = ctrl.xc.copy()
        elif name in ("xc_lo", "xc_hi") and ctrl is not None:  # the projection bounds, as the loop passes them
            bound = ctrl.bounds[0 if name == "xc_lo" else 1]
            out = np.where(np.isfinite(bound), bound, -1e300 if name == "xc_lo" else 1e300)
        elif ctrl is not None and name in ctrl.values:
            out = np.asarray(ctrl.values[name], float).ravel(order="F")
        elif name == "theta":
            out = m.theta
        elif name == NUMBERS and self.dyn.numbers is not None:  # the description's, as the runtime passes them
            out = self.dyn.numbers
        elif name in ("gamma1", "gamma2"):
            out = m.gamma[0 if name == "gamma1" else 1]
        elif name in self._plant_inputs:  # a block's numbers, per actuator (hydrogen.plant.plant_inputs)
            out = np.tile(self._plant_inputs[name], m.n_cylinders)
        elif name in FIXED:
            out = FIXED[name]
        if out is None or np.size(out) != size:
            out = small(RANDOM_SCALE.get(name, 0.05))
        return np.array(out, float).ravel()

    def function_inputs(self, entry: dict, seed: int = 0) -> list:
        """[(name, flat column-major values)] for a manifest function entry (inputs [[name, rows, cols]])."""
        rng = np.random.default_rng(seed)
        return [(name, self.value(entry["name"], name, int(r), int(c), rng)) for name, r, c in entry["inputs"]]


# ---------------------------------------------------------------------------------------------
# robots and their scenarios
# ---------------------------------------------------------------------------------------------
def robots() -> list:
    """Every shipped robot's name (``hydrogen.models()``), the default model first."""
    import hydrogen
    from hydrogen.model import DEFAULT_MODEL

    names = list(hydrogen.models())
    return sorted(names, key=lambda x: (x != DEFAULT_MODEL, x))


#: The benchmarks' URDF-born robot: one leg of a hydraulic quadruped as a CAD export gives it (rpy
#: joint origins, full inertia tensors, fixed foot and sensor links; a rotary vane and two four-way
#: cylinders; nine adapted parameters), the kind of description users load. Its own numbers.
URDF_LEG = Path(__file__).resolve().parent / "data" / "urdf_leg.toml"


def _scenario_tables(model) -> list:
    from hydrogen.simulation.scenarios import scenario_names

    return [(name, model.scenarios[name]) for name in scenario_names(model)]


def sim_scenario(model) -> str:
    """The robot's simulation scenario: the first one of its description on the ideal plant
    (not ``rig = true``): paper-sim for the Stewart platform, arm-sim for the arm."""
    for name, table in _scenario_tables(model):
        if not table.get("rig", False):
            return name
    raise RuntimeError(f"model '{model.name}' has no simulation scenario (every scenario is on the rig)")


def rig_scenario(model) -> str | None:
    """The robot's first experiment-like scenario (``rig = true``), or None."""
    return next((name for name, table in _scenario_tables(model) if table.get("rig", False)), None)


def periods_per_s(dyn, scenario) -> float:
    """Control rate (Hz) of ``scenario``: a name of ``dyn``'s model or a Scenario."""
    from hydrogen.simulation.scenarios import scenario as named

    return (named(scenario, dyn.model) if isinstance(scenario, str) else scenario).control_rate


def c_loop_per_period(dyn, scenario: str, controller: str, n_periods: int) -> float:
    """Seconds per period of the C loop (no logs), over ``n_periods`` periods of ``scenario``."""
    import time

    from hydrogen.simulation import simulator as S

    rate = periods_per_s(dyn, scenario)
    p = S.prepare_run(dyn, scenario, controller, None, n_periods / rate, False, {})
    runner = S.make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    t0 = time.perf_counter()
    code = runner.run(p.n, p.noise, None)
    wall = time.perf_counter() - t0
    if code != 0:
        raise RuntimeError(f"the C loop of {dyn.model.name} {scenario} {controller} stopped with code {code}")
    return wall / p.n


# ---------------------------------------------------------------------------------------------
# machine, tools, subprocesses
# ---------------------------------------------------------------------------------------------
def cc_version(cc: str = "cc") -> str:
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30)
        return out.stdout.splitlines()[0] if out.stdout else "unknown"
    except OSError:
        return "unknown"


def cpu_name() -> str:
    name = platform.processor()
    if name and name not in ("x86_64", "aarch64", "arm64"):
        return name
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def machine_info(cc: str = "cc") -> dict:
    import casadi
    import sympy

    return {"processor": cpu_name(), "cpu_count": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version(), "numpy": np.__version__, "sympy": sympy.__version__,
            "casadi": casadi.__version__, "cc": cc_version(shutil.which(cc) or cc)}


def require_cc(cc: str = "cc") -> str:
    path = shutil.which(cc)
    if path is None:
        raise RuntimeError(f"C compiler '{cc}' not found on PATH")
    return path


def jinja_env():
    import jinja2

    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                              undefined=jinja2.StrictUndefined, trim_blocks=True,
                              lstrip_blocks=True, keep_trailing_newline=True)


def c_float(x: float) -> str:
    """A C double literal that round-trips ``x`` exactly."""
    r = repr(float(x))
    if r in ("inf", "-inf", "nan"):
        raise ValueError(f"non-finite value {r} cannot be a C literal")
    return r if any(ch in r for ch in ".eE") else r + ".0"


def python_env() -> dict:
    """Environment for a benchmark subprocess: this interpreter's hydrogen, unbuffered output."""
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    return env


#: The end of a benchmark subprocess's script that started its clock as ``t0`` (``time`` and ``resource``
#: imported) and built with ``progress=events.append``: its wall seconds inside, the build's generation
#: and compile seconds (0 where it only loaded), whether it generated, and its CPU seconds with its
#: compilers', as ``KEY value`` lines (:func:`parse_keyed`). Not a format string: append it as it is.
BUILD_REPORT = """
t1 = time.perf_counter()
stages = {}
for e in events:
    if e.stage in ("generated", "compiled"):
        stages.setdefault(e.stage, e.elapsed_s)
own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print("wall_in_s", t1 - t0)
print("generate_s", stages.get("generated", 0.0))
print("compile_s", stages.get("compiled", 0.0))
print("generated", int("generated" in stages))
print("cpu_s", own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime)
"""


def run_python(code: str, timeout: float = 600.0, env: dict | None = None,
               cwd: Path | None = None) -> tuple[str, float]:
    """Run ``code`` with this interpreter in a fresh process, in ``cwd`` (default: the repository,
    whose folder comes first on ``sys.path``); return (stdout, wall seconds)."""
    import time

    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=timeout, env=env or python_env(), cwd=str(cwd or REPO))
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed (exit {proc.returncode}):\n{code}\n"
                           f"--- stderr ---\n{proc.stderr.strip()}")
    return proc.stdout, wall


def parse_keyed(stdout: str) -> dict:
    """Lines ``KEY value`` (value a float) of a subprocess's output, as a dict."""
    out = {}
    for line in stdout.splitlines():
        parts = line.split()
        if len(parts) == 2:
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                pass
    return out


def median(values) -> float:
    return float(statistics.median(values))


def median_of_runs(runs: int, one, keys) -> tuple:
    """``(medians, results)``: ``one(i)`` for each of ``runs`` runs (a dict each), and the median of
    each of ``keys`` over them."""
    results = [one(i) for i in range(runs)]
    return {k: median(r[k] for r in results) for k in keys}, results


def seconds(key: str):
    """A :func:`print_rows` cell: the row's ``key`` in seconds, two decimals."""
    return lambda row: f"{row[key]:.2f}"


def print_rows(title: str, columns: list, rows: list, wall_s: float, checks: bool = False) -> None:
    """A benchmark's table: ``columns`` as ``(header, width, cell)`` with ``cell(row)`` the text
    (left-aligned where the header is, i.e. the label columns, when ``width`` is negative); with
    ``checks`` (the project's release checks) each row's ``target_s`` and whether ``within_target``."""
    if checks:
        columns = [*columns, ("target", 7, lambda r: "-" if r["target_s"] is None else f"{r['target_s']:.0f}"),
                   ("met", 4, lambda r: {True: "yes", False: "NO", None: "-"}[r["within_target"]])]
    align = lambda text, w: f"{text:<{-w}}" if w < 0 else f"{text:>{w}}"  # noqa: E731
    header = " ".join(align(h, w) for h, w, _ in columns)
    print(title)
    print(header)
    print("-" * len(header))
    for r in rows:
        print(" ".join(align(cell(r), w) for _, w, cell in columns))
    print(f"whole benchmark {wall_s:.1f} s")


def script_main(doc: str, run, print_table, argv=None, options: dict | None = None) -> int:
    """A benchmark module run as a script: ``--quick``, ``--json FILE`` (:func:`write_results`) and
    the module's own ``options`` ({flag: argparse keywords}; each passed to ``run`` by its name)."""
    import argparse

    from hydrogen.errors import HydrogenError

    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", type=Path, metavar="FILE")
    dests = [ap.add_argument(flag, **kw).dest for flag, kw in (options or {}).items()]
    a = ap.parse_args(argv)
    module = Path(sys.modules[run.__module__].__file__).stem
    if a.json:
        try:  # before minutes of benchmarks, not after
            _results_kind(a.json)
        except HydrogenError as exc:  # its one message, no traceback
            print(exc, file=sys.stderr)
            return 2
    r = run(quick=a.quick, **{d: getattr(a, d) for d in dests})
    print_table(r)
    if a.json:
        print(write_results(a.json, module, r))
    return 0


def _results_kind(path: Path) -> str:
    """"suite" when ``path`` holds ``hydrogen bench`` results (a JSON object of modules' sections), else
    "own" (no file there, or any other file: written whole, as a module's results always were). An
    OutputPathError when ``path`` is not a regular file, or the suite's page beside it is not bench's."""
    import json

    from hydrogen.bench import SUITE, check_results_file

    path = Path(path)
    if path.is_symlink() or (path.exists() and not path.is_file()):
        check_results_file(path)  # raises: not a regular file
    try:
        data = json.loads(path.read_text(encoding="utf-8")) if path.exists() else None
    except (OSError, UnicodeDecodeError, ValueError):
        data = None
    if not (isinstance(data, dict) and data and set(data) <= {n for n, _ in SUITE}):
        return "own"
    from hydrogen.pages import check_benchmarks_page

    check_benchmarks_page(path)
    return "suite"


def write_results(path: Path, module: str, results: dict) -> str:
    """Write ``results`` of benchmark ``module`` to ``path`` atomically: into its section when
    ``path`` holds ``hydrogen bench`` results (docs/bench.json: the other modules' sections kept,
    the page beside it rendered again), else as the whole file. What was written, for the log."""
    import json

    from hydrogen.fileio import atomic_write

    path = Path(path)
    if _results_kind(path) == "suite":
        from hydrogen.bench import merge_results
        from hydrogen.pages import write_benchmarks_page

        merge_results(path, {module: results})
        return f"results written to {path} (section {module}); page written to {write_benchmarks_page(path)}"
    atomic_write(path, json.dumps(results, indent=2, default=str) + "\n")
    return f"results written to {path}"


_GRAVITY = re.compile(r"^(gravity\s*=\s*)([0-9.eE+-]+)", re.M)


def copy_description(name: str, folder: Path, edit) -> Path:
    """A copy of robot ``name``'s description folder (its TOML and the files beside it, the URDF) in
    ``folder`` with its TOML text replaced by ``edit(text)``; the copy's TOML path."""
    import hydrogen

    toml = hydrogen.model.model_path(name)
    for p in toml.parent.iterdir():
        if p.is_file():
            shutil.copy(p, folder / p.name)
    (folder / toml.name).write_text(edit(toml.read_text()))
    return folder / toml.name


def copy_with_gravity(name: str, folder: Path, gravity) -> Path:
    """A copy of robot ``name``'s description folder in ``folder`` with its gravity replaced by
    ``gravity(old)`` (m/s²); the copy's TOML path. Every description has a gravity: the edit is generic."""
    def edit(text):
        if _GRAVITY.search(text) is None:
            raise RuntimeError(f"{name}: no 'gravity =' line to edit")
        return _GRAVITY.sub(lambda m: f"{m[1]}{float(gravity(float(m[2])))!r}", text, count=1)
    return copy_description(name, folder, edit)



def spread_line(ax, x, points, coord, colour, label, style="o-"):
    """One controller's median max error (line) and min-max band over seeds at the values ``x`` on
    ``ax``: ``points`` each with "median", "min", "max" by coordinate (None: every seed failed)."""
    med, lo, hi = ([p[s][coord] if p[s][coord] is not None else np.nan for p in points]
                   for s in ("median", "min", "max"))
    ax.plot(x, med, style, ms=3, color=colour, label=label)
    ax.fill_between(x, lo, hi, color=colour, alpha=0.15, lw=0)


def error_axes(ax, coord, title, xlabel):
    """A max-error panel's log scale, labels and grid."""
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"max error in {coord} (% of amplitude)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)


def save_figure(fig, axes, path, title, ncol, bottom):
    """The figure's legend (from its first panel), ``title``, and the PNG written atomically at ``path``."""
    import io

    import matplotlib.pyplot as plt

    from hydrogen.fileio import atomic_write

    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, bottom, 1, 1))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    atomic_write(Path(path), buf.getvalue())
    return path


def spread_point(summary, coordinates, **fields) -> dict:
    """One point of a study over seeds from a sweep entry's ``summary``: ``fields``, the failed and
    completed counts, and the max error (% of amplitude) of each of ``coordinates`` as "median", "min"
    and "max" over the seeds (None where no seed completed)."""
    point = {**fields, "failed": len(summary.get("failed", [])), "completed": summary.get("completed", 0)}
    for stat in ("median", "min", "max"):
        errs = (summary.get(stat) or {}).get("max_error_pct") or {}
        point[stat] = {k: errs.get(k) for k in coordinates}
    return point


def medians_cell(points, keys) -> str:
    """One cell of a study's table in docs/paper.md: ``a / b / c``, the median max error (%) of each
    ``(key, coordinate)`` of ``keys`` in ``points[key]`` (a :func:`spread_point`), ``fail`` where no seed
    completed, and how many runs diverged where some did."""
    out, failed, runs = [], 0, 0
    for key, coord in keys:
        p = points[key]
        med = p["median"][coord]
        out.append("fail" if med is None else f"{med:.1f}")
        failed, runs = failed + p["failed"], runs + p["failed"] + p["completed"]
    return " / ".join(out) + (f" ({failed} of {runs} runs diverge)" if failed else "")


def fraction_text(x: float) -> str:
    """A fraction of a period as a table writes it: 0, 1/4, 1/2, 1."""
    from fractions import Fraction
    return str(Fraction(x).limit_denominator(64))




def study_result(model, seeds, quick: bool, quick_duration: float, scenarios: dict, figure, start: float, **fields):
    """A study over seeds as a benchmark returns it: the robot, ``fields``, the seeds, whether quick (and
    its run duration), the rows by scenario, the figure's path (None when quick), cores and wall time."""
    return {"model": model.name, **fields, "seeds": list(seeds), "quick": quick,
            "duration_s": quick_duration if quick else None, "scenarios": scenarios,
            "figure": None if quick else figure.relative_to(REPO).as_posix(), "cores": os.cpu_count(),
            "wall_s": time.perf_counter() - start}


def merge_rows(old: list, new: list, key) -> list:
    """``new`` after the rows of ``old`` it does not redo (``key(row)`` not among ``new``'s keys), in
    ``old``'s order: a study run for some robots or controllers updates its file, keeping the rest."""
    ran = {key(r) for r in new}
    return [r for r in old if key(r) not in ran] + list(new)


def merge_study(old: dict | None, new: dict) -> dict:
    """A study file by robot (``{"seeds", "models": {robot: {"rows", "wall_s"}}}``, rows keyed by scenario
    and controller) updated by ``new``: the rows of ``old`` that ``new`` did not redo are kept, when
    both ran on the same seeds (else ``new`` alone). A robot's wall time sums the runs its rows came from."""
    import json

    if not old or old.get("seeds") != new["seeds"]:
        return new
    out = json.loads(json.dumps(old))
    for model, d in new["models"].items():
        before = out["models"].get(model, {"rows": [], "wall_s": 0.0})
        rows = merge_rows(before["rows"], d["rows"], lambda r: (r["scenario"], r["controller"]))
        kept = len(rows) > len(d["rows"])
        out["models"][model] = {**before, **d, "rows": rows,
                                "wall_s": d["wall_s"] + (before.get("wall_s", 0.0) if kept else 0.0)}
    return {**out, **{k: v for k, v in new.items() if k != "models"}}


def json_study_main(doc: str, collect, markdown, default_json: Path, argv=None, options=None) -> int:
    """A study script's command line: ``--workers`` (default 2), ``--json`` (default ``default_json``) and
    ``options`` ({flag: argparse keywords}, passed to ``collect`` by their dest); runs
    ``collect(workers=..., ...)``, writes its data as sorted JSON atomically and prints ``markdown`` of it."""
    import argparse
    import json

    from hydrogen.fileio import atomic_write

    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--json", default=str(default_json), help=f"output (default {default_json.relative_to(REPO)})")
    dests = [ap.add_argument(flag, **kw).dest for flag, kw in (options or {}).items()]
    args = ap.parse_args(argv)
    data = collect(workers=args.workers, **{d: getattr(args, d) for d in dests})
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    atomic_write(Path(args.json), text)
    print(markdown(json.loads(text)))
    print(f"written to {args.json}")
    return 0
