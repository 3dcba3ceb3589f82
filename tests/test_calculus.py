"""The symbolic helpers: forward-mode time derivative and the projection of Lemma 1."""
import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.symbolic.calculus import clip, diff, diff_matrix, jacobian, matmul, projection, time_derivative


def test_time_derivative_matches_the_chain_rule(rng):
    x, y, z = sp.symbols("x y z", real=True)
    xd, yd, zd = sp.symbols("xd yd zd", real=True)
    exprs = sp.Matrix([x * y * z ** 2, sp.sin(x * y) * sp.cos(z) / (1 + x ** 2), sp.tan(y) - 3 * x ** 3 * z,
                       sp.sqrt(2 + x ** 2) * y])
    fwd = time_derivative(exprs, [((x, y, z), (xd, yd, zd))])
    chain = exprs.jacobian([x, y, z]) * sp.Matrix([xd, yd, zd])
    f = sp.lambdify([x, y, z, xd, yd, zd], list(fwd - chain))
    for _ in range(20):
        np.testing.assert_allclose(f(*rng.uniform(-1, 1, 6)), 0, atol=1e-12)


def test_time_derivative_names_what_it_cannot_differentiate():
    x = sp.Symbol("x")
    with pytest.raises(hydrogen.UnsupportedExpressionError, match="gamma"):
        time_derivative(sp.Matrix([sp.gamma(x)]), [((x,), (sp.Integer(1),))])


@pytest.mark.parametrize("estimate,rho,expected", [
    (0.5, -1.0, 0.0),   # at the lower bound, pushed down: stop
    (0.5, 1.0, 1.0),    # at the lower bound, pushed up: move
    (2.0, 1.0, 0.0),    # at the upper bound, pushed up: stop
    (2.0, -1.0, -1.0),  # at the upper bound, pushed down: move
    (1.0, -1.0, -1.0),  # inside: κ = 1
])
def test_projection_of_lemma_1(estimate, rho, expected):
    th, r = sp.symbols("th r")
    f = sp.lambdify([th, r], projection(th, r, 0.5, 2.0))
    assert f(estimate, rho) == expected


def test_projection_keeps_alpha_nonpositive(rng):
    """Lemma 1: with θ̂̇ = κρ and a ≤ θ ≤ b, α = (θ − θ̂)ᵀ(ρ − θ̂̇) ≤ 0 at the bounds as well as inside."""
    th, r = sp.symbols("th r")
    f = sp.lambdify([th, r], projection(th, r, 0.5, 2.0))
    for _ in range(200):
        theta = rng.uniform(0.5, 2.0)
        est = rng.choice([0.5, 2.0, rng.uniform(0.5, 2.0)])
        rho = rng.normal()
        assert (theta - est) * (rho - f(est, rho)) <= 1e-12


def test_clip():
    x = sp.Symbol("x")
    f = sp.lambdify([x], clip(x, -1, 2))
    assert [f(-5), f(0.5), f(7)] == [-1, 0.5, 2]


def test_projection_equals_its_direct_construction():
    """The projection puts ρ into a stand-in's canonical structure: the same expression as building
    it directly, for each type of ρ (a sum, a product with a sign, a symbol)."""
    from hydrogen.symbolic.calculus import _projection, projection

    a, lo, hi, x, y, z = sp.symbols("a lo hi x y z", real=True)
    for rho in (x * y + z, -x * (y + z) * 3, x, x * y - z ** 2 + sp.sin(x)):
        got, want = projection(a, rho, lo, hi), _projection(a, rho, lo, hi)
        assert got == want and sp.srepr(got) == sp.srepr(want)
    rho = x * y + z  # the law itself: zero when pushing outward at a bound, else ρ
    f = sp.lambdify([a, x, y, z], projection(a, rho, 0.5, 1.5))
    assert f(0.4, 1.0, -2.0, 0.0) == 0.0 and f(0.4, 1.0, 2.0, 0.0) == 2.0
    assert f(1.6, 1.0, 2.0, 0.0) == 0.0 and f(1.6, 1.0, -2.0, 0.0) == -2.0 and f(1.0, 1.0, -2.0, 0.0) == -2.0


def test_matmul_equals_sympys_product():
    x, y, z = sp.symbols("x y z", real=True)
    a = sp.Matrix([[x, 0, sp.sin(y)], [sp.Float(0.0), x * y + 1, 0]])
    b = sp.Matrix([[1, y], [0, 0], [z, sp.Float(0.0)]])
    c = sp.Matrix([[sp.cos(x)], [2]])
    assert matmul(a, b) == a * b
    assert matmul(a, b, c) == a * b * c
    assert matmul(-a, b.T.T) == (-a) * b
    with pytest.raises(sp.ShapeError):
        matmul(a, a)


def test_matmul_asks_no_entry_whether_it_is_finite():
    """SymPy's product asks whether 0 times each entry is 0 (for infinities): an assumption query
    over the whole expression, which is what made large controllers slow to derive."""
    class Wary(sp.Symbol):
        def _eval_is_finite(self):
            raise AssertionError("asked whether it is finite")

    w, x = Wary("w"), sp.Symbol("x", real=True)
    a, b = sp.Matrix([[w * x + x, w]]), sp.Matrix([[x], [1]])
    with pytest.raises(AssertionError, match="finite"):
        a * b
    assert matmul(a, b) == sp.Matrix([[(w * x + x) * x + w]])


def _same(a, b):
    """The same SymPy tree, node for node (not merely equal)."""
    return a == b and sp.srepr(a) == sp.srepr(b)


def test_diff_is_sympys_diff_node_for_node():
    """Sums, products (numbers, Floats, signs), powers (numeric and symbolic exponents, roots),
    sine and cosine of sums, nested functions; a node type without a rule (tanh, Abs, atan2) left
    to SymPy; a symbol it does not hold gives SymPy's zero."""
    x, y, z = sp.symbols("x y z", real=True)
    exprs = [x * y + 3 * x ** 2 * sp.sin(x + y), sp.Float(0.25) * x * sp.cos(2 * x) - sp.Float(1.5) * y,
             -x * (y + z) * sp.sin(x) ** 2 / (1 + x ** 2), sp.sqrt(x ** 2 + y ** 2), x ** y, sp.exp(x) * y,
             sp.sin(sp.cos(x * y)) * sp.cos(x) ** 3, sp.tanh(x * y) + sp.Abs(x - y) + sp.atan2(y, x),
             sp.sin(x) ** 2 + sp.cos(x) ** 2, sp.Rational(1, 2) * (x * sp.sin(y) + z) ** 2, z, sp.Integer(7)]
    for e in exprs:
        for s in (x, y, z, sp.Symbol("w", real=True)):
            assert _same(diff(e, s), e.diff(s)), (e, s)
    f = sp.Function("f")(x)  # not a symbol: SymPy's own rules
    assert _same(diff(x * f ** 2, f), (x * f ** 2).diff(f))
    with pytest.raises(ValueError, match="wrt"):
        diff(x * sp.sin(y), sp.sin(y))  # as SymPy refuses it
    with pytest.raises(TypeError, match="vectors"):
        jacobian(sp.Matrix([[x, y], [y, x]]), [x, y])


def test_diff_of_the_shipped_robots_mass_matrix_and_gravity():
    """∂D/∂q_k and ∂G/∂θ of every shipped robot, folded and with the numbers as inputs (the trees
    the Christoffel C and the composite law differentiate), the same nodes as SymPy's."""
    from hydrogen.symbolic.constants import folded, numbers_as_symbols
    from hydrogen.symbolic.rigid_body import gravity, mass_matrix, theta_symbols

    for name in hydrogen.models():
        model = hydrogen.load_model(name)
        q = sp.Matrix(sp.symbols(f"q0:{len(model.coordinate_names)}", real=True))
        for mode in (folded, numbers_as_symbols):
            with mode():
                th = theta_symbols(model, prefix="check_theta")
                D, G = mass_matrix(model, q, th), gravity(model, q, th)
                for k in range(len(q)):
                    assert _same(diff_matrix(D, q[k]), D.diff(q[k])), (name, mode.__name__, k)
                assert _same(jacobian(G, th), G.jacobian(th)), (name, mode.__name__)
                assert _same(jacobian(G, q), G.jacobian(q)), (name, mode.__name__)


def test_diff_skips_sympys_per_node_checks():
    """Each node is differentiated once, without SymPy's Derivative (which asks of every node's
    result whether it is zero): a sum of products of a symbol that refuses that question is
    differentiated all the same."""
    from sympy.core.cache import clear_cache

    class WaryOfZero(sp.Symbol):
        def _eval_is_zero(self):
            raise AssertionError("asked whether it is zero")

    clear_cache()  # SymPy's cache would answer for another test's symbol of the same name
    w, x = WaryOfZero("w_wary_of_zero"), sp.Symbol("x", real=True)
    e = (w * x + x ** 2) * (w + x)
    with pytest.raises(AssertionError, match="zero"):
        e.diff(x)
    assert sp.expand(diff(e, x) - ((w + 2 * x) * (w + x) + (w * x + x ** 2))) == 0
