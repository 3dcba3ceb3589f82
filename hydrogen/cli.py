"""Command line of hydrogen: generate, simulate, identify, figures, bench, tune, tune-p, margins, export.

Errors that hydrogen raises on purpose are printed as one message (no
traceback) and exit with status 2; ``--check`` exits 1 when generated code is stale.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np
from pathlib import Path

from .errors import DescriptionNote, HydrogenError

__all__ = ["main"]


def _default_generated(model, shipped: Path) -> Path:
    """Where ``generate`` writes without --out: a shipped robot's committed folder (``shipped``/<name>),
    else ``generated/<name>`` beside the user's description (never inside the installed package)."""
    from .model import is_shipped

    if is_shipped(model):
        return shipped / model.name
    return Path(model.source).resolve().parent / "generated" / model.name


def _in_installed_package(folder: Path) -> bool:
    """Whether ``folder`` lies inside the installed package (a wheel's ``hydrogen/_generated``), not a
    source checkout's ``generated/``."""
    from .resources import package_dir

    return Path(folder).resolve().is_relative_to(package_dir())


def _cmd_generate(args) -> int:
    from .codegen.generate import check_output, generate
    from .model import load_model
    from .runtime.build import repo_generated_dir

    model = load_model(args.model)
    out = Path(args.out) if args.out else _default_generated(model, repo_generated_dir())
    if not args.check and _in_installed_package(out):  # never written to, not even its lock file
        if args.force or check_output(model, out, args.numbers):
            from .errors import OutputPathError
            raise OutputPathError(f"{out} is the installed package's own generated code for {model.name}, which "
                                  "generate never rewrites: write a copy elsewhere with --out DIR (a build "
                                  "generates into its cache by itself)")
        print(f"{out}: up to date")
        return 0
    if args.check:
        reasons = check_output(model, out, args.numbers)
        if reasons:
            print(f"generated code in {out} is stale:", *reasons, sep="\n  ", file=sys.stderr)
            print("run 'hydrogen generate' to regenerate", file=sys.stderr)
            return 1
        print(f"{out}: up to date")
        return 0
    from .progress import Reporter, print_event
    from .runtime.build import generation_reported
    with generation_reported(Reporter(None if args.quiet else print_event, model.name), model, out, args.force,
                             numbers=args.numbers) as whole:
        changed = generate(model, out, force=args.force, progress=not args.quiet, whole=whole,
                           **({} if args.numbers is None else {"numbers": args.numbers}))
    print(f"{out}: {'generated' if changed else 'up to date, nothing regenerated'}")
    return 0


def _model_files(model) -> list:
    """The files a loaded description was read from, as ``(what, path)`` inputs of a command (its TOML and
    the URDF it names, if any): no output may replace them."""
    return [("robot description", getattr(model, "source", None)), ("URDF", getattr(model, "urdf", None))]


def _cmd_simulate(args) -> int:
    import hydrogen

    from .errors import SimulationError
    from .outputs import check_distinct, check_output_file, check_plot_path
    from .simulation.checks import check_run_size
    from .simulation.scenarios import default_scenario_name, scenario as named_scenario
    from .progress import print_event
    from .summary import error_lines, estimate_lines, excitation_lines, saturation_lines

    # Everything that can be refused is refused before the run: outputs, then the run's size.
    if args.json:
        check_output_file(args.json, "--json")
    if args.plot:
        check_plot_path(args.plot, "--plot")
    if args.log:
        check_output_file(args.log, "--log")
    model = hydrogen.load_model(args.model)
    check_distinct([("--json", args.json), ("--plot", args.plot), ("--log", args.log)], _model_files(model))
    args.scenario = args.scenario or default_scenario_name(model)
    sc = named_scenario(args.scenario, model)
    if args.duration is not None:
        sc = sc.with_overrides(duration=args.duration)
    check_run_size(sc, model, args.controller)
    if args.seeds is not None and args.log:
        raise HydrogenError("--log writes one run's log and --seeds runs several; run the seed you want "
                            "alone (the scenario's seed) to log it")
    # Built apart from the run, so the summary tells the two times apart (stages on stderr).
    events = []
    # one run after a structural edit: what is not compiled yet compiles quickly (-O0) for it
    dyn = hydrogen.build(model, progress=lambda e: (events.append(e), print_event(e)),
                         controllers=(args.controller,), gains={args.controller: sc.gains.get(args.controller)},
                         quick=args.seeds is None and not args.optimized, **_build_options(args))
    if args.seeds is not None:
        return _simulate_seeds(args, model, dyn, events)
    try:
        res = hydrogen.simulate(args.scenario, args.controller, model=model, dyn=dyn, duration=args.duration)
    except SimulationError as exc:
        if exc.result is not None and len(exc.result.t):
            _write_outputs(args, exc.result, diverged=str(exc))
        raise
    m = res.metrics
    last = events[-1] if events else None
    if last is not None and last.stage == "built":
        print(f"built in {last.elapsed_s:.1f} s ({last.detail})")
    slow = dyn.library.unoptimized()
    if slow:
        print(f"note: this run's {', '.join(slow)} librar{'ies' if len(slow) > 1 else 'y'} compiled unoptimized "
              "(-O0: the same numbers, slower per period); the optimized build finishes in the background for "
              "the next run (--optimized waits for it)")
    print(f"scenario {res.scenario_name}, controller {res.controller}: {m['sim_time_s']:.2f} s simulated "
          f"in {m['wall_time_s'] * 1e3:.1f} ms ({m['sim_time_s'] / max(m['wall_time_s'], 1e-9):.0f}x real time; "
          f"the C loop {m['loop_wall_s'] * 1e3:.1f} ms, the rest setup)")
    if m.get("metric_note"):
        print(f"note: {m['metric_note']}")
    print(f"max tracking error over t >= {m['metric_start_s']} s (% of reference amplitude, absolute; "
          f"'-': the reference does not move that coordinate):")
    for line in error_lines(res.coordinates, res.units, m["max_error"], m["max_error_pct"]):
        print(line)
    for line in saturation_lines(res) + estimate_lines(res) + excitation_lines(res):
        print(line)
    _write_outputs(args, res)
    return 0


def _simulate_seeds(args, model, dyn, events) -> int:
    """``simulate --seeds``: one run per seed over the pool; median and range per coordinate. A seed
    that diverged is named after the summary of the others (exit status 2)."""
    import json
    import time

    import hydrogen
    from .errors import SimulationError
    from .fileio import atomic_write
    from .summary import seed_error_lines

    start = time.perf_counter()
    res = hydrogen.simulate(args.scenario, args.controller, model=model, dyn=dyn, duration=args.duration,
                            seeds=args.seeds, max_workers=args.workers)
    wall = time.perf_counter() - start
    m = res.metrics
    last = events[-1] if events else None
    if last is not None and last.stage == "built":
        print(f"built in {last.elapsed_s:.1f} s ({last.detail})")
    seeds = res.seeds
    names = f"{seeds[0]}..{seeds[-1]}" if seeds == list(range(seeds[0], seeds[0] + len(seeds))) else ",".join(map(str, seeds))
    if m["completed"]:
        print(f"scenario {res.scenario_name}, controller {res.controller}: {len(seeds)} noise seeds ({names}), "
              f"{m['median']['sim_time_s']:.2f} s simulated each, in {wall:.1f} s")
        print(f"max tracking error over t >= {m['median']['metric_start_s']} s (% of reference amplitude: "
              f"median and range over the {m['completed']} completed seeds; '-': the reference does not move "
              f"that coordinate):")
        for line in seed_error_lines(res.coordinates, res.units, m):
            print(line)
        print(f"median run: seed {m['median_seed']}")
    if args.json:
        atomic_write(Path(args.json), json.dumps(m, indent=2, sort_keys=True, default=float) + "\n")
        print(f"metrics over the seeds written to {args.json}")
    if args.plot and m["completed"]:
        from .figures import plot_tracking_errors
        plot_tracking_errors(res, Path(args.plot))
        print(f"figure written to {args.plot} (the median run and the band of the seeds)")
    if res.failures:
        raise SimulationError(f"{len(res.failures)} of {len(seeds)} seeds diverged: "
                              + "; ".join(f"seed {s}: {e}" for s, e in res.failures.items()))
    return 0


def _write_outputs(args, res, diverged=None) -> None:
    """--json and --plot of ``res``; a run that diverged is written as far as it went, marked
    ``"diverged": true`` with the message."""
    import json

    from .fileio import atomic_write

    if args.json:
        metrics = dict(res.metrics or (res.compute_metrics() if len(res.t) else {}))
        metrics["diverged"] = diverged is not None
        if diverged is not None:
            metrics["error"] = diverged
        atomic_write(Path(args.json), json.dumps(metrics, indent=2, sort_keys=True) + "\n")
        print(f"metrics written to {args.json}" + (" (diverged run, as far as it went)" if diverged else ""))
    if args.plot:
        from .figures import plot_tracking_errors
        plot_tracking_errors(res, Path(args.plot))
        print(f"figure written to {args.plot}" + (" (diverged run, as far as it went)" if diverged else ""))
    if args.log:
        res.save_log(Path(args.log), noise_l=args.log_noise_l, noise_p=args.log_noise_p, seed=args.log_seed)
        print(f"log written to {args.log} ({len(res.t)} samples; sensor noise added: cylinder lengths "
              f"{args.log_noise_l:g} m, pressures {args.log_noise_p:g} Pa)")


def _cmd_identify(args) -> int:
    import json

    import hydrogen
    from .fileio import atomic_write
    from .outputs import check_distinct, check_output_file

    model = hydrogen.load_model(args.model) if args.model else None  # read once: its notes shown once
    if args.json:
        check_output_file(args.json, "--json")
        inputs = [("log", args.log)] + (_model_files(model) if model is not None else [])
        check_distinct([("--json", args.json)], inputs)
    res = hydrogen.identify(Path(args.log), model=model, cutoff_hz=args.cutoff,
                            zoh_correction=args.zoh_correction, friction=args.friction,
                            friction_speed=args.friction_speed, **_build_options(args))
    print(res.summary())
    if args.json:
        atomic_write(Path(args.json), json.dumps(res.to_dict(), indent=2, sort_keys=True) + "\n")
        print(f"results written to {args.json}")
    return 0


def _cmd_figures(args) -> int:
    import hydrogen
    from .figures import make_all
    from .outputs import check_output_dir

    check_output_dir(args.out, "figures --out")
    paths = make_all(hydrogen.build(hydrogen.load_model(args.model), **_build_options(args)), Path(args.out),
                     quiet=args.quiet, seeds=args.seeds)
    for name, path in paths.items():
        print(f"{name}: {path}")
    return 0


def _cmd_export(args) -> int:
    import hydrogen
    from .export import export
    from .progress import print_event
    from .simulation.scenarios import default_scenario_name

    if args.format == "fmu":
        return _cmd_export_fmu(args)
    if args.part is not None or args.step is not None:
        raise HydrogenError("--part and --step are options of --format fmu")
    model = hydrogen.load_model(args.model)
    args.scenario = args.scenario or default_scenario_name(model)
    out = export(Path(args.out), args.scenario, args.controller, model=model, duration=args.duration,
                 progress=print_event, **_build_options(args))
    print(f"{out}: {args.controller} on {args.scenario}; build and run with 'make -C {out} run'")
    return 0


def _cmd_export_fmu(args) -> int:
    import hydrogen
    from .errors import FmuError
    from .fmu import PARTS, export_fmu
    from .progress import print_event
    from .simulation.scenarios import default_scenario_name

    if args.part is None:
        raise FmuError(f"--format fmu needs --part: one of {', '.join(PARTS)}")
    model = hydrogen.load_model(args.model)
    args.scenario = args.scenario or default_scenario_name(model)
    out = export_fmu(Path(args.out), args.part, args.scenario, args.controller, model=model, duration=args.duration,
                     step=args.step, progress=print_event, **_build_options(args))
    what = "plant" if args.part == "plant" else f"{args.part} ({args.controller})"
    print(f"{out}: FMI 2.0 co-simulation FMU of the {what} on {args.scenario}; check it with "
          f"'python -m fmpy validate {out}'")
    return 0


def _cmd_tune(args, controller=None) -> int:
    from .simulation.tuning import PER_OCTAVE, default_grid, tune

    controller = controller or args.controller
    if args.min is not None and args.max is not None and args.min >= args.max:
        raise HydrogenError(f"--min ({args.min:g}) must be below --max ({args.max:g})")
    grid = None
    if args.n is not None or args.min is not None or args.max is not None:
        d = default_grid(controller)
        lo, hi = args.min if args.min is not None else d[0], args.max if args.max is not None else d[-1]
        if lo >= hi:
            raise HydrogenError(f"--min ({lo:g}) must be below --max ({hi:g})")
        # without --n, the documented density (PER_OCTAVE points per octave) over --min .. --max
        n = args.n if args.n is not None else max(int(round(PER_OCTAVE * np.log2(hi / lo))) + 1, 2)
        grid = np.geomspace(lo, hi, n)
    res = tune(controller, grid, model=args.model, max_workers=args.workers, progress=not args.quiet,
               seeds=args.seeds, variant=args.variant, margin=args.margin, **_build_options(args))
    name = res["main_gain"]
    print(f"{controller} on model {res['model']}: main gain {name}; every point over {len(res['seeds'])} noise "
          f"seeds (stable: on every seed; max err: median [min - max] over the seeds)")
    sec = list(res["secondary"]) + list(res["adaptation"])
    print(f"{'scenario':12} {name:>9} " + "".join(f"{k:>8} " for k in sec) + f"{'max err %':>10} {'range %':>15} "
          f"{'hf err %':>9} {'sat':>6}  stable")
    for r in res["table"]:
        head = f"{r['scenario']:12} {r['gain']:9.4g} " + "".join(
            f"{r[k]:8.4g} " if k in r else f"{'':8} " for k in sec)
        if "max_error_pct" in r:
            lo, hi = r["max_error_range"]
            print(head + f"{r['max_error_pct']:10.2f} {f'[{lo:.2f} - {hi:.2f}]':>15} {100 * r['hf_error']:9.3f} "
                  f"{r['saturation']:6.3f}  {'yes' if r['stable'] else 'no: ' + r['reason']}")
        else:
            print(head + r["reason"][:70])
    print(f"largest gain stable on every scenario (at the tuned {', '.join(sec) or 'point'}): "
          f"{name} = {res['largest_stable']}")
    if res["best"] is None:
        print("no point of the grid completes every scenario without saturating")
        return 0
    if not res["grid_spans_margin"]:
        print(f"NO gain of the grid can show a gain margin of {res['margin']:.3g}: it spans a factor of "
              f"{res['grid'][-1] / res['grid'][0]:.3g} (widen --min / --max); the least bad point follows")
    elif not res["margin_ok"]:
        print(f"NO gain of the grid has a gain margin of {res['margin']:.3g} on every scenario (the loop rings at "
              "every gain); the least bad point (smallest worst-case error without saturation) follows")
    what = (f"smallest worst-case error with a gain margin >= {res['margin']:.3g}" if res["margin_ok"]
            else f"least bad, margin < {res['margin']:.3g}")
    print(f"tuned ({what}): {name} = {res['best']:.6g} "
          + "".join(f", {k} = {v:.6g}" for k, v in res["best_secondary"].items()) + "; errors (median [range]) "
          + ", ".join(f"{s} {v:.2f} % [{res['best_error_ranges'][s][0]:.2f} - {res['best_error_ranges'][s][1]:.2f}]"
                      for s, v in res["best_errors"].items() if v is not None))
    g = res["best_gains"]
    print(f"[gains.{controller}]")
    for k, v in g.items():
        print(f"{k} = {_toml_number(v)}")
    rest = {k: v for k, v in res["gains_used"].items() if k not in g}
    if rest:  # pinning these too keeps the point when the robot's own gains change later
        print(f"# the rest of the set the search ran with ({'the variant' if args.variant else 'the robot'}'s gains):")
        for k, v in rest.items():
            if np.isnan(np.asarray(v, float)).any():  # a default the run derives from the others (e.g. K_o)
                print(f"# {k}: derived from the other gains at each run (leave it out)")
            else:
                print(f"# {k} = {_toml_number(v)}")
    return 0


def _toml_number(v) -> str:
    """A gain (a number or a list) as TOML, six significant digits: 4e-09 stays 4e-09, not 0.0."""
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_number(x) for x in v) + "]"
    text = f"{float(v):.6g}"
    return text if any(c in text for c in ".en") else text + ".0"  # a float, as TOML reads it back


def _cmd_tune_p(args) -> int:
    from .controllers import baseline
    return _cmd_tune(args, baseline())


def _cmd_margins(args) -> int:
    from .simulation.tuning import margins

    res = margins(args.controller or None, model=args.model, max_workers=args.workers, progress=not args.quiet,
                  seeds=args.seeds, variant=args.variant, **_build_options(args))
    n = len(res["seeds"])
    print(f"stability margins on model {res['model']}: factor by which the main gain can grow while stable on "
          f"every one of {n} noise seeds; max error at the robot's gains: median [min - max] over the seeds")
    print("| controller | scenario | main gain | value | max error % (median [range]) | margin | "
          "first unstable because |")
    print("|---|---|---|---|---|---|---|")
    for r in res["rows"]:
        m = f">= {r['margin']:.3g}" if r["margin_capped"] else f"{r['margin']:.3g}"
        err = ", ".join(f"{c} {e['median']:.1f} [{e['min']:.1f} - {e['max']:.1f}]" for c, e in r["errors"].items())
        print(f"| {r['controller']} | {r['scenario']} | {r['main_gain']} | {r['gain']:.4g} | {err or '-'} | {m} | "
              f"{r['limit_reason'] or '-'} |")
    ends = [r for r in res["rows"] if r.get("estimates")]
    if ends:
        print("final estimate errors at the robot's gains (median over the seeds of the largest, % of the true "
              "value) and estimates that end a run at a projection bound:")
        for r in ends:
            e = r["estimates"]
            print(f"  {r['controller']} {r['scenario']}: theta {e['theta_error_pct']:.1f} %, gamma "
                  f"{e['gamma_error_pct']:.1f} %; at a bound: {', '.join(e['at_bound']) or 'none'}")
    return 0


def _cmd_bench(args) -> int:
    from .bench import run_suite
    if args.json:
        from .outputs import check_output_file
        check_output_file(args.json, "--json")
    run_suite(quick=args.quick, json_path=args.json, only=args.only, progress=not args.quiet,
              release_checks=args.release_checks)
    return 0




def _number(kind, low=None, strict=True, high=None):
    """An argparse type: a finite ``kind`` (> low, or >= low unless strict; <= high), refused with
    a message naming the value (argparse names the argument and exits with status 2)."""
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if kind is int else 'a number'}")
        if value != value or value in (float("inf"), float("-inf")):
            raise argparse.ArgumentTypeError(f"{text!r} must be finite")
        if low is not None and (value <= low if strict else value < low):
            raise argparse.ArgumentTypeError(f"{text!r} must be {'>' if strict else '>='} {low:g}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"{text!r} must be <= {high:g}")
        return value
    parse.__name__ = kind.__name__  # argparse's "invalid int value" wording
    return parse


def _add_build_options(sp) -> None:
    """The options of every command that builds the model: ``--numbers``."""
    from .codegen.generate import DEFAULT_NUMBERS, NUMBERS_MODES
    sp.add_argument("--numbers", choices=NUMBERS_MODES, default=DEFAULT_NUMBERS,
                    help=f"build with the description's numbers as inputs of the generated functions (one "
                         f"library serves every edit of numbers) or folded as constants (a library per set of "
                         f"numbers; default: {DEFAULT_NUMBERS})")


def _build_options(args) -> dict:
    """The keywords of :func:`hydrogen.build` that :func:`_add_build_options` added, from ``args``."""
    return {"numbers": args.numbers}


def _md_text(text: str) -> str:
    """Help text as Markdown table-cell text: <...> and & as entities (a browser would take <scenario>
    for a tag and hide it), | escaped, one line."""
    return (text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("|", "\\|")
            .replace("\n", " "))


def reference_markdown() -> str:
    """Markdown: every subcommand with each of its arguments (name, default, meaning), read off
    :func:`build_parser` (the documentation's command-line reference is this, so it cannot go stale)."""
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    helps = {c.dest: c.help for c in subs._choices_actions}  # noqa: SLF001 - argparse keeps them only there
    out = []
    for name, sp in subs.choices.items():
        out += [f"### hydrogen {name}", "", _md_text((sp.description or helps.get(name) or "").strip()), "",
                "| argument | default | meaning |", "|---|---|---|"]
        for a in sp._actions:  # noqa: SLF001 - argparse's own list of the parser's arguments
            if isinstance(a, argparse._HelpAction):  # noqa: SLF001
                continue
            arg = ", ".join(a.option_strings) or a.dest
            if a.choices and not isinstance(a.choices, dict):
                arg += " {" + ",".join(map(str, a.choices)) + "}"
            if a.required and a.option_strings:
                default = "required"
            elif a.default is None or a.default is False or a.default == argparse.SUPPRESS:
                default = "–"
            else:
                default = f"`{a.default}`"
            meaning = _md_text(a.help or "")
            out.append(f"| `{arg}` | {default} | {meaning} |")
        out.append("")
    return "\n".join(out)


def build_parser() -> argparse.ArgumentParser:
    from .codegen.generate import DEFAULT_NUMBERS, NUMBERS_MODES
    parser = argparse.ArgumentParser(prog="hydrogen", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("generate", help="derive the model and write its C into generated/",
                       description="Derive the model symbolically and write C, headers and a manifest.")
    g.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
    g.add_argument("--out", help="output folder (default: a shipped robot's generated/<model name> of the package; "
                                 "for your own description, generated/<model name> beside it)")
    g.add_argument("--check", action="store_true", help="exit 1 if the folder is stale; write nothing")
    g.add_argument("--force", action="store_true", help="regenerate even when up to date")
    g.add_argument("--numbers", choices=NUMBERS_MODES, default=None,
                   help=f"the description's numbers as inputs of the generated functions (one library serves "
                        f"every edit of numbers) or folded as constants (default: {DEFAULT_NUMBERS}; with "
                        "--check: the folder's own)")
    g.add_argument("--quiet", action="store_true", help="no progress bar")
    g.set_defaults(func=_cmd_generate)
    from .controllers import CONTROLLERS
    from .simulation.seeds import DEFAULT_SEEDS, parse_seeds
    from .simulation.tuning import HEADROOM, MARGIN
    sim = sub.add_parser("simulate", help="run a scenario in closed loop and print its metrics",
                         description="Simulate a scenario of the model's description with one controller.")
    sim.add_argument("--scenario", help="a scenario of the model, or <scenario>.<variant> for one of its [variants] "
                     "(default: the model's first)")
    sim.add_argument("--controller", default="adaptive-robust", choices=CONTROLLERS,
                     help="the controller run (one the model's description lists)")
    sim.add_argument("--duration", type=_number(float, 0), help="simulated time, s (default: the scenario's)")
    sim.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
    sim.add_argument("--json", help="write the metrics as JSON to this file")
    sim.add_argument("--plot", help="write the tracking-error figure to this file; the extension names the "
                                    "format (.png, .pdf, .svg, ...)")
    sim.add_argument("--log", help="write the run as a rig log CSV (t, l*, pc*, ps0 with a pump, u*, q*, a rig part's outputs) for "
                     "'hydrogen identify'")
    sim.add_argument("--log-noise-l", type=_number(float, 0, strict=False), default=5e-6,
                     help="std of the white noise added to the logged cylinder lengths, m (default: 5e-6)")
    sim.add_argument("--log-noise-p", type=_number(float, 0, strict=False), default=2e4,
                     help="std of the white noise added to the logged pressures, Pa (default: 2e4)")
    sim.add_argument("--log-seed", type=_number(int, 0, strict=False), default=0, help="seed of that noise (>= 0; default 0)")
    sim.add_argument("--seeds", type=parse_seeds, metavar="N|LIST",
                     help="run once per sensor-noise seed and print the median and range per coordinate: N for "
                          "seeds 0..N-1, or a list such as 0,3,7 (default: one run, the scenario's seed)")
    sim.add_argument("--workers", type=_number(int, 1, strict=False),
                     help="with --seeds: processes (default: the core count)")
    sim.add_argument("--optimized", action="store_true",
                     help="compile what is not built yet optimized before the run (as --seeds always does); "
                          "without it one run compiles it at -O0 (with the default compiler flags: the same "
                          "numbers, quicker to compile, each call slower) and the optimized compile finishes in the "
                          "background for the next run")
    _add_build_options(sim)
    sim.set_defaults(func=_cmd_simulate)
    ident = sub.add_parser("identify", help="estimate theta (and gamma) by least squares from a rig log CSV",
                           description="Least-squares identification of the rigid-body parameters theta and the "
                                       "hydraulic parameters gamma from measured leg lengths, pressures and spool "
                                       "commands (columns t, l0.., pc0.., u0..; see docs/guide/identification.md).")
    ident.add_argument("log", help="log CSV file")
    ident.add_argument("--json", help="write the estimates, standard errors and conditioning as JSON to this file")
    ident.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
    ident.add_argument("--cutoff", type=_number(float, 0), help="low-pass cutoff for theta, Hz (default: from the trajectory)")
    ident.add_argument("--zoh-correction", action="store_true",
                       help="pressures sampled where the held spool command changes, ideal valve (hydrogen's "
                            "paper-sim): correct for the pressure's curve within the period")
    ident.add_argument("--friction", action="store_true",
                       help="also fit each actuator's Coulomb and viscous friction with theta (F_c tanh(v/v_s) + b v)")
    ident.add_argument("--friction-speed", type=_number(float, 0), default=1e-3, metavar="V_S",
                       help="the friction's smoothing speed v_s, m/s or rad/s (default 1e-3, the rig's)")
    _add_build_options(ident)
    ident.set_defaults(func=_cmd_identify)
    fig = sub.add_parser("figures", help="run every scenario and write the paper's figures and table",
                         description="Counterparts of Figs. 2, 3, 5-8 (PNG) and the comparison table (Markdown).")
    fig.add_argument("--out", default="figures", help="output folder (default: ./figures)")
    fig.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
    fig.add_argument("--quiet", action="store_true", help="no progress bar")
    fig.add_argument("--seeds", type=parse_seeds, metavar="N|LIST",
                     help=f"sensor-noise seeds of the rig scenarios: the figures show the median run and the band "
                          f"of the seeds, the table median and range (N: seeds 0..N-1, or a list such as 0,3,7; "
                          f"default: {DEFAULT_SEEDS})")
    _add_build_options(fig)
    fig.set_defaults(func=_cmd_figures)
    b = sub.add_parser("bench", help="run the benchmark suite (per-step cost, build times)",
                       description="Per-period cost of the loop through four routes, C cost of each function, "
                                   "generation and compile times, in one run.")
    b.add_argument("--quick", action="store_true", help="fewer repeats and smaller sizes (a smoke run; its figures are noisier)")
    b.add_argument("--json", help="write all results as JSON to this file")
    from .bench import SUITE
    b.add_argument("--only", nargs="*", choices=[n for n, _ in SUITE], metavar="MODULE",
                   help="run only these modules: " + ", ".join(n for n, _ in SUITE))
    b.add_argument("--quiet", action="store_true", help="no progress bar")
    b.add_argument("--release-checks", action="store_true",
                   help="for hydrogen's developers: also check the project's release targets (bounds against "
                        "the previous release, generation-time targets) and say which hold")
    b.set_defaults(func=_cmd_bench)
    def seeds_arg(sp):
        sp.add_argument("--seeds", type=parse_seeds, metavar="N|LIST",
                        help=f"sensor-noise seeds every gain is judged over (stable: on all of them): N for seeds "
                             f"0..N-1 or a list such as 0,3,7 (default: {DEFAULT_SEEDS})")
        sp.add_argument("--variant", help="the rig scenarios at this [variants.<name>] of the description "
                                          "(run as <scenario>.<variant>; default: as the scenarios are)")

    def tune_args(sp):
        sp.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
        sp.add_argument("--min", type=_number(float, 0), help="smallest gain of the grid (> 0; default: documented)")
        sp.add_argument("--max", type=_number(float, 0), help="largest gain of the grid (> --min)")
        sp.add_argument("--n", type=_number(int, 2, strict=False), default=None,
                        help="grid size, at least 2: --min to --max (default: the documented grid, 4 points per "
                             "octave)")
        sp.add_argument("--margin", type=_number(float, 1, strict=False), default=MARGIN,
                        help=f"gain margin a tuned point holds on the grid (default {MARGIN:g}; {HEADROOM:.3g}, the "
                             "next grid point, gives room for seeds the search never saw)")
        sp.add_argument("--workers", type=_number(int, 1, strict=False), help="processes (default: the core count)")
        sp.add_argument("--quiet", action="store_true", help="no progress bar")
        seeds_arg(sp)
        _add_build_options(sp)

    tn = sub.add_parser("tune", help="the documented gain search for a controller on the model's rig (parallel sweep)",
                        description="Sweep a controller's main gain on the model's rig scenarios; pick the gain with "
                                    "the smallest error whose double (--margin) is still stable (hydrogen/simulation/tuning.py).")
    tn.add_argument("--controller", required=True, choices=CONTROLLERS)
    tune_args(tn)
    tn.set_defaults(func=_cmd_tune)
    tp = sub.add_parser("tune-p", help="hydrogen tune --controller p",
                        description="The documented search for the P controller (hydrogen tune --controller p).")
    tune_args(tp)
    tp.set_defaults(func=_cmd_tune_p)
    mg = sub.add_parser("margins", help="stability margin of each controller's main gain on the rig scenarios",
                        description="For each controller and rig scenario, the factor by which the main gain of the "
                                    "robot's gains can grow before the loop goes unstable (bisection over sweeps).")
    mg.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
    mg.add_argument("--controller", nargs="*", choices=CONTROLLERS, help="controllers (default: all)")
    mg.add_argument("--workers", type=_number(int, 1, strict=False), help="processes (default: the core count)")
    mg.add_argument("--quiet", action="store_true", help="no progress bar")
    seeds_arg(mg)
    _add_build_options(mg)
    mg.set_defaults(func=_cmd_margins)
    ex = sub.add_parser("export", help="write deployable C (sources, params.h, main.c, Makefile) or an FMU",
                        description="A folder that builds with only a C compiler and runs one scenario's "
                                    "closed loop, printing the tracking error; or (--format fmu) an FMI 2.0 "
                                    "co-simulation FMU of the plant, a controller or the closed loop.")
    ex.add_argument("--out", required=True, help="output folder (replaced if it holds an earlier export); with "
                                                 "--format fmu, a .fmu file (replaced if it is an earlier FMU hydrogen wrote)")
    ex.add_argument("--format", choices=("c", "fmu"), default="c",
                    help="c: a C99 folder with main.c and a Makefile (default); fmu: an FMI 2.0 co-simulation FMU")
    ex.add_argument("--part", help="with --format fmu: plant, controller or closed-loop")
    ex.add_argument("--step", type=_number(float, 0),
                    help="with --format fmu: the FMU's default communication step, s, a whole number of control "
                         "periods (default: one period)")
    ex.add_argument("--scenario", help="a scenario of the model (default: the model's first)")
    ex.add_argument("--controller", default="adaptive-robust", choices=CONTROLLERS)
    ex.add_argument("--duration", type=_number(float, 0), help="simulated time, s (default: the scenario's)")
    ex.add_argument("--model", help="built-in model name (hydrogen.models()) or TOML file (default: ubc_stewart)")
    _add_build_options(ex)
    ex.set_defaults(func=_cmd_export)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """hydrogen's own warnings as one line each (no source line): notes and fallbacks, not faults."""
    print(f"hydrogen: {'note' if issubclass(category, DescriptionNote) else 'warning'}: {message}",
          file=file or sys.stderr)


def main(argv=None) -> int:
    import warnings

    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        return args.func(args)
    except HydrogenError as exc:
        print(f"hydrogen {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file or folder the system refused: one message naming it
        print(f"hydrogen {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's status for SIGINT; files are written whole or not
        print(f"hydrogen {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
