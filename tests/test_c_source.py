"""The edits of CasADi's C (hydrogen.codegen.c_source): same results, NULL inputs still zeros."""
import ctypes
import re

import casadi as ca
import numpy as np
import pytest

from hydrogen.codegen.c_source import hoist_input_reads, mark_unused
from hydrogen.codegen.generate import write_casadi
from hydrogen.runtime.compiler import Toolchain, compile_library


def _functions():
    x, p, unused = ca.SX.sym("x", 3), ca.SX.sym("p", 5), ca.SX.sym("unused", 2)
    f = ca.Function("f", [x, p, unused], [ca.vertcat(x[0] * p[4] + ca.sin(x[2]) / (1 + p[1] ** 2), p[0] * p[3]),
                                          ca.exp(x[1]) - p[2]])
    g = ca.Function("g", [p, x], [ca.vertcat(f(x, p, 0)[0] * x[1], p[3])])  # calls f
    return [f, g]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("c_source")
    write_casadi(_functions(), "fun", folder)
    lib = compile_library([folder / "fun.c"], "fun", cache=folder / "cache")
    return folder / "fun.c", ctypes.CDLL(str(lib))


def _call(lib, fun, values):
    """Evaluate ``fun`` in the compiled C; an input given as None is passed as a NULL pointer."""
    sizes = [ctypes.c_longlong() for _ in range(4)]
    getattr(lib, f"{fun.name()}_work")(*map(ctypes.byref, sizes))
    n_arg, n_res, n_iw, n_w = (s.value for s in sizes)
    dbl = ctypes.POINTER(ctypes.c_double)
    inputs = [None if v is None else np.ascontiguousarray(v, dtype=float) for v in values]
    arg = (dbl * n_arg)(*[ctypes.cast(None, dbl) if v is None else v.ctypes.data_as(dbl) for v in inputs])
    outputs = [np.zeros(fun.nnz_out(i)) for i in range(fun.n_out())]
    res = (dbl * n_res)(*[o.ctypes.data_as(dbl) for o in outputs])
    iw, w = (ctypes.c_longlong * max(n_iw, 1))(), (ctypes.c_double * max(n_w, 1))()
    assert getattr(lib, fun.name())(arg, res, iw, w, 0) == 0
    return outputs


def test_every_element_read_is_hoisted_and_the_source_is_warning_free(built):
    source = built[0].read_text()
    assert not re.search(r"arg\[\d+\]\? arg\[\d+\]\[", source)  # every read goes through a pointer
    assert "hg_in1[4]" in source and "static const casadi_real hg_zeros[5] = {0};" in source
    assert "hg_in2" not in source.split("static int casadi_f0")[1].split("static int")[0]  # unread input


def test_the_compiled_functions_equal_casadi_and_null_inputs_read_as_zeros(built):
    _, lib = built
    rng = np.random.default_rng(3)
    for fun in _functions():
        values = [rng.normal(size=fun.nnz_in(i)) for i in range(fun.n_in())]
        for k in range(fun.n_in() + 1):  # all inputs given, then each one NULL in turn
            given = [None if i == k else v for i, v in enumerate(values)]
            expected = fun(*[np.zeros(fun.nnz_in(i)) if v is None else v for i, v in enumerate(given)])
            expected = expected if isinstance(expected, tuple) else (expected,)
            for got, want in zip(_call(lib, fun, given), expected):
                np.testing.assert_allclose(got, np.asarray(want).ravel(), rtol=1e-14, atol=1e-14)


def test_sources_without_casadis_forms_pass_unchanged():
    text = "int main(void) { return arg[1]? arg[1][0] : 0; }\n"
    assert hoist_input_reads(mark_unused(text)) == text
    # a function CasADi writes that reads no input keeps no pointer and no zeros
    folder_text = ("static int casadi_f0(const casadi_real** arg, casadi_real** res, casadi_int* iw, "
                   "casadi_real* w, int mem) {\n  res[0][0] = 1;\n  return 0;\n}\n")
    marked = mark_unused(folder_text)
    assert hoist_input_reads(marked) == marked and "(void)arg;" in marked


def test_compile_is_clean_under_pedantic_warnings(built, tmp_path):
    import subprocess

    proc = subprocess.run([Toolchain().executable(), "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                           "-fsyntax-only", str(built[0])], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
