"""The documentation: docstrings of the public API, the README's links, the pages the runs write,
and the description reference rendered from the loader's own definitions."""
from __future__ import annotations

import functools
import importlib
import importlib.util
import inspect
import json
import re
from pathlib import Path

import pytest

import hydrogen
from hydrogen import pages, schema

ROOT = Path(__file__).resolve().parents[1]

#: The modules whose reference pages the site builds (docs/api/<module>.md, ``::: <module>``).
DOCUMENTED = ("hydrogen", "hydrogen.dynamics", "hydrogen.model", "hydrogen.simulation.simulator",
              "hydrogen.simulation.scenarios", "hydrogen.simulation.sweep", "hydrogen.simulation.tuning",
              "hydrogen.identification", "hydrogen.logs", "hydrogen.export", "hydrogen.fmu", "hydrogen.figures",
              "hydrogen.pages", "hydrogen.schema", "hydrogen.errors")


def _undocumented(module_name: str) -> list:
    mod = importlib.import_module(module_name)
    missing = [] if (mod.__doc__ or "").strip() else [module_name]
    for name in getattr(mod, "__all__", ()):
        obj = getattr(mod, name)
        if not (inspect.isclass(obj) or inspect.isfunction(obj)):
            continue  # constants are documented by the module's docstring or a #: comment
        own = obj.__doc__ if not inspect.isclass(obj) else vars(obj).get("__doc__")
        if not (own or "").strip():
            missing.append(f"{module_name}.{name}")
        if inspect.isclass(obj):
            for attr, value in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if isinstance(value, (staticmethod, classmethod)):
                    value = value.__func__
                if (inspect.isfunction(value) or isinstance(value, property)) and not (value.__doc__ or "").strip():
                    missing.append(f"{module_name}.{name}.{attr}")
    return missing


def test_every_documented_module_lists_its_api_in_all():
    for name in DOCUMENTED:
        assert getattr(importlib.import_module(name), "__all__", None), f"{name} has no __all__"


def test_api_pages_cover_the_documented_modules():
    for name in DOCUMENTED:
        page = ROOT / "docs" / "api" / f"{name}.md"
        assert page.is_file() and f"::: {name}" in page.read_text(encoding="utf-8"), page


@pytest.mark.parametrize("module_name", DOCUMENTED)
def test_every_public_name_has_a_docstring(module_name):
    assert _undocumented(module_name) == []


def test_the_docstring_check_finds_a_missing_docstring(monkeypatch):
    import hydrogen.fmu  # noqa: F401  (not imported by `import hydrogen`; the test runs alone too)

    def bare():
        pass
    monkeypatch.setattr(hydrogen.fmu, "bare", bare, raising=False)
    monkeypatch.setattr(hydrogen.fmu, "__all__", [*hydrogen.fmu.__all__, "bare"])
    assert _undocumented("hydrogen.fmu") == ["hydrogen.fmu.bare"]


_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def _relative_links(text: str) -> list:
    return [t.split("#")[0] for t in _LINK.findall(text)
            if not re.match(r"^[a-z][a-z0-9+.-]*:", t) and not t.startswith("#")]


def test_every_relative_link_in_the_readme_points_at_a_file():
    links = _relative_links((ROOT / "README.md").read_text(encoding="utf-8"))
    assert links, "the README has no relative links: the pattern is wrong"
    missing = [t for t in links if not (ROOT / t).exists()]
    assert missing == []


def test_the_link_check_sees_a_broken_link():
    assert _relative_links("see [x](docs/nope.md#a) and [y](https://example.org) and ![f](a.png)") \
        == ["docs/nope.md", "a.png"]


def test_readme_mentions_no_issue_numbers():
    assert not re.search(r"\bissue\s*#?\d", (ROOT / "README.md").read_text(encoding="utf-8"), re.I)


# --- pages written by the runs ---------------------------------------------------------------

def test_committed_results_pages_are_the_renderer_on_the_committed_figures():
    for model in hydrogen.models():  # every built-in robot has its committed results page
        folder = pages.figures_folder(model)
        page = (ROOT / folder / pages.RESULTS_PAGE).read_text(encoding="utf-8")
        assert page == pages.results_page(hydrogen.load_model(model), ROOT / folder), folder


def test_committed_benchmarks_page_is_the_renderer_on_the_committed_json():
    bench = json.loads((ROOT / "docs/bench.json").read_text(encoding="utf-8"))
    repeats = json.loads((ROOT / "docs" / pages.REPEATS_JSON).read_text(encoding="utf-8"))
    page = (ROOT / "docs" / pages.BENCHMARKS_PAGE).read_text(encoding="utf-8")
    assert page == pages.benchmarks_page(bench, repeats, source="docs/bench.json")


def test_results_page_groups_figures_by_scenario_and_includes_the_table(tmp_path):
    model = hydrogen.load_model("ubc_stewart")
    (tmp_path / "table.md").write_text("caption\n\n| a |\n|---|\n| 12.5 |\n", encoding="utf-8")
    for f in ("z-1hz.png", "z-2hz.png", "paper-sim_errors.png", "stray.png"):
        (tmp_path / f).write_bytes(b"")
    path = pages.write_results_page(model, tmp_path)
    text = path.read_text(encoding="utf-8")
    assert path == tmp_path / "results.md" and "| 12.5 |" in text
    assert text.index("paper-sim_errors.png") < text.index("(z-1hz.png)") < text.index("(z-2hz.png)")
    assert "## Fig. 5: z, 1 Hz" in text and "## Other figures" in text and "(stray.png)" in text


def test_benchmarks_page_renders_what_the_run_holds(tmp_path):
    bench = json.loads((ROOT / "docs/bench.json").read_text(encoding="utf-8"))
    only = {"bench_sweep": bench["bench_sweep"]}
    (tmp_path / "bench.json").write_text(json.dumps(only), encoding="utf-8")
    text = pages.write_benchmarks_page(tmp_path / "bench.json").read_text(encoding="utf-8")
    rate = bench["bench_sweep"]["runs_per_s"]["dask"]
    shown = f"{rate:,.0f}" if rate >= 100 else f"{rate:.1f}"  # the page's rounding
    assert shown in text and "## Sweeps and identification" in text
    assert "## The closed loop" not in text and "## How cost grows" not in text


def test_benchmarks_page_renders_the_batched_sweep(tmp_path):
    batch = {"runs": 100, "gain_sets": 10, "seeds": 10, "sim_duration_s": 6.0, "workers": 2,
             "runs_per_cpu_s": {"c_loop": 31.25, "per_run_former": 12.0, "per_run": 25.4, "batched": 27.75},
             "of_c_loop": {"per_run_former": 0.384, "per_run": 0.81, "batched": 0.888},
             "former": {"substeps": 8, "pressure_bounds": "step"}, "batched_over_former": 2.3125,
             "release": {"commit": "abc1234", "runs_per_cpu_s": 9.25}, "batched_over_release": 3.0}
    (tmp_path / "bench.json").write_text(json.dumps({"bench_sweep": {"batch": batch}}), encoding="utf-8")
    text = pages.write_benchmarks_page(tmp_path / "bench.json").read_text(encoding="utf-8")
    assert "| batched, process pool (default) | 27.8 | 0.89 |" in text and "| bare C loop" in text
    assert "| one run per task, the former plant integration (8 sub-steps, pressure bounds `step`) | 12.0 | 0.38 |" in text
    assert "10 gain sets x 10 seeds" in text and "2.31× the runs per CPU-second" in text
    assert "commit abc1234" in text and "9.2 runs/CPU-s" in text and "3.00× that" in text


def test_figures_run_ends_by_writing_its_results_page(tmp_path, cache):
    from hydrogen import figures
    model = hydrogen.load_model("excavator_arm")
    dyn = hydrogen.build(model, cache=cache)
    paths = figures.make_all(dyn, tmp_path, durations={"arm-sim": 0.2, "arm-dig": 0.2})
    text = paths["results"].read_text(encoding="utf-8")
    assert paths["results"] == tmp_path / "results.md"
    assert text == pages.results_page(model, tmp_path)
    assert paths["table"].read_text(encoding="utf-8").strip() in text and "(arm-dig_bucket.png)" in text


def test_bench_run_ends_by_writing_its_page(tmp_path, monkeypatch):
    """hydrogen bench --json renders the page from the JSON it has just written (one cheap module)."""
    import sys
    import types
    from hydrogen import bench
    fake = types.ModuleType("bench_fake")
    fake.run = lambda quick: {"workers": 2, "runs": 8, "sim_duration_s": 6.0, "runs_per_s": {"dask": 12.34}}
    fake.print_table = lambda res: None
    monkeypatch.setitem(sys.modules, "bench_fake", fake)
    monkeypatch.setattr(bench, "SUITE", (("bench_fake", "a stand-in"),))
    bench.run_suite(json_path=str(tmp_path / "b.json"), progress=False)
    assert json.loads((tmp_path / "b.json").read_text())["bench_fake"]["runs_per_s"]["dask"] == 12.34
    assert (tmp_path / "benchmarks.md").is_file()


# --- the description reference ----------------------------------------------------------------

def test_description_table_lists_every_key_the_loader_accepts():
    from hydrogen.model import HYDRAULIC_KEYS
    from hydrogen.scenario_settings import _FIELDS
    table = schema.description_table()
    rows = {tuple(c.strip(" `") for c in line.split("|")[1:3]) for line in table.splitlines()[2:]}
    for k in schema.DESCRIPTION_KEYS + schema.SCENARIO_TABLE_KEYS + schema.VARIANT_KEYS:
        assert (k.table, k.key) in rows
    for f in _FIELDS:
        assert ("[scenarios.<name>], [rig], [variants.<name>]", f) in rows
    assert set(HYDRAULIC_KEYS) | {"name", "from", "to", "linkage", "valve", "friction"} == schema.keys("[[cylinders]]")


def test_scenario_rows_come_from_the_fields_own_declarations(monkeypatch):
    """A scenario field's unit, meaning and default are declared once, on the field: the table shows
    what the declaration says, and a changed declaration changes the row."""
    import dataclasses
    from hydrogen import scenario_settings as scenarios
    rows = {line.split("|")[2].strip(" `"): line for line in schema.description_table().splitlines()[2:]
            if "[rig]" in line}
    for f in scenarios.settings():
        assert f.metadata["unit"] in rows[f.name] and f.metadata["meaning"].split("(")[0].strip() in rows[f.name]
    assert "| 0.0 |" in rows["quantization_l"] and "required" in rows["duration"]
    seed = next(f for f in scenarios.settings() if f.name == "seed")
    patched = dataclasses.field(default=7, metadata={**seed.metadata, "meaning": "a changed meaning"})
    patched.name = "seed"
    monkeypatch.setattr(scenarios, "settings", lambda: tuple(patched if f.name == "seed" else f
                                                             for f in dataclasses.fields(scenarios.ScenarioFields)
                                                             if "unit" in f.metadata))
    assert "| `seed` | – | 7 | *run*: a changed meaning |" in schema.description_table()


def test_each_scenario_setting_is_declared_once_by_the_part_that_reads_it():
    """The plant's integration, valve and friction and the Kalman filter declare their own settings in
    their modules; the scenario's fields are those declarations (the same objects), each setting in one
    part only, and the description table labels each row with its part."""
    import dataclasses

    from hydrogen import scenario_settings as scenarios
    from hydrogen.estimators import kalman
    from hydrogen.plant import friction, integrator, valve

    owners = {"plant integration": integrator, "valve": valve, "friction": friction, "kalman estimator": kalman}
    parts = {part.name: part for part in scenarios.PARTS}
    for name, module in owners.items():
        assert parts[name].settings is module.SCENARIO_SETTINGS
    declared = [n for part in scenarios.PARTS for n in part.settings]
    assert len(declared) == len(set(declared)) == len(scenarios.settings())
    by_name = {f.name: f for f in dataclasses.fields(scenarios.ScenarioFields)}
    for part in scenarios.PARTS:
        for name, decl in part.settings.items():
            assert by_name[name].metadata == decl.metadata and scenarios.part_of(name) == part.name
    rows = {line.split("|")[2].strip(" `"): line for line in schema.description_table().splitlines()[2:]
            if "[rig]" in line}
    assert "*valve*: second-order servo-valve natural frequency" in rows["valve_bandwidth_hz"]
    assert "*plant integration*: RK4 plant steps" in rows["substeps"]


def test_the_loader_checks_keys_against_the_schema(monkeypatch):
    from hydrogen.model import tomllib
    from hydrogen.errors import ModelError
    from hydrogen.model import default_model_path, model_from_dict
    data = tomllib.loads(default_model_path().read_text(encoding="utf-8"))
    data["sensors"] = {"bogus": 1}
    with pytest.raises(ModelError, match=r"\[sensors\]: unknown key 'bogus' \(known: joint_encoders\)"):
        model_from_dict(data, source="t.toml")


def test_documented_defaults_are_the_defaults_the_loader_applies(tmp_path):
    from hydrogen.model import tomllib
    data = tomllib.loads(hydrogen.model.default_model_path().read_text(encoding="utf-8"))
    data["links"][0].pop("com")
    data.pop("sensors", None)
    m = hydrogen.model.model_from_dict(data, source="t.toml")
    assert list(m.links[0].com) == schema.default("[[links]]", "com")
    assert list(m.joints[0].origin_xyz) == schema.default("[[joints]]", "origin_xyz")
    assert m.joint_encoders is schema.default("[sensors]", "joint_encoders")
    assert m.figures_nonlinear == schema.default("[figures]", "nonlinear")


def test_the_pages_hold_their_rendered_tables_current():
    """The description reference and the command-line reference are rendered from the code's own
    definitions into the committed pages (``python tools/render_pages.py``): each page's block equals
    a fresh rendering, and the site's hook renders the same."""
    pages = _render_pages().block_pages()
    assert {p.name for p in pages} >= {"description.md", "cli.md"}
    hooks = _render_pages().render_blocks
    for path in pages:
        text = path.read_text(encoding="utf-8")
        assert hooks(text) == text, f"{path} is stale: run python tools/render_pages.py"
    description = (ROOT / "docs/guide/description.md").read_text(encoding="utf-8")
    assert "`orifice_linear_below`" in description and "*valve*: " in description
    cli_page = (ROOT / "docs/guide/cli.md").read_text(encoding="utf-8")
    assert "### hydrogen identify" in cli_page and "`--friction-speed`" in cli_page and "`--seeds`" in cli_page


def test_the_rig_seeds_page_is_its_data_rendered():
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import rig_seeds

    data = json.loads((ROOT / "docs" / "rig_seeds.json").read_text(encoding="utf-8"))
    assert (ROOT / "docs" / "rig_seeds.md").read_text(encoding="utf-8") == rig_seeds.markdown(data)
    # docs/paper.md's table of the timings is the same data's, as the script renders it
    table = rig_seeds.timing_markdown(data)
    assert table in (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")
    assert table.count("\n") == 2 + len(hydrogen.load_model().controllers)


def test_the_paper_shows_the_margins_checked_on_unseen_seeds_as_committed():
    """docs/paper.md holds the table of docs/margins_checking.json as its script renders it, a row for
    every nonlinear controller of every robot and rig scenario, over seeds none of the searches saw."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import margins_checking

    from hydrogen.simulation.tuning import rig_scenarios

    data = json.loads((ROOT / "docs" / "margins_checking.json").read_text(encoding="utf-8"))
    assert not set(data["seeds"]) & set(range(10)) and set(data["models"]) == set(hydrogen.models())
    for m, v in data["models"].items():
        model = hydrogen.load_model(m)
        want = {(c, s) for c in margins_checking.nonlinear(model)
                for s in rig_scenarios(model)}
        assert want <= {(r["controller"], r["scenario"]) for r in v["rows"]}, m
    text = (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")
    assert margins_checking.markdown(data) in text
    # the paragraph after the table names every row that falls short, with its margin and seeds
    rows = [r for v in data["models"].values() for r in v["rows"]]
    span = f"seeds {data['seeds'][0]}-{data['seeds'][-1]}"
    (paragraph,) = [p for p in text.split("\n\n") if p.startswith("**") and span in p and "margin of 2" in p]
    ok = sum(r["margin_ok"] for r in rows)
    assert f"{ok} of {len(rows)} rows" in paragraph or (ok == len(rows) and f"({ok} of {ok})" in paragraph)
    for r in rows:
        if not r["margin_ok"]:
            assert r["controller"] in paragraph and f"{r['margin']:.3g}" in paragraph
            assert all(f"seed {s}" in paragraph for s in r["unstable_seeds_at_limit"])


def test_every_nonlinear_controller_keeps_its_margin_in_the_committed_distributions():
    """What the README says of the committed 10-seed data: every model-based controller keeps a gain
    margin of 2 on every rig scenario and variant of every robot, judged over all seeds."""
    from hydrogen.controllers import CONTROLLERS, spec

    data = json.loads((ROOT / "docs" / "rig_seeds.json").read_text(encoding="utf-8"))
    assert len(data["seeds"]) >= 10 and set(data["models"]) == set(hydrogen.models())
    rows = []
    for m, v in data["models"].items():  # each robot's own controllers: a controller it does not list has no rows
        model_based = {k for k in hydrogen.load_model(m).controllers if not spec(k).compared}  # P: the comparison
        held = [r for r in v["rows"] if r["controller"] in model_based]
        assert {r["controller"] for r in held} == model_based and set(model_based) <= set(CONTROLLERS), m
        rows += [(m, r) for r in held]
    short = [(m, r["scenario"], r["controller"], r["margin"]) for m, r in rows if not r["margin"] >= 2.0]
    assert not short, short


# --- what the pages say hydrogen has ------------------------------------------------------------

#: ``hydrogen.<module>[.<name>...]`` and repository paths (``hydrogen/urdf.py``, ``tests/...``) in a page
_MODULE_REF = re.compile(r"(?<![\w/.-])hydrogen((?:\.[A-Za-z_]\w*)+)")
_PATH_REF = re.compile(r"(?<![\w/.-])((?:hydrogen|tests|tools|benchmarks|templates)/[\w./-]*\w)")
#: a tool hydrogen itself uses: "is read with X", "are parsed by hydrogen/urdf.py using X", "needs X"
_USES = re.compile(r"\b(?:(?:is|are)\s+(?:first\s+)?(?:read|parsed|loaded|written|drawn|plotted|rendered|"
                   r"solved|derived|generated)\b[^.;:()\n]{0,40}?\b(?:with|using|through)|needs?|requires?)"
                   r"\s+[\[`]*([A-Za-z](?:[\w.-]*\w)?)")
_PIP = re.compile(r"\bpip install\s+([^`\n;&|)#]+)")
#: extras for working on hydrogen, not for using it: a page saying hydrogen uses one of their
#: packages names something a user's install does not have
DEV_EXTRAS = ("test", "docs")


def _requirement_name(spec: str) -> str:
    return re.match(r"[A-Za-z0-9_.-]+", spec.strip()).group(0).lower().replace("_", "-")


def _declared() -> tuple:
    """(runtime, every) distribution names pyproject.toml declares: dependencies and the extras a
    user installs; and those with the extras for working on hydrogen. Plus the extras' names."""
    from hydrogen.model import tomllib
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = project.get("optional-dependencies", {})
    runtime = {_requirement_name(r) for r in project["dependencies"]}
    runtime |= {_requirement_name(r) for k, reqs in extras.items() if k not in DEV_EXTRAS for r in reqs}
    every = runtime | {_requirement_name(r) for reqs in extras.values() for r in reqs}
    return runtime, every, set(extras)


@functools.lru_cache(maxsize=None)
def _import_names() -> dict:
    """Installed import name -> its distributions' names (``pinocchio`` -> ``pin``)."""
    import importlib.metadata as md
    return {k.lower(): {d.lower().replace("_", "-") for d in v} for k, v in md.packages_distributions().items()}


def _distributions(name: str) -> set:
    """The distribution names a package or import name may be."""
    name = name.lower().replace("_", "-")
    return {name} | _import_names().get(name.replace("-", "_"), set())


@functools.lru_cache(maxsize=None)
def _packaged_dirs() -> dict:
    """setup.py's package_dir: a package the wheel holds -> its folder in the repository."""
    import ast
    for node in ast.walk(ast.parse((ROOT / "setup.py").read_text(encoding="utf-8"))):
        if isinstance(node, ast.keyword) and node.arg == "package_dir":
            return ast.literal_eval(node.value)
    return {}


def _resolves(dotted: str) -> bool:
    """``hydrogen.a.b.C``: the longest importable module, then attributes (or a packaged folder)."""
    packaged = _packaged_dirs()
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        module = ".".join(parts[:k])
        if module in packaged:
            return k == len(parts) and (ROOT / packaged[module]).is_dir()
        try:
            obj = importlib.import_module(module)
        except ImportError:
            continue
        for attr in parts[k:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def _path_exists(path: str) -> bool:
    for package, folder in _packaged_dirs().items():  # hydrogen/_templates is templates/ in the repository
        prefix = package.replace(".", "/")
        if path == prefix or path.startswith(prefix + "/"):
            path = folder + path[len(prefix):]
    return (ROOT / path).exists()


def _missing_references(text: str) -> list:
    """What ``text`` (a page) names of hydrogen that it does not have: a ``hydrogen.<module>...``
    that does not import or resolve, a repository path that does not exist, a package hydrogen is
    said to use ("read with X", "needs X") that pyproject.toml's dependencies and user extras lack,
    and a ``pip install`` of a package or extra pyproject.toml does not declare."""
    runtime, every, extras = _declared()
    known = every | {d for n in every for d in _distributions(n)}
    problems = [f"hydrogen{m}" for m in dict.fromkeys(_MODULE_REF.findall(text)) if not _resolves(f"hydrogen{m}")]
    problems += [p for p in dict.fromkeys(_PATH_REF.findall(text)) if "<" not in p and not _path_exists(p)]
    for name in dict.fromkeys(_USES.findall(text)):
        if name == "hydrogen":  # the package itself (a Dask worker needs hydrogen)
            continue
        dists = _distributions(name)
        importable = name.isidentifier() and importlib.util.find_spec(name) is not None
        is_package = dists & known or len(dists) > 1 or importable  # a name pyproject or an installed package has
        if is_package and not dists & runtime:
            problems.append(f"uses {name}")
    for args in _PIP.findall(text):
        for arg in args.replace("'", " ").replace('"', " ").split():
            extra = re.fullmatch(r"(?:\.|hydrogen)\[([\w,-]+)\]", arg)
            if extra:
                problems += [f"pip install extra {e}" for e in extra.group(1).split(",") if e not in extras]
            elif re.fullmatch(r"[A-Za-z][\w.-]*", arg) and arg != "hydrogen" and not _distributions(arg) & every:
                problems.append(f"pip install {arg}")
    return problems


def test_the_pages_name_only_modules_files_and_dependencies_hydrogen_has():
    pages_ = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    found = {str(p.relative_to(ROOT)): _missing_references(p.read_text(encoding="utf-8")) for p in pages_}
    assert {p: v for p, v in found.items() if v} == {}


def test_the_reference_check_finds_what_a_page_names_wrongly():
    stale = ("The URDF is read with [yourdfpy](https://github.com/clemense/yourdfpy), a maintained parser; "
             "see `hydrogen.urdfpy.load` and `hydrogen/yourdf.py`; `pip install -e '.[viewer]'`, then "
             "`pip install meshcat`.")
    assert _missing_references(stale) == ["hydrogen.urdfpy.load", "hydrogen/yourdf.py", "uses yourdfpy",
                                          "pip install extra viewer", "pip install meshcat"]
    fine = ("The URDF is read by `hydrogen/urdf.py` with lxml (`hydrogen.urdf.load_robot`, "
            "`hydrogen.model.QUANTITIES`); figures need matplotlib: `pip install -e '.[plot]'`; the wheel holds "
            "`hydrogen/_templates`; Pinocchio (`pip install pin`, in the test extra) is loaded with the URDF.")
    assert _missing_references(fine) == []
    # a tool only the test suite installs is not one hydrogen uses
    assert _missing_references("Running a sweep needs pytest-xdist.") == ["uses pytest-xdist"]


def test_the_paper_shows_the_tables_timing_over_fifty_unseen_seeds_as_committed():
    """docs/paper.md holds docs/table_seeds.json's table as its script prints it: every controller the
    default robot lists on every rig scenario, over 50 seeds none of the searches saw; the median lies
    in its range and the worst seed holds the maximum."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import table_seeds

    from hydrogen.simulation.tuning import rig_scenarios

    data = json.loads((ROOT / "docs" / "table_seeds.json").read_text(encoding="utf-8"))
    model = hydrogen.load_model()
    assert len(data["seeds"]) == 50 and not set(data["seeds"]) & set(range(10)) and data["model"] == model.name
    assert {(r["controller"], r["scenario"]) for r in data["rows"]} == {
        (c, s) for c in model.controllers for v in (None, *data["variants"]) for s in rig_scenarios(model, v)}
    for r in data["rows"]:
        assert r["min"] <= r["median"] <= r["max"] and r["worst_seed"] in data["seeds"]
        assert all(s in data["seeds"] for s in r["tail_seeds"])
    assert table_seeds.markdown(data) in (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")


def test_the_paper_shows_where_the_estimates_end_one_element_at_a_time_as_committed():
    """docs/paper.md holds docs/estimates_elements.json's table as its script prints it: every adaptive
    controller of the default robot on every rig scenario, each rig element switched alone, over seeds
    no search saw; and the data says what the text draws from it (on z-1hz the mass ends far above the
    truth on the rig and below it with the friction alone switched off; the ideal valve alone removes
    most of the γ error)."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import estimates_elements

    data = json.loads((ROOT / "docs" / "estimates_elements.json").read_text(encoding="utf-8"))
    assert not set(data["seeds"]) & set(range(10))
    rows = {(r["controller"], r["scenario"], r["element"]): r for r in data["rows"]}
    for c in ("adaptive-robust", "adaptive-observer"):
        mass = "platform.mass"
        rig, free = rows[(c, "z-1hz", "rig")], rows[(c, "z-1hz", "no friction")]
        assert rig["theta_ratio"][mass] > 1.25 and free["theta_ratio"][mass] < 0.8 and mass not in free["at_bound"]
        assert rows[(c, "z-1hz", "ideal valve")]["gamma_error_pct"] < 0.25 * rows[(c, "z-1hz", "rig")]["gamma_error_pct"]
    assert estimates_elements.markdown(data) in (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")


@pytest.mark.parametrize("study", ["bench_delay", "bench_sensitivity"])
def test_the_paper_shows_the_delay_and_sensitivity_tables_as_committed(study):
    """docs/paper.md's tables of error against delay and against the rig's friction and valve are the
    committed docs/bench.json rendered by the study's own script, not numbers pasted by hand."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    module = importlib.import_module(study)
    data = json.loads((ROOT / "docs" / "bench.json").read_text(encoding="utf-8"))[study]
    table = module.paper_markdown(data)
    controllers = next(iter(data["scenarios"].values()))["controllers"]
    rows = sum(len(sets) for sets in controllers.values()) if study == "bench_delay" else len(controllers)
    assert table.count("\n| ") == 1 + rows  # the header and a row per controller (and gain set)
    assert table in (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")


def test_the_study_tables_say_where_runs_diverged():
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import common

    points = {"a": {"median": {"z": 4.04}, "failed": 0, "completed": 5},
              "b": {"median": {"z": None}, "failed": 5, "completed": 0},
              "c": {"median": {"psi": 12.0}, "failed": 1, "completed": 4}}
    assert common.medians_cell(points, [("a", "z"), ("b", "z"), ("c", "psi")]) == "4.0 / fail / 12.0 (6 of 15 runs diverge)"
    assert common.medians_cell(points, [("a", "z")]) == "4.0"
    assert [common.fraction_text(f) for f in (0.0, 0.25, 0.5, 1.0)] == ["0", "1/4", "1/2", "1"]


def test_the_paper_names_every_margin_that_falls_short_on_the_confirming_seeds():
    """docs/margins_confirming.json checks the Stewart rows again on seeds neither a search nor the
    choice of what to search again saw; the paper's paragraph on it names each row under 2 there with
    its margin and seeds."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import margins_checking

    data = json.loads((ROOT / "docs" / "margins_confirming.json").read_text(encoding="utf-8"))
    checking = json.loads((ROOT / "docs" / "margins_checking.json").read_text(encoding="utf-8"))
    assert not set(data["seeds"]) & (set(range(10)) | set(checking["seeds"]))
    text = (ROOT / "docs" / "paper.md").read_text(encoding="utf-8")
    span = f"seeds {data['seeds'][0]}-{data['seeds'][-1]}"
    (paragraph,) = [p for p in text.split("\n\n") if span in p and "margins_confirming.json" in p]
    rows = [r for d in data["models"].values() for r in d["rows"]]
    assert rows and {r["controller"] for r in rows} == set(margins_checking.nonlinear(hydrogen.load_model()))
    for r in rows:
        if not r["margin_ok"]:
            assert r["controller"] in paragraph and f"{r['margin']:.3g}" in paragraph
            assert all(f"seed {s}" in paragraph for s in r["unstable_seeds_at_limit"])


def test_the_controllers_guide_shows_the_friction_compensation_study_as_committed():
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import friction_compensation

    data = json.loads((ROOT / "docs" / "friction_compensation.json").read_text(encoding="utf-8"))
    assert not set(data["seeds"]) & set(range(10))
    rendered = friction_compensation.markdown(data["rows"], data["seeds"])
    table = "\n".join(line for line in rendered.splitlines() if line.startswith("|"))  # without its caption
    assert table.count("\n") > 2 and table in (ROOT / "docs" / "guide" / "controllers.md").read_text(encoding="utf-8")


def _render_pages():
    spec = importlib.util.spec_from_file_location("render_pages", ROOT / "tools" / "render_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_page_renderer_replaces_a_stale_study_table_and_only_it():
    splice = _render_pages().splice
    page = "intro\n\nCaption:\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\nafter\n"
    new = "Caption:\n\n| a | b |\n|---|---|\n| 3 | 4 |\n| 5 | 6 |\n"
    assert splice(page, new) == "intro\n\nCaption:\n\n| a | b |\n|---|---|\n| 3 | 4 |\n| 5 | 6 |\n\nafter\n"
    with pytest.raises(ValueError, match="0 blocks start with"):
        splice(page, "Other:\n\n| x |\n")
    with pytest.raises(ValueError, match="2 blocks start with"):
        splice(page + page, new)


def test_every_study_table_the_renderer_writes_is_on_its_page_as_committed():
    for page, tables in _render_pages().study_tables().items():
        text = (ROOT / page).read_text(encoding="utf-8")
        assert tables and all(t.rstrip("\n") in text for t in tables), page
