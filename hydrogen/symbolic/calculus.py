"""Small symbolic helpers: time derivatives by the chain rule, the projection of Lemma 1."""
from __future__ import annotations

import sympy as sp

__all__ = ["time_derivative", "projection", "clip"]


def time_derivative(expr, rates: list) -> sp.Matrix:
    """d/dt of ``expr`` given (symbols, their time derivatives) pairs: Σ ∂expr/∂s · ṡ.

    ``expr`` is a column Matrix; every time-varying symbol it holds must be listed.
    """
    expr = sp.Matrix(expr)
    out = sp.zeros(*expr.shape)
    for syms, dots in rates:
        syms, dots = sp.Matrix(syms), sp.Matrix(dots)
        out += expr.jacobian(syms) * dots
    return out


def projection(estimate, rho, lower, upper) -> sp.Expr:
    """κ(a, b, ρ) ρ of Lemma 1 (eq. 18) for one parameter: stop at a bound when pushing outward."""
    # evaluate=False throughout: SymPy would otherwise query assumptions on the (large) ρ
    # to try to decide the conditions, which costs minutes and can never succeed here.
    le, ge = (lambda a, b: sp.Le(a, b, evaluate=False)), (lambda a, b: sp.Ge(a, b, evaluate=False))
    stop = sp.Or(sp.And(le(estimate, lower), le(rho, 0), evaluate=False),
                 sp.And(ge(estimate, upper), ge(rho, 0), evaluate=False), evaluate=False)
    return sp.Piecewise((sp.S.Zero, stop), (rho, True), evaluate=False)


def clip(x, lower, upper) -> sp.Expr:
    """min(max(x, lower), upper) without SymPy trying to order large arguments."""
    return sp.Min(sp.Max(x, lower, evaluate=False), upper, evaluate=False)
