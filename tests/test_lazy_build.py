"""A build compiles a core library; each controller's library is compiled on its first use and cached."""
import dataclasses
import json
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.controllers import CONTROLLERS, LEAN, function_name, rates_function_name, step_function_name
from hydrogen.runtime.library import CORE, function_groups, group_sources

#: No optimisation: these tests are about which files are compiled, not about the code's speed.
FAST = ("-O0", "-fPIC", "-std=c99")


def cached_builds(cache: Path) -> dict:
    """What the cache holds: for each build folder with a library, the sorted source names it was compiled from."""
    out = {}
    for info in sorted((cache / "build").glob("*/build.json")):
        data = json.loads(info.read_text())
        if (info.parent / data["library"]).is_file():
            out[info.parent.name] = tuple(sorted(data["sources"]))
    return out


def sources_of(dyn, group) -> tuple:
    return tuple(sorted(group_sources(dyn.library.manifest, group)))


def test_every_function_is_in_exactly_one_library(robot_dyn):
    manifest = robot_dyn.library.manifest
    groups = function_groups(manifest)
    names = [n for g in groups.values() for n in g]
    assert sorted(names) == sorted(e["name"] for e in manifest["functions"]) and len(set(names)) == len(names)
    # per controller its full variant, then its lean one where it has one (the adaptive ones), each
    # followed by its rates' library (a controller with a state)
    listed = robot_dyn.model.controllers  # the controllers the robot's description lists, in registry order
    want = [CORE] + [g for c in listed for v in (c, f"{c}-{LEAN}") for g in (v, f"{v}-rates") if g in groups]
    assert list(groups) == want and set(listed) <= set(groups)
    assert groups["adaptive-robust-lean"] == [function_name("adaptive-robust", LEAN),
                                              step_function_name("adaptive-robust", LEAN)]
    assert groups["adaptive-robust-lean-rates"] == [rates_function_name("adaptive-robust", LEAN)]
    assert not any(n.startswith("ctrl_") for n in groups[CORE])
    assert groups["p"] == ["ctrl_p"] and groups["p-task"] == ["ctrl_p_task"]  # ctrl_p does not claim ctrl_p_task
    assert f"{manifest['model_name']}_loop.c" in group_sources(manifest, CORE)


def test_a_run_compiles_the_core_and_its_controller_only(model, tmp_path):
    cache = tmp_path / "cache"
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes")
    assert list(cached_builds(cache).values()) == [sources_of(dyn, CORE)]
    assert dyn.library.loaded_groups() == (CORE,)
    hydrogen.simulate("z-1hz", "p", dyn=dyn, duration=0.02)
    assert sorted(cached_builds(cache).values()) == sorted([sources_of(dyn, CORE), sources_of(dyn, "p")])
    assert dyn.library.loaded_groups() == (CORE, "p")

    # A second controller compiles its own library alone; the first two are reused.
    before = cached_builds(cache)
    hydrogen.simulate("z-1hz", "p-task", dyn=dyn, duration=0.02)
    after = cached_builds(cache)
    assert {k: v for k, v in after.items() if k in before} == before
    assert [v for k, v in after.items() if k not in before] == [sources_of(dyn, "p-task")]

    # Another process (a new build) finds all three in the cache and compiles nothing.
    events = []
    again = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", progress=events.append,
                           controllers=("p", "p-task"))
    assert [e.stage for e in events] == ["loaded"] and cached_builds(cache) == after
    assert again.library.paths == dyn.library.paths


def test_build_compiles_the_controllers_it_is_given_with_the_core(model, tmp_path):
    cache = tmp_path / "cache"
    events = []
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("p",),
                         progress=events.append)
    assert [e.stage for e in events] == ["compiling", "compiled", "built"]  # one compile step for both
    assert dyn.library.loaded_groups() == (CORE, "p")
    assert sorted(cached_builds(cache).values()) == sorted([sources_of(dyn, CORE), sources_of(dyn, "p")])
    with pytest.raises(hydrogen.ScenarioError, match="unknown controller 'nope'"):
        hydrogen.build(model, cache=cache, cflags=FAST, controllers=("nope",))


def test_a_run_compiles_only_the_variant_it_runs(model, tmp_path):
    """An adaptive controller with its composite law compiles its full variant alone; with the
    paper's gradient laws (composite rates 0) its lean variant then; build(controllers=) the one the
    description's gains run (the Stewart's adaptive-observer sets a composite rate: the full one)."""
    from controller_inputs import PAPER_LAWS

    cache = tmp_path / "cache"
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes")
    hydrogen.simulate("z-1hz", "adaptive-robust", dyn=dyn, duration=0.02)
    assert dyn.library.loaded_groups() == (CORE, "adaptive-robust")
    assert sorted(cached_builds(cache).values()) == sorted([sources_of(dyn, CORE), sources_of(dyn, "adaptive-robust")])
    hydrogen.simulate("z-1hz", "adaptive-robust", dyn=dyn, duration=0.02, gains=PAPER_LAWS)
    assert dyn.library.loaded_groups() == (CORE, "adaptive-robust", "adaptive-robust-lean")
    both = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("adaptive-observer",))
    assert both.library.loaded_groups() == (CORE, "adaptive-observer")
    # a description that sets no composite rate runs the lean variant: that one is compiled with the core
    plain = dataclasses.replace(model, gains={k: {g: v for g, v in t.items() if not g.startswith("rate_ls")}
                                              for k, t in model.gains.items()})
    lean = hydrogen.build(plain, cache=cache, cflags=FAST, backend="ctypes", controllers=("adaptive-observer",))
    assert lean.library.loaded_groups() == (CORE, "adaptive-observer-lean")
    # a run's own gains (a scenario's) over the description's decide it too
    full = hydrogen.build(plain, cache=cache, cflags=FAST, backend="ctypes", controllers=("adaptive-observer",),
                          gains={"adaptive-observer": {"rate_ls_theta": 5.0}})
    assert full.library.loaded_groups() == (CORE, "adaptive-observer")


def test_the_rates_library_is_compiled_by_the_python_engine_alone(model, tmp_path, monkeypatch):
    """A controller's rates (the state's rates alone) are called by the Python engine's semi-implicit
    update only: a run of the C loop compiles the core and the controller's variant, not the rates; a
    run of the Python engine then compiles them, and the two runs agree."""
    cache = tmp_path / "cache"
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("adaptive-robust",))
    c = hydrogen.simulate("z-1hz", "adaptive-robust", dyn=dyn, duration=0.02)
    assert dyn.library.loaded_groups() == (CORE, "adaptive-robust")
    assert "adaptive-robust-rates" in dyn.library.groups()  # there, not compiled
    import hydrogen.simulation.simulator as simulator

    loaded_at_start = []  # the rates' library is loaded before the Python loop starts (and is timed)
    real = simulator.run_python_loop
    monkeypatch.setattr(simulator, "run_python_loop",
                        lambda *a: loaded_at_start.append(dyn.library.loaded_groups()) or real(*a))
    py = hydrogen.simulate("z-1hz", "adaptive-robust", dyn=dyn, duration=0.02, engine="python")
    assert loaded_at_start == [(CORE, "adaptive-robust", "adaptive-robust-rates")]
    assert dyn.library.loaded_groups() == (CORE, "adaptive-robust", "adaptive-robust-rates")
    assert sorted(cached_builds(cache).values()) == sorted(sources_of(dyn, g) for g in dyn.library.loaded_groups())
    np.testing.assert_allclose(py.q, c.q, rtol=0, atol=1e-12)


def _library_of(dyn, group) -> Path:
    return dyn.library.paths[group]


@pytest.mark.parametrize("damage", ["truncated", "removed"])
def test_a_damaged_controller_library_is_rebuilt(model, tmp_path, damage):
    cache = tmp_path / "cache"
    d1 = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("p",))
    path = _library_of(d1, "p")
    core = _library_of(d1, CORE)
    if damage == "truncated":  # through a new inode, as another process would: this process keeps its mapping
        tmp = path.with_name("truncated.tmp")
        tmp.write_bytes(path.read_bytes()[:1000])
        os.replace(tmp, path)
    else:
        path.unlink()
    events = []
    d2 = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", progress=events.append)
    assert [e.stage for e in events] == ["loaded"] and _library_of(d2, CORE) == core  # the core is intact
    r = hydrogen.simulate("z-1hz", "p", dyn=d2, duration=0.02)
    new = _library_of(d2, "p")
    assert new != path and new.is_file() and path.parent == new.parent
    assert [e.stage for e in events] == ["loaded", "compiling", "compiled"]
    np.testing.assert_array_equal(r.u, hydrogen.simulate("z-1hz", "p", dyn=d1, duration=0.02).u)


def test_threads_sharing_a_library_compile_a_controller_once(model, tmp_path):
    cache = tmp_path / "cache"
    events, got, errors = [], [], []
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", progress=events.append)
    del events[:]
    start = threading.Barrier(3)

    def use():
        try:
            start.wait()
            got.append(dyn.functions["ctrl_p"])
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=use) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors and len(got) == 3 and all(f is got[0] for f in got)
    assert [e.stage for e in events] == ["compiling", "compiled"]


_CHILD = """
import sys, hydrogen
dyn = hydrogen.build(cache=sys.argv[1], cflags=("-O0", "-fPIC", "-std=c99"), backend="ctypes")
res = hydrogen.simulate("z-1hz", "p", dyn=dyn, duration=0.02)
print(dyn.library.paths["p"], float(res.u[-1, 0]).hex())
"""


def test_processes_using_a_controller_first_at_once_share_one_build(model, tmp_path):
    cache = tmp_path / "cache"
    hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes")  # the core is warm: p is first used below
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(hydrogen.__file__).parents[1]),
                                                       os.environ.get("PYTHONPATH", "")]))
    children = [subprocess.Popen([sys.executable, "-c", _CHILD, str(cache)], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, env=env) for _ in range(2)]
    outs = [c.communicate(timeout=600) for c in children]
    assert all(c.returncode == 0 for c in children), [o[1] for o in outs]
    lines = [o[0].split() for o in outs]
    assert lines[0] == lines[1]  # one library, the same commands
    builds = cached_builds(cache)
    assert len(builds) == 2 and Path(lines[0][0]).parent.name in builds


def test_a_controller_first_used_after_its_sources_changed_is_refused(model, tmp_path):
    import shutil

    from hydrogen.runtime.build import repo_generated_dir

    folder = tmp_path / "generated"
    shutil.copytree(repo_generated_dir() / model.name, folder)
    dyn = hydrogen.build(model, cache=tmp_path / "cache", cflags=FAST, backend="ctypes", generated=folder)
    (source,) = group_sources(dyn.library.manifest, "p")
    with open(folder / source, "a") as f:
        f.write("/* edited */\n")
    with pytest.raises(hydrogen.BuildCacheError, match=f"{source}: differs from the generated folder"):
        dyn.functions["ctrl_p"]
    assert dyn.library.loaded_groups() == (CORE,) and len(cached_builds(tmp_path / "cache")) == 1


def test_a_library_compiled_after_a_header_it_includes_changed_is_refused(model, tmp_path):
    """The headers a library's sources include are checked against the manifest as the sources are
    (the library's key covers them): the loop header edited after the build is refused by name
    when the core compiles again, not compiled in."""
    import shutil

    from hydrogen.runtime.build import repo_generated_dir

    folder = tmp_path / "generated"
    shutil.copytree(repo_generated_dir() / model.name, folder)
    dyn = hydrogen.build(model, cache=tmp_path / "cache", cflags=FAST, backend="ctypes", generated=folder)
    header = folder / f"{model.name}_loop.h"
    with open(header, "a") as f:
        f.write("/* edited */\n")
    with pytest.raises(hydrogen.BuildCacheError, match=f"{header}: differs from the generated folder"):
        dyn.library._loader(CORE, True)  # what a rebuild of a library that failed to load calls


def test_a_build_for_one_controller_derives_it_alone_and_grows_on_demand(tmp_path):
    """A new structure built for one controller derives that one only (what ``hydrogen simulate``
    does); another is an error naming what the build holds; building for it derives it alone."""
    from hydrogen.codegen.generate import held_controllers

    model = hydrogen.load_model(Path(__file__).parent / "data" / "four_way_arm.toml")
    cache = tmp_path / "cache"
    events = []
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("p",),
                         progress=events.append)
    assert held_controllers(dyn.library.manifest) == ("p",)
    assert [e.stage for e in events][:2] == ["generating", "generated"]
    with pytest.raises(hydrogen.ScenarioError, match=r"controller 'backstepping' is not in this build of "
                       r"'four_way_arm' \(it holds p\); build with"):
        hydrogen.simulate("arm-sim", "backstepping", dyn=dyn, duration=0.01)
    events.clear()
    grown = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("backstepping",),
                           progress=events.append)
    assert held_controllers(grown.library.manifest) == ("backstepping", "p")
    assert events[0].stage == "generating" and events[0].detail.startswith("deriving backstepping (SymPy)")
    n, own = len(grown.library.manifest["functions"]), len(dyn.library.manifest["functions"])
    assert events[1].stage == "generated" and events[1].detail.startswith(f"{n - own} of {n} functions again")
    assert grown.library.manifest["files"] | dyn.library.manifest["files"] == grown.library.manifest["files"]
    r = hydrogen.simulate("arm-sim", "backstepping", dyn=grown, duration=0.01)
    assert np.isfinite(r.q).all()
    # no controller named: every one, the missing ones derived
    assert held_controllers(hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes").library.manifest) \
        == tuple(CONTROLLERS)


def test_the_default_dynamics_grow_with_the_controllers_run(tmp_path, monkeypatch):
    from hydrogen.codegen.generate import held_controllers

    monkeypatch.setenv("HYDROGEN_CACHE_DIR", str(tmp_path / "cache"))
    model = hydrogen.load_model(Path(__file__).parent / "data" / "four_way_arm.toml")
    first = hydrogen.default_dynamics(model, controller="p")
    assert held_controllers(first.library.manifest) == ("p",)
    assert hydrogen.default_dynamics(model, controller="p").library is first.library  # built once
    second = hydrogen.default_dynamics(model, controller="p-task")
    assert held_controllers(second.library.manifest) == ("p", "p-task")
    assert hydrogen.default_dynamics(model, controller="p").library is second.library


def test_a_robot_generates_the_controllers_its_description_lists(tmp_path):
    """``controllers = [...]``: a whole generation holds those (in the registry's order); a build,
    run or export of another is refused naming the file and the key."""
    from hydrogen.codegen import generate as gen
    from hydrogen.codegen.generate import held_controllers

    text = (Path(__file__).parent / "data" / "four_way_arm.toml").read_text()
    path = tmp_path / "two.toml"
    path.write_text('controllers = ["p", "backstepping"]\n' + text)
    model = hydrogen.load_model(path)
    assert model.controllers == ("backstepping", "p")
    cache = tmp_path / "cache"
    dyn = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes")
    assert held_controllers(dyn.library.manifest) == ("backstepping", "p")
    assert gen.check_output(model, dyn.library.generated_dir) == []  # whole, for this robot
    r = hydrogen.simulate("arm-sim", "backstepping", dyn=dyn, duration=0.01)
    assert np.isfinite(r.q).all()
    want = rf"{path}: controllers: controller 'adaptive-robust' is not generated for 'four_way_arm' \(its " \
           r"description lists backstepping, p\); add it to controllers to run it"
    with pytest.raises(hydrogen.ScenarioError, match=want):
        hydrogen.simulate("arm-sim", "adaptive-robust", dyn=dyn, duration=0.01)
    with pytest.raises(hydrogen.ScenarioError, match=want):
        hydrogen.build(model, cache=cache, cflags=FAST, controllers=("adaptive-robust",))


@pytest.mark.parametrize("value, words", [
    ('["nope"]', "unknown controller 'nope'; hydrogen's controllers: backstepping"),
    ("[]", "expected a non-empty list of controller names"),
    ('"p"', "expected a non-empty list of controller names"),
    ('["p", "p"]', "a controller is listed twice"),
])
def test_a_bad_controllers_list_names_the_file_and_key(tmp_path, value, words):
    path = tmp_path / "bad.toml"
    path.write_text(f"controllers = {value}\n" + (Path(__file__).parent / "data" / "four_way_arm.toml").read_text())
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    assert str(err.value).startswith(f"{path}: controllers: ") and words in str(err.value)


def test_a_build_for_no_controller_holds_the_core_alone(tmp_path):
    """``controllers=()``: the core only (what identification calls); a later build for a
    controller adds it."""
    from hydrogen.codegen.generate import held_controllers

    model = hydrogen.load_model(Path(__file__).parent / "data" / "four_way_arm.toml")
    cache = tmp_path / "cache"
    core = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=())
    assert held_controllers(core.library.manifest) == () and core.library.loaded_groups() == (CORE,)
    assert np.all(np.isfinite(core.leg_lengths(model.neutral_pose)))  # the core's functions run
    grown = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes", controllers=("p",))
    assert held_controllers(grown.library.manifest) == ("p",)
    every = hydrogen.build(model, cache=cache, cflags=FAST, backend="ctypes")  # None: all it lists
    assert held_controllers(every.library.manifest) == tuple(CONTROLLERS)


def test_a_new_structure_compiles_its_core_while_the_controller_derives(tmp_path, monkeypatch):
    """Each source of the libraries a build compiles starts compiling as soon as it is written: the
    core's before the controller is derived, the variant the run uses, never the other one."""
    import hydrogen.runtime.build as build_module
    from hydrogen.controllers import controller
    from hydrogen.runtime.library import group_of

    model = hydrogen.load_model(Path(__file__).parent / "data" / "four_way_arm.toml")
    timeline = []
    real_precompile, ctrl = build_module.precompile, controller("adaptive-robust")
    real_derive = ctrl.derive
    monkeypatch.setattr(build_module, "precompile",
                        lambda sources, *a: (timeline.extend(Path(s).name for s in sources), real_precompile(sources, *a)))
    monkeypatch.setattr(ctrl, "derive", lambda m: (timeline.append("derive"), real_derive(m))[1])
    dyn = hydrogen.build(model, cache=tmp_path / "cache", cflags=FAST, backend="ctypes",
                         controllers=("adaptive-robust",))
    manifest = dyn.library.manifest
    lean = f"adaptive-robust-{LEAN}"  # the description sets no composite rate
    assert timeline.index("derive") == len(group_sources(manifest, CORE)) - 1  # every core function, not the driver
    assert sorted(timeline[:timeline.index("derive")] + timeline[-1:]) == sorted(group_sources(manifest, CORE))
    own = timeline[timeline.index("derive") + 1:-1]
    assert sorted(own) == sorted(group_sources(manifest, lean))
    assert own[0] == f"four_way_arm_{step_function_name('adaptive-robust', LEAN)}.c"  # the longest compile first
    assert all(group_of(e["name"]) != "adaptive-robust" or e["source"] not in timeline for e in manifest["functions"])
    # the library's own compile found every object made: nothing compiled twice
    objects = list((tmp_path / "cache" / "objects").glob("*.o"))
    assert len(objects) == len(group_sources(manifest, CORE)) + len(group_sources(manifest, lean))
    assert np.isfinite(hydrogen.simulate("arm-sim", "adaptive-robust", dyn=dyn, duration=0.01).q).all()


def _wait_for(predicate, limit_s: float = 300.0) -> bool:
    """Poll ``predicate`` until true or ``limit_s`` passed (the background compiles of a busy machine)."""
    import time
    t0 = time.monotonic()
    while not predicate():
        if time.monotonic() - t0 > limit_s:
            return False
        time.sleep(0.1)
    return True


def test_a_quick_build_runs_unoptimized_alike_and_the_next_build_links_the_optimized_objects(tmp_path, dyn):
    """quick=True on an empty cache: the libraries it must compile are compiled at -O0 and loaded, the run
    equals the optimized build's bit for bit, the optimized objects arrive in the store in the
    background, and the next build links them (no -O0 library loaded then)."""
    from hydrogen.runtime.compiler import Toolchain, objects_stored

    cache = tmp_path / "cache"
    events = []
    quick = hydrogen.build("ubc_stewart", cache=cache, controllers=("adaptive-robust",), quick=True,
                           progress=events.append)
    groups = quick.library.loaded_groups()
    assert set(quick.library.unoptimized()) == set(groups) and CORE in groups
    for g in groups:
        argv = json.loads((Path(quick.library.paths[g]).parent / "build.json").read_text())["argv"]
        assert "-O0" in argv and "-O2" not in argv
    assert any("unoptimized (-O0)" in e.detail for e in events if e.stage == "compiling")
    assert quick.library.backend == "extension"  # compiled unoptimized too: no optimized one cached
    ext = json.loads((Path(quick.library.extension_path).parent / "build.json").read_text())["argv"]
    assert "-O0" in ext and "-O2" not in ext
    a = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=quick, duration=0.2)
    b = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn, duration=0.2)
    for name in ("q", "u", "pressures", "leg_forces", "theta_hat", "leg_lengths_measured"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    folder = quick.library.generated_dir
    sources = [folder / s for g in groups for s in group_sources(quick.library.manifest, g)]
    assert _wait_for(lambda: objects_stored(sources, Toolchain(), cache)), "the optimized objects never arrived"
    events.clear()
    again = hydrogen.build("ubc_stewart", cache=cache, controllers=("adaptive-robust",), quick=True,
                           progress=events.append)
    assert again.library.unoptimized() == ()
    argv = json.loads((Path(again.library.path).parent / "build.json").read_text())["argv"]
    assert "-O2" in argv and "-O0" not in argv
    assert not any("unoptimized" in e.detail for e in events)


def test_an_optimized_build_after_a_quick_one_loads_no_unoptimized_library(tmp_path):
    """quick=False (the default) never loads an -O0 library, even where a quick build left one."""
    cache = tmp_path / "cache"
    quick = hydrogen.build("ubc_stewart", cache=cache, controllers=(), quick=True)
    assert quick.library.unoptimized() == (CORE,)
    plain = hydrogen.build("ubc_stewart", cache=cache, controllers=())
    assert plain.library.unoptimized() == ()
    argv = json.loads((Path(plain.library.path).parent / "build.json").read_text())["argv"]
    assert "-O2" in argv and "-O0" not in argv


def test_a_quick_build_with_flags_of_the_users_own_is_optimized(tmp_path):
    """Other flags may round otherwise at -O0 (e.g. -march with fused multiply-adds): built as given."""
    flags = ("-O1", "-fPIC", "-std=c99")
    dyn = hydrogen.build("ubc_stewart", cache=tmp_path / "cache", controllers=(), quick=True, cflags=flags)
    assert dyn.library.unoptimized() == ()
    argv = json.loads((Path(dyn.library.path).parent / "build.json").read_text())["argv"]
    assert "-O1" in argv and "-O0" not in argv


def test_a_quick_build_links_the_optimized_objects_already_stored(tmp_path, monkeypatch):
    """Of a library whose optimized objects are stored but two, only those two compile at -O0."""
    import hydrogen.runtime.compiler as compiler

    cache = tmp_path / "cache"
    hydrogen.build("ubc_stewart", cache=cache, controllers=())
    for folder in (cache / "build").iterdir():  # the library gone, its objects kept ...
        if folder.is_dir():
            shutil.rmtree(folder)
    objects = sorted((cache / "objects").glob("*.o"), key=lambda o: o.stat().st_size)
    for o in objects[-2:]:  # ... but for the two largest
        o.unlink()
    calls = []
    real = compiler.run_compiler
    monkeypatch.setattr(compiler, "run_compiler", lambda argv, *a, **k: (calls.append(argv), real(argv, *a, **k))[1])
    quick = hydrogen.build("ubc_stewart", cache=cache, controllers=(), quick=True)
    assert quick.library.unoptimized() == (CORE,)
    sources = [Path(c[c.index("-c") + 1]).name for c in calls if "-c" in c and "-O0" in c]
    assert len([s for s in sources if not s.startswith("_hydrogen")]) == 2, sources  # the extension apart

def test_a_quick_build_of_a_built_robot_loads_the_optimized_libraries_and_extension(dyn, cache):
    """Nothing to compile: quick=True loads what the optimized build made, the extension included."""
    quick = hydrogen.build("ubc_stewart", cache=cache, quick=True)
    assert quick.library.unoptimized() == ()
    assert quick.library.path == dyn.library.path
    assert quick.library.extension_path == dyn.library.extension_path
