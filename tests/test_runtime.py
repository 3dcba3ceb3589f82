"""Build cache, compiler selection and failure reporting of the runtime."""
import os

import numpy as np
import pytest

import hydrogen
from hydrogen.runtime.compiler import Toolchain, compile_library


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
