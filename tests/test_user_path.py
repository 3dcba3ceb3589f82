"""A new user's path: model edits reach the C; concurrent and interrupted builds; ABI mismatches."""
import json
import multiprocessing as mp
from pathlib import Path

import numpy as np
import pytest

import hydrogen
import hydrogen.runtime.build
from hydrogen.codegen import generate as gen
from hydrogen.model import default_model_path
from hydrogen.runtime.library import GeneratedLibrary


def _edited_model(tmp_path, old, new):
    text = default_model_path().read_text()
    assert old in text
    path = tmp_path / "my.toml"
    path.write_text(text.replace(old, new))
    return hydrogen.load_model(path)


def test_geometry_edit_reaches_the_compiled_functions(tmp_path, model, dyn):
    mine = _edited_model(tmp_path, "0.15] }", "0.2] }")  # platform joints 5 cm higher
    # -O0: that the edit reaches the C is under test, not the optimiser (5x faster to compile)
    d2 = hydrogen.build(mine, cache=tmp_path / "cache", cflags=("-O0", "-fPIC", "-std=c99"))
    q = model.neutral_pose
    assert np.all(d2.leg_lengths(q) < dyn.leg_lengths(q) - 0.04)
    # and the unchanged default is still served from the committed code, untouched
    assert d2.library.path != dyn.library.path


def test_mass_edit_needs_no_regeneration(tmp_path, model):
    heavy = _edited_model(tmp_path, "mass = 250.0", "mass = 300.0")
    assert heavy.baked_hash() == model.baked_hash()
    assert heavy.theta[0] == 300.0


def _generate_forced(folder):
    gen.generate(hydrogen.load_model(), Path(folder), force=True)


def test_two_processes_generating_at_once_leave_a_valid_folder(tmp_path, model):
    folder = tmp_path / "gen"
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_generate_forced, args=(str(folder),)) for _ in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(300)
        assert p.exitcode == 0
    assert gen.check(model, folder) == []
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".gen.") and p.name != ".gen.lock"]


def _build_in(cache):
    # -O0: the lock and the shared cache are under test, not the optimiser (5x faster to compile)
    d = hydrogen.build(cache=Path(cache), cflags=("-O0", "-fPIC", "-std=c99"))
    print(d.library.path)


def test_two_processes_building_at_once_share_one_cache(tmp_path):
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_build_in, args=(str(tmp_path),)) for _ in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(300)
        assert p.exitcode == 0
    libs = list((tmp_path / "build").glob("*/*.so"))
    assert len(libs) == 1  # the second waited for the lock and found the first one's build


def test_library_from_another_casadi_version_is_reported(dyn):
    manifest = json.loads(json.dumps(dyn.library.manifest))
    manifest["casadi_version"] = "0.0.1"
    with pytest.raises(hydrogen.BuildCacheError, match="CasADi"):
        GeneratedLibrary(dyn.library.path, manifest, numbers=dyn.model.numbers)


def test_missing_library_file_is_reported(tmp_path, dyn):
    with pytest.raises(hydrogen.BuildCacheError, match="cannot load"):
        GeneratedLibrary(tmp_path / "nope.so", dyn.library.manifest, numbers=dyn.model.numbers)


def test_library_built_with_another_integer_size_is_detected(tmp_path, dyn):
    """casadi_int of 4 bytes (a build with -Dcasadi_int=int) must not be called with 8-byte buffers."""
    from hydrogen.runtime.compiler import Toolchain, compile_library
    manifest = dyn.library.manifest
    gen_dir = dyn.library.generated_dir
    sources = [gen_dir / e["source"] for e in manifest["functions"]][:1]
    entry = manifest["functions"][0]
    lib = compile_library(sources, "abi_test", Toolchain(cflags=("-O0", "-fPIC", "-std=c99", "-Dcasadi_int=int")),
                          cache=tmp_path)
    with pytest.raises(hydrogen.BuildCacheError, match="casadi_int of 4 bytes"):
        GeneratedLibrary(lib, {**manifest, "functions": [entry]}, numbers=dyn.model.numbers)
