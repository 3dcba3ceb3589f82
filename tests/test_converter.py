import casadi as ca
import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.codegen.sympy_to_casadi import SympyToCasadi, to_casadi


def _eval(sx, syms, vals):
    f = ca.Function("f", [syms], [sx])
    return np.array(f(vals)).squeeze()


def test_operators_match_sympy(rng):
    x, y, z = sp.symbols("x y z", real=True)
    X = ca.SX.sym("X", 3)
    table = {x: X[0], y: X[1], z: X[2]}
    exprs = [
        x + 2 * y - z / 3, x * y ** 2 / z ** 3, sp.sqrt(x) + x ** sp.Rational(-1, 2), x ** 1.5,
        sp.sin(x) * sp.cos(y) + sp.tan(z), sp.exp(-x) * sp.log(z), sp.Abs(y - x) + sp.sign(y - x),
        sp.atan2(y, x), sp.Max(x, y, z) - sp.Min(x, 1), sp.pi * x,
        sp.Piecewise((x, y < 0.5), (y, sp.And(y >= 0.5, z > 1.0)), (z ** 2, True)),
    ]
    for _ in range(20):
        vals = rng.uniform(0.1, 2.0, 3)
        sub = dict(zip((x, y, z), vals))
        for e in exprs:
            assert _eval(to_casadi(e, table), X, vals) == pytest.approx(float(e.evalf(subs=sub)), rel=1e-12)


def test_shared_subexpressions_stay_shared():
    x = sp.Symbol("x", real=True)
    X = ca.SX.sym("X")
    big = sp.sin(x) * sp.cos(x) + sp.exp(x)
    conv = SympyToCasadi({x: X})
    m = conv(sp.Matrix([big ** 2, big + 1, big * x]))
    f = ca.Function("f", [X], [m], {"cse": True})
    single = ca.Function("g", [X], [conv(big)])
    # sin, cos, exp are computed once in total, not once per output
    assert f.n_instructions() < 3 * single.n_instructions()


def test_unsupported_node_is_named():
    x = sp.Symbol("x")
    with pytest.raises(hydrogen.UnsupportedExpressionError, match="gamma"):
        to_casadi(sp.gamma(x), {x: ca.SX.sym("x")})


def test_unknown_symbol_is_named():
    x, y = sp.symbols("x y")
    with pytest.raises(hydrogen.UnsupportedExpressionError, match="symbol y"):
        to_casadi(x + y, {x: ca.SX.sym("x")})
