"""Build cache, compiler selection and failure reporting of the runtime."""
import os
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.runtime.compiler import Toolchain, compile_library
from conftest import warm_copy


def test_build_reuses_the_cache(model, cache, dyn):
    again = hydrogen.build(model, cache=cache)
    assert again.library.path == dyn.library.path


def test_other_flags_get_another_library(model, cache, dyn):
    other = hydrogen.build(model, cache=cache, cflags=("-O1", "-fPIC", "-std=c99"))
    assert other.library.path != dyn.library.path
    q = model.neutral_pose + 0.01
    np.testing.assert_allclose(other.leg_lengths(q), dyn.leg_lengths(q), rtol=1e-15)


def test_corrupt_cached_library_is_rebuilt_under_a_new_name(model, tmp_path):
    fast = ("-O0", "-fPIC", "-std=c99")  # the cache's integrity check is under test, not the optimiser
    d1 = hydrogen.build(model, cache=tmp_path, cflags=fast)
    path = d1.library.path
    # Truncate through a new inode, as another process would: this process keeps its mapping.
    tmp = path.with_name("truncated.tmp")
    tmp.write_bytes(path.read_bytes()[:1000])
    os.replace(tmp, path)
    d2 = hydrogen.build(model, cache=tmp_path, cflags=fast)
    assert d2.library.path != path and d2.library.path.exists()
    q = model.neutral_pose
    np.testing.assert_allclose(d2.leg_lengths(q), d1.leg_lengths(q))


def test_missing_compiler_is_a_clear_error(model, tmp_path):
    with pytest.raises(hydrogen.CompilerError, match="no C compiler found"):
        hydrogen.build(model, cache=tmp_path, cc="definitely-not-a-compiler")


def test_compile_error_shows_the_compilers_message(tmp_path):
    src = tmp_path / "broken.c"
    src.write_text("int f(void) { return undefined_name; }\n")
    with pytest.raises(hydrogen.CompilerError) as err:
        compile_library([src], "broken", Toolchain(), cache=tmp_path)
    assert "undefined_name" in str(err.value) and "broken.c" in str(err.value)


def test_wrong_input_shape_is_rejected(dyn):
    with pytest.raises(ValueError, match="input 'q' needs shape"):
        dyn.leg_lengths(np.zeros(5))
    with pytest.raises(TypeError, match="takes 2 inputs"):
        dyn.functions["mass_matrix"](np.zeros(6))


def test_outputs_are_fresh_arrays(dyn, model):
    a = dyn.leg_lengths(model.neutral_pose)
    b = dyn.leg_lengths(model.neutral_pose + 0.01)
    assert not np.allclose(a, b)


def test_runtime_path_imports_neither_sympy_nor_casadi(dyn, cache):
    """The thin runtime: loading a built library and simulating needs no SymPy, CasADi or jinja2
    (a sweep worker or a CLI call starts in a fraction of the time)."""
    import subprocess
    import sys

    code = ("import sys, hydrogen; dyn = hydrogen.build(cache=%r); "
            "hydrogen.simulate('z-step', 'p', duration=0.1, dyn=dyn); "
            "print(sorted(m for m in ('sympy', 'casadi', 'jinja2') if m in sys.modules))" % str(cache))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def _copy_of_committed(model, dest):
    """A generated folder for ``model`` made by copying the committed one (no generation needed)."""
    import shutil

    from hydrogen.resources import committed_generated_dir
    shutil.copytree(committed_generated_dir() / model.name, dest)
    return dest


def test_a_corrupt_manifest_in_hydrogens_own_cache_is_generated_again(model, cache, dyn, tmp_path, monkeypatch):
    """hydrogen's cache is its own: a broken entry is rebuilt with one warning line. The same fault in
    the user's generated folder is an error naming the file, and the folder is left as it was."""
    import shutil
    import warnings

    import hydrogen.runtime.build as build_mod
    from hydrogen.codegen import generate as gen
    from hydrogen.errors import OutputPathError

    committed = build_mod.repo_generated_dir() / model.name
    monkeypatch.setattr(build_mod, "repo_generated_dir", lambda: tmp_path / "no-committed-code")
    entry = build_mod.generated_dir_for(model, cache)
    assert entry.parent == cache / "generated"
    shutil.rmtree(entry, ignore_errors=True)
    _copy_of_committed(model, entry)
    try:
        (entry / "manifest.json").write_text('{"model_hash": ')  # cut short, as by a crash or a full disk
        rendered = []

        def render_by_copy(model, folder, progress=False, numbers="constants", controllers=None, written=None, first=None):  # the same files, without SymPy's minutes
            rendered.append(folder)
            for p in committed.iterdir():
                shutil.copy(p, folder / p.name)
        monkeypatch.setattr(gen, "render", render_by_copy)
        with pytest.warns(RuntimeWarning, match=r"cache entry .* is broken \(.*manifest.json.*\); generating it again"):
            d = hydrogen.build(model, cache=cache)
        assert rendered and gen.check(model, entry) == []
        np.testing.assert_array_equal(d.leg_lengths(model.neutral_pose), dyn.leg_lengths(model.neutral_pose))
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a sound entry: no warning
            hydrogen.build(model, cache=cache)
    finally:
        shutil.rmtree(entry, ignore_errors=True)

    mine = _copy_of_committed(model, tmp_path / "mine")
    (mine / "manifest.json").write_text("{not json")
    with pytest.raises(OutputPathError, match=r"manifest.json cannot be read") as err:
        hydrogen.build(model, cache=cache, generated=mine)
    assert str(mine / "manifest.json") in str(err.value)
    assert (mine / "manifest.json").read_text() == "{not json"


def test_a_full_disk_names_the_file_being_written(tmp_path, monkeypatch):
    import errno

    import hydrogen.fileio as fileio
    from hydrogen.errors import BuildCacheError, DiskFullError
    from hydrogen.runtime.cachedir import cache_errors

    def full(path, data, sync=False):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(fileio, "_write_bytes", full)
    target = tmp_path / "out" / "results.json"
    with pytest.raises(DiskFullError, match=r"results.json: cannot be written, the disk is full") as err:
        fileio.atomic_write(target, "{}")
    assert str(target) in str(err.value) and "Errno" not in str(err.value)
    assert not list((tmp_path / "out").iterdir())  # no temporary file left behind
    with pytest.raises(DiskFullError, match="disk is full"):
        fileio.write_file(tmp_path / "a.c", "int a;")
    # in the cache: the file, and where else the cache can go
    with pytest.raises(BuildCacheError, match=r"build.json: cannot be written, the disk is full.*HYDROGEN_CACHE_DIR"):
        with cache_errors(tmp_path):
            fileio.atomic_write(tmp_path / "build.json", "{}")
    with pytest.raises(BuildCacheError, match=r"cache folder .*: the disk is full \(.*lib.so\).*HYDROGEN_CACHE_DIR"):
        with cache_errors(tmp_path):
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "lib.so"))


def test_a_cache_on_a_noexec_mount_is_named(dyn, monkeypatch):
    import ctypes

    from hydrogen.errors import BuildCacheError
    from hydrogen.runtime.library import GeneratedLibrary

    path = dyn.library.path

    def refuse(name, *a, **k):  # what glibc's loader says when mmap of code is refused
        raise OSError(f"{name}: failed to map segment from shared object")
    monkeypatch.setattr(ctypes, "CDLL", refuse)
    with pytest.raises(BuildCacheError, match=r"failed to map segment.*mounted noexec.*HYDROGEN_CACHE_DIR") as err:
        GeneratedLibrary(path, dyn.library.manifest, numbers=dyn.model.numbers)
    assert str(path.parent) in str(err.value)


def test_a_full_disk_during_generation_names_the_generated_file(tmp_path, monkeypatch, model):
    import errno
    import json

    import hydrogen.fileio as fileio
    from hydrogen.codegen.generate import render_drivers
    from hydrogen.errors import DiskFullError
    from hydrogen.resources import committed_generated_dir

    def full(path, data, sync=False):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(fileio, "_write_bytes", full)
    manifest = json.loads((committed_generated_dir() / model.name / "manifest.json").read_text())
    with pytest.raises(DiskFullError, match=rf"{model.name}_loop.h: cannot be written, the disk is full"):
        render_drivers(manifest, tmp_path)


def test_a_build_with_the_numbers_as_inputs_serves_a_numeric_edit_without_compiling(tmp_path, cache, rng):
    """The numbers as inputs (the default): the edited arm (a pin, the linkage's crank pin, an area,
    the supply pressure, gravity, a mass) loads the library built for the shipped one, no generation
    and no compile, and its functions give the folded derivation of the edited description; the
    shipped build keeps its own numbers."""
    from hydrogen.codegen.casadi_functions import to_casadi_function
    from hydrogen.errors import ScenarioError
    from hydrogen.symbolic.functions import SymbolicFunction, derive_functions
    from test_codegen import _random_input
    from test_constants import NUMERIC_EDIT, _edited_arm

    arm = hydrogen.load_model("excavator_arm")
    first = hydrogen.build(arm, numbers="inputs", cache=cache)
    events = []
    edited = _edited_arm(tmp_path, NUMERIC_EDIT)
    dyn = hydrogen.build(edited, numbers="inputs", cache=cache, progress=events.append)
    assert [e.stage for e in events] == ["loaded"] and dyn.library.path == first.library.path
    # the extension fills the numbers as the ctypes route does: a caller never passes them
    assert dyn.backend == "extension"
    for fns in (dyn.functions, dyn.library.functions):
        assert "numbers" not in fns["mass_matrix"].in_names
    checked = 0
    for f in derive_functions(edited, controllers=False):
        if not isinstance(f, SymbolicFunction):
            continue
        ref = to_casadi_function(f)
        args = [_random_input(n, m.shape, edited, rng, f.name) for n, m in f.inputs]
        want = [np.array(x) for x in ref.call(args)]
        for fn in (dyn.functions[f.name], dyn.library.functions[f.name]):
            got = fn(*[np.ravel(a) if np.ndim(a) == 2 and np.shape(a)[1] == 1 else a for a in args])
            got = got if isinstance(got, tuple) else (got,)
            for x, y in zip(want, got):
                np.testing.assert_allclose(np.reshape(y, x.shape), x, rtol=1e-9, atol=1e-9,
                                           err_msg=f"{f.name} ({fn.backend})")
        checked += 1
    assert checked >= 10
    q = edited.neutral_pose
    assert not np.allclose(first.gravity(q, arm.theta), dyn.gravity(q, arm.theta), rtol=1e-6)
    qs = np.stack([q, q + 0.05])  # a batch: the extension's C loop over states passes the numbers too
    np.testing.assert_allclose(dyn.functions["gravity"](qs, arm.theta),
                               [dyn.library.functions["gravity"](x, arm.theta) for x in qs], rtol=1e-12)
    # the C loop runs on it: on the shipped arm as on the folded library (a controller with a state:
    # its semi-implicit step takes the numbers too); on the edited arm as the Python loop does
    folded = hydrogen.build(arm, cache=cache, numbers="constants")
    shipped = {}
    for ctrl in ("backstepping", "adaptive-robust"):
        a, b = (hydrogen.simulate("arm-sim", ctrl, dyn=d, duration=0.2) for d in (first, folded))
        assert np.all(np.isfinite(a.q)) and len(a.q) > 10
        np.testing.assert_allclose(a.q, b.q, rtol=1e-9, atol=1e-12, err_msg=ctrl)
        np.testing.assert_allclose(a.leg_forces, b.leg_forces, rtol=1e-9, atol=1e-6, err_msg=ctrl)
        shipped[ctrl] = a
    c, py = (hydrogen.simulate("arm-sim", "backstepping", dyn=dyn, engine=e, duration=0.2) for e in ("c", "python"))
    np.testing.assert_allclose(c.q, py.q, rtol=1e-7, atol=1e-9)
    assert not np.allclose(c.q, shipped["backstepping"].q, atol=1e-6)  # the edit reached the C loop
    with pytest.raises(ScenarioError, match="numbers must be one of"):
        hydrogen.build(arm, numbers="folded", cache=cache)


def test_a_cached_manifest_whose_numbers_list_was_swapped_is_generated_again(model, cache, dyn, tmp_path,
                                                                            monkeypatch):
    """The manifest's ``numbers`` list maps each value the runtime fills to its place in the C: two names
    swapped (gravity and a mass: gravity hundreds of times wrong) fail the check, and the cache entry is
    generated again instead of loaded."""
    import json
    import shutil

    import hydrogen.runtime.build as build_mod
    from hydrogen.codegen import generate as gen

    committed = build_mod.repo_generated_dir() / model.name
    monkeypatch.setattr(build_mod, "repo_generated_dir", lambda: tmp_path / "no-committed-code")
    root = warm_copy(cache, tmp_path / "cache")
    entry = build_mod.generated_dir_for(model, root)
    _copy_of_committed(model, entry)
    assert gen.check(model, entry) == []
    manifest = json.loads((entry / "manifest.json").read_text())
    names = manifest["numbers"]
    i, j = names.index("gravity"), names.index("platform.mass")
    names[i], names[j] = names[j], names[i]
    (entry / "manifest.json").write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    assert any("numbers list does not match" in r for r in gen.check(model, entry))

    rendered = []

    def render_by_copy(model, folder, progress=False, numbers="inputs", controllers=None, written=None, first=None):  # the same files, without the derivation
        rendered.append(folder)
        for p in committed.iterdir():
            shutil.copy(p, folder / p.name)
    monkeypatch.setattr(gen, "render", render_by_copy)
    d = hydrogen.build(model, cache=root)
    assert rendered and gen.check(model, entry) == []
    q = model.neutral_pose
    np.testing.assert_array_equal(d.library.numbers, dyn.library.numbers)  # each value in its own place
    np.testing.assert_allclose(d.gravity(q, model.theta), dyn.gravity(q, model.theta), rtol=1e-12)


def test_separate_caches_build_under_their_own_locks(model, tmp_path, monkeypatch):
    """A build from the committed generated/ only reads it: its lock is in the cache, so two caches
    never wait for each other's compile, and no lock file is made in the checkout."""
    from contextlib import contextmanager

    import hydrogen.fileio as fileio
    from hydrogen.runtime.build import repo_generated_dir
    from hydrogen.runtime.cachedir import build_lock_path

    committed = repo_generated_dir() / model.name
    a, b = (build_lock_path(committed, tmp_path / r, committed=True) for r in ("a", "b"))
    assert a != b and a.is_relative_to(tmp_path / "a") and b.is_relative_to(tmp_path / "b")
    mine = tmp_path / "mine"
    assert build_lock_path(mine, tmp_path / "a", committed=False) == mine  # a folder the build may write

    real, taken = fileio.locked, []

    @contextmanager
    def recorded(path, timeout=None):
        taken.append(Path(path))
        with real(path, timeout):
            yield
    monkeypatch.setattr(fileio, "locked", recorded)
    fast = ("-O0", "-fPIC", "-std=c99")  # the lock is under test, not the optimiser
    for root in (tmp_path / "a", tmp_path / "b"):
        dyn = hydrogen.build(model, cache=root, cflags=fast)
        assert dyn.library.generated_dir == committed
    assert taken and a in taken and b in taken
    assert not [p for p in taken if p.is_relative_to(repo_generated_dir())], taken


def test_a_build_after_an_edit_of_a_rig_part_derives_the_plant_alone(tmp_path, monkeypatch, package_copy):
    """The committed folder is stale for the plant's function alone (a module of hydrogen/plant
    edited): a build's cache folder starts as a copy of it and derives the plant's function alone."""
    import hydrogen.runtime.build as build_mod
    from hydrogen.codegen import generate as gen

    model = hydrogen.load_model("loader_crane")
    path = package_copy / "plant" / "valve.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    committed = build_mod.repo_generated_dir() / model.name
    assert gen.stale_parts(model, committed) == {"plant": True, "drivers": True}
    folder = build_mod.generated_dir_for(model, tmp_path / "cache", controllers=())
    assert folder != committed
    derived, real = [], gen.derive
    monkeypatch.setattr(gen, "derive", lambda *a, **k: (derived.append(k.get("core", True)), real(*a, **k))[1])
    dyn = hydrogen.build(model, cache=tmp_path / "cache", controllers=())
    assert derived == [("plant",)]
    assert gen.check(model, folder) == []
    assert sorted(os.listdir(folder)) == sorted(os.listdir(committed))
    assert dyn.leg_lengths(model.neutral_pose).shape == (model.n_cylinders,)


def test_a_part_generated_alone_is_reported_as_such(tmp_path, monkeypatch, package_copy):
    """The build's progress says what it derives and what it wrote: the plant's function alone and
    the loop drivers, not every function."""
    from hydrogen.codegen import generate as gen

    model = hydrogen.load_model("loader_crane")
    path = package_copy / "plant" / "valve.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    events = []
    hydrogen.build(model, cache=tmp_path / "cache", controllers=(), progress=events.append)
    said = {e.stage: e.detail for e in events}
    assert said["generating"].startswith("deriving the plant (SymPy)")
    import hydrogen.runtime.build as build_mod
    folder = build_mod.generated_dir_for(model, tmp_path / "cache", controllers=())
    n = len(gen.read_manifest(folder)["functions"])
    assert said["generated"].startswith(f"1 of {n} functions again") and "loop drivers rendered again" in said["generated"]


def test_the_loop_structs_mirror_each_robots_own_layout():
    """Two robots alike but for their joint encoders have signals structs of their own (the encoders'
    reading is a field only where fitted): the ctypes mirrors are never shared between them."""
    import ctypes

    from hydrogen.layout import loop_context, model_summary
    from hydrogen.runtime.loop import _structs
    summary = model_summary(hydrogen.load_model("excavator_arm"))
    bare = {**summary, "joint_encoders": False}
    with_enc, without = (_structs(loop_context({"model": s}))[3] for s in (summary, bare))
    assert "q_enc" in dict(with_enc._fields_) and "q_enc" not in dict(without._fields_)
    assert ctypes.sizeof(with_enc) == ctypes.sizeof(without) + 8 * summary["n"]


def test_a_folder_argument_that_is_no_path_and_an_unknown_function_are_named(dyn, tmp_path):
    """build(cache=5) and export(5) raised the os module's TypeError; a function the build lacks was a
    bare KeyError of its name."""
    from hydrogen.export import export

    for kw in ({"cache": 5}, {"generated": 3.0}):
        with pytest.raises(hydrogen.InputError, match=rf"build: {list(kw)[0]} must be a folder's path"):
            hydrogen.build(dyn.model, **kw)
    with pytest.raises(hydrogen.OutputPathError, match="export: out_dir must be a folder's path .* got int 5"):
        export(5, dyn=dyn)
    with pytest.raises(KeyError, match=r"no generated function 'ctrl_nonexistent' in this build; its functions: "
                                       r".*leg_lengths"):
        dyn.functions["ctrl_nonexistent"]
