"""Small symbolic helpers: time derivatives by the chain rule, the projection of Lemma 1, the
product of matrices of large entries."""
from __future__ import annotations

import sympy as sp

from ..errors import UnsupportedExpressionError

__all__ = ["time_derivative", "projection", "clip", "matmul", "diff", "jacobian", "diff_matrix"]


def time_derivative(expr, rates: list) -> sp.Matrix:
    """d/dt of ``expr`` given (symbols, their time derivatives) pairs, in forward mode.

    ``expr`` is a column Matrix; every time-varying symbol it holds must be listed.
    The derivative is built node by node over the expression DAG, each node's rate
    from its operands' values and rates (a product a·b gives ȧ·b + a·ḃ, reusing the
    node a·b already has), with unevaluated SymPy nodes so nothing is re-expanded.
    This is what forward-mode AD computes, written out symbolically: the chain-rule
    form Σ ∂expr/∂s · ṡ gives the same values but materialises every partial
    derivative first and made the Theorem 1 controller 2.5 % larger in CasADi
    instructions. With the sign rule for (−1)·a·b below, the controllers are exactly as
    large as with CasADi's own forward AD (benchmarks/bench_build.py, and a test).
    """
    rate_of = {}
    for syms, dots in rates:
        for s, r in zip(sp.Matrix(syms), sp.Matrix(dots)):
            rate_of[s] = r
    memo = {}
    for e in sp.Matrix(expr):
        _forward(e, rate_of, memo)
    return sp.Matrix([memo[e] for e in sp.Matrix(expr)])


_ZERO = sp.S.Zero


def matmul(a, b, *more) -> sp.Matrix:
    """The product ``a b`` of two SymPy matrices (or more: ``matmul(a, b, c)`` is ``(a b) c``), the
    same expressions as SymPy's ``a * b`` for entries that are finite (every expression a derivation
    here makes): each entry one ``Add`` of the products of its non-zero pairs.

    Why: SymPy's product first multiplies every non-zero entry of ``a`` by 0 to see whether it is
    infinite (0 times infinity is nan), an assumption query over the whole expression tree; on a
    controller's large entries (Wᵀ s, Yᵀ s) that query was most of the derivation."""
    return _matmul(a, b, *more)


def _matmul(a, b, *more):
    if a.cols != b.rows:
        raise sp.ShapeError(f"matmul: {a.rows}x{a.cols} times {b.rows}x{b.cols}")
    # non-zero entries only, by truthiness as SymPy's sparse form keeps them (0 and 0.0 drop)
    rows = [[(k, x) for k in range(a.cols) if (x := a[i, k])] for i in range(a.rows)]
    cols = [{k: x for k in range(b.rows) if (x := b[k, j])} for j in range(b.cols)]
    out = sp.Matrix(a.rows, b.cols, lambda i, j: sp.Add(*[x * cols[j][k] for k, x in rows[i] if k in cols[j]]))
    return _matmul(out, *more) if more else out


def diff(expr, s, memo=None):
    """∂expr/∂s for a symbol ``s``: the same expression as SymPy's ``expr.diff(s)``, node by node
    by SymPy's own rules (sums, products, powers, sine and cosine) from the operands' derivatives,
    each made once (``memo``: a dict shared by the calls on one ``s``, keyed by node). For the finite
    expressions a derivation makes, without unevaluated derivatives: where a factor is infinite
    (``zoo``, a symbol declared infinite) SymPy's nan is not reproduced.

    Why: SymPy's ``diff`` makes every node's derivative through ``Derivative``, which walks the
    node's whole subtree twice more (its free symbols, a search for unevaluated derivatives) and
    asks whether the result is zero (an assumption query): quadratic in the depth of the
    expressions D, C and the composite laws differentiate, most of the derivation's time. A node
    whose type these rules do not cover is left to SymPy (``node.diff(s)``); a test compares the
    two on the shipped robots' expressions."""
    expr = sp.sympify(expr)
    if not isinstance(s, sp.Symbol):
        return expr.diff(s)  # SymPy's own checks and rules for anything else
    memo = {} if memo is None else memo
    stack = [(expr, False)]
    while stack:
        n, ready = stack.pop()
        if n in memo:
            continue
        if not ready and type(n) in _DIFF_RULES and n.args:
            stack.append((n, True))
            stack.extend((a, False) for a in n.args if a not in memo)
            continue
        memo[n] = _diff_rule(n, s, memo)
    return memo[expr]


def jacobian(f, x) -> sp.Matrix:
    """∂f/∂x (rows: the entries of the column ``f``, columns: the symbols of ``x``): SymPy's
    ``f.jacobian(x)`` by :func:`diff`."""
    f, x = sp.Matrix(f), sp.Matrix(x)
    if 1 not in f.shape or 1 not in x.shape:
        raise TypeError(f"jacobian: f and x must be vectors, got {f.shape[0]}x{f.shape[1]} and "
                        f"{x.shape[0]}x{x.shape[1]}")
    x = list(x)
    memos = [{} for _ in x]
    return sp.Matrix(len(f), len(x), lambda i, j: diff(f[i], x[j], memos[j]))


def diff_matrix(m, s) -> sp.Matrix:
    """Each entry of the matrix ``m`` differentiated by the symbol ``s`` (SymPy's ``m.diff(s)``)."""
    memo = {}
    return sp.Matrix(m.rows, m.cols, lambda i, j: diff(m[i, j], s, memo))


def _diff_mul(n, s, memo):
    # Mul._eval_derivative_n_times's Leibniz rule at order 1: one term per factor, the others kept
    terms = []
    for kvals, c in _multinomial(len(n.args)):
        terms.append(c * sp.Mul(*[memo[a] if k else a for k, a in zip(kvals, n.args)]))
    return sp.Add(*terms)


def _multinomial(m):
    from sympy.ntheory.multinomial import multinomial_coefficients_iterator

    return multinomial_coefficients_iterator(m, 1)


def _diff_pow(n, s, memo):
    # Pow._eval_derivative: self (d(exp) log(base) + d(base) exp / base)
    base, exp = n.args
    dexp = memo[exp]
    log_term = _ZERO if dexp is _ZERO else dexp * sp.log(base)  # 0 log(b): 0 for a finite log(b)
    return n * (log_term + memo[base] * exp / base)


def _diff_function(n, s, memo):
    # Function._eval_derivative: the chain rule over the arguments whose derivative is not zero
    out = []
    for i, a in enumerate(n.args, 1):
        da = memo[a]
        if da is _ZERO or da.is_zero:
            continue
        out.append(n.fdiff(i) * da)
    return sp.Add(*out)


_DIFF_RULES = {sp.Add: lambda n, s, memo: sp.Add(*[memo[a] for a in n.args]), sp.Mul: _diff_mul,
               sp.Pow: _diff_pow, sp.sin: _diff_function, sp.cos: _diff_function}


def _diff_rule(n, s, memo):
    if n.is_Atom:
        return sp.S.One if n == s else _ZERO
    rule = _DIFF_RULES.get(type(n))
    if rule is None:
        return n.diff(s)  # SymPy's own (it finds a node without s zero first)
    if not any(memo[a] is not _ZERO for a in n.args):
        return _ZERO  # what every rule gives when no operand's derivative is other than 0
    return rule(n, s, memo)


def _add(*terms):
    terms = [t for t in terms if t is not _ZERO]
    if not terms:
        return _ZERO
    return terms[0] if len(terms) == 1 else sp.Add(*terms, evaluate=False)


def _mul(a, b):
    if a is _ZERO or b is _ZERO:
        return _ZERO
    return sp.Mul(a, b, evaluate=False)


def _forward(root, rate_of, memo):
    stack = [(root, False)]
    while stack:
        n, ready = stack.pop()
        if n in memo:
            continue
        if not ready and n.args and not n.is_Atom:
            stack.append((n, True))
            stack.extend((a, False) for a in n.args if a not in memo)
            continue
        memo[n] = _forward_rule(n, rate_of, memo)


def _product_rate(args, memo):
    """Rate of the product of ``args`` folded from the left, as the SymPy → CasADi converter
    evaluates an n-ary product: the partial products p are the converter's own nodes, so
    CasADi's CSE shares them."""
    p, dp = args[0], memo[args[0]]
    for a in args[1:]:
        dp = _add(_mul(dp, a), _mul(p, memo[a]))
        p = sp.Mul(p, a, evaluate=False)
    return dp


def _forward_rule(n, rate_of, memo):
    if n.is_Symbol:
        r = rate_of.get(n, _ZERO)
        return _ZERO if r == 0 else r
    if n.is_Number or n.is_NumberSymbol:
        return _ZERO
    if isinstance(n, sp.Add):
        return _add(*[memo[a] for a in n.args])
    if isinstance(n, sp.Mul):
        args = n.args
        if args[0] is sp.S.NegativeOne and len(args) > 1:
            # −a·b·…: CasADi turns the converter's (−1·a)·b·… into −(a·b·…), so its rate is
            # −d(a·b·…) and the sum that uses it subtracts one product rate, as CasADi's AD does
            # (the plain fold would negate ȧ·b and a·ḃ separately: one more instruction).
            return _mul(sp.S.NegativeOne, _product_rate(args[1:], memo))
        return _product_rate(args, memo)
    if isinstance(n, sp.Pow):
        b, e = n.args
        db = memo[b]
        if db is _ZERO:
            return _ZERO
        if not e.is_Number:
            raise UnsupportedExpressionError(f"time derivative of a power with a symbolic exponent: {n}")
        if e == 2:
            return _mul(_mul(sp.Integer(2), b), db)
        return _mul(_mul(e, sp.Pow(b, e - 1, evaluate=False)), db)
    arg = n.args[0] if n.args else None
    if isinstance(n, sp.sin):
        return _mul(sp.cos(arg), memo[arg])
    if isinstance(n, sp.cos):
        return _mul(sp.Mul(sp.S.NegativeOne, sp.sin(arg), evaluate=False), memo[arg])
    if isinstance(n, sp.tan):
        return _mul(_add(sp.S.One, sp.Pow(n, 2, evaluate=False)), memo[arg])
    raise UnsupportedExpressionError(f"no time-derivative rule for SymPy node {type(n).__name__}: {n}")


def projection(estimate, rho, lower, upper) -> sp.Expr:
    """κ(a, b, ρ) ρ of Lemma 1 (eq. 18) for one parameter: stop at a bound when pushing outward.

    Built on a two-symbol stand-in for a long ρ, then ρ put in its place node by node without
    SymPy's canonicalisation: And, Or and Piecewise sort and search their arguments by walking
    them as trees, which for the regressor's ρ of a deep chain cost minutes. The stand-in has ρ's
    type, and the canonical order of these arguments depends on nothing else (a test checks the
    result equals the direct construction)."""
    rho = sp.sympify(rho)
    if rho.is_Atom or type(rho) not in (sp.Add, sp.Mul):
        return _projection(estimate, rho, lower, upper)
    a, b = sp.Dummy("a", real=True), sp.Dummy("b", real=True)
    stand_in = type(rho)(a, b)
    return _put(_projection(estimate, stand_in, lower, upper), stand_in, rho)


def _projection(estimate, rho, lower, upper):
    # evaluate=False throughout: SymPy would otherwise query assumptions on the (large) ρ
    # to try to decide the conditions, which costs minutes and can never succeed here.
    le, ge = (lambda a, b: sp.Le(a, b, evaluate=False)), (lambda a, b: sp.Ge(a, b, evaluate=False))
    stop = sp.Or(sp.And(le(estimate, lower), le(rho, 0), evaluate=False),
                 sp.And(ge(estimate, upper), ge(rho, 0), evaluate=False), evaluate=False)
    return sp.Piecewise((sp.S.Zero, stop), (rho, True), evaluate=False)


def _put(expr, old, new):
    """``expr`` with the node ``old`` replaced by ``new``, every node rebuilt as it is (no re-sorting)."""
    if expr == old:
        return new
    if expr.is_Atom or not expr.has(old):
        return expr
    return sp.Basic.__new__(type(expr), *[_put(x, old, new) for x in expr.args])


def clip(x, lower, upper) -> sp.Expr:
    """min(max(x, lower), upper) without SymPy trying to order large arguments."""
    return sp.Min(sp.Max(x, lower, evaluate=False), upper, evaluate=False)
