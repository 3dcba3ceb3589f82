"""Translate SymPy expressions into CasADi SX by walking the expression tree.

No strings are evaluated and nothing is lambdified: every node type has an
explicit rule. A memo keyed by the (hashable, structurally compared) SymPy node
means a subexpression that occurs many times becomes one SX node, so shared
work stays shared in the generated C. A node without a rule raises
:class:`~hydrogen.errors.UnsupportedExpressionError` naming its type.
:func:`to_casadi_function` makes a derived function's casadi.Function (the
derivation's form choice counts its instructions, code generation writes its C).
"""
from __future__ import annotations

import casadi as ca
import sympy as sp
from sympy.functions.elementary.piecewise import ExprCondPair

from ..errors import UnsupportedExpressionError

__all__ = ["SympyToCasadi", "to_casadi", "to_casadi_function", "shape_of"]

_UNARY = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan,
    sp.asin: ca.asin, sp.acos: ca.acos, sp.atan: ca.atan,
    sp.sinh: ca.sinh, sp.cosh: ca.cosh, sp.tanh: ca.tanh,
    sp.exp: ca.exp, sp.log: ca.log, sp.Abs: ca.fabs, sp.sign: ca.sign,
    sp.floor: ca.floor, sp.ceiling: ca.ceil,
}

_RELATIONAL = {
    sp.StrictLessThan: lambda a, b: a < b,
    sp.LessThan: lambda a, b: a <= b,
    sp.StrictGreaterThan: lambda a, b: a > b,
    sp.GreaterThan: lambda a, b: a >= b,
    sp.Equality: lambda a, b: a == b,
    sp.Unequality: lambda a, b: a != b,
}


class SympyToCasadi:
    """Converter with a symbol table and a memo shared across calls.

    Parameters
    ----------
    symbols : dict
        Maps each SymPy Symbol to a scalar CasADi SX (usually an element of an
        input vector).
    """

    def __init__(self, symbols: dict):
        self._memo = dict(symbols)

    def define(self, symbols, value) -> None:
        """Bind each SymPy symbol of the Matrix ``symbols`` to the matching entry of SX ``value``.

        Used for intermediates: quantities computed numerically (e.g. a linear
        solve) or once (e.g. an observer rate) and then referred to by symbol.
        """
        rows, cols = symbols.shape
        for i in range(rows):
            for j in range(cols):
                self._memo[symbols[i, j]] = value[i, j]

    def __call__(self, expr):
        """Convert a SymPy scalar expression or Matrix (→ dense SX of the same shape)."""
        if isinstance(expr, sp.MatrixBase):
            out = ca.SX.zeros(*expr.shape)
            for i in range(expr.shape[0]):
                for j in range(expr.shape[1]):
                    out[i, j] = self.scalar(expr[i, j])
            return ca.densify(out)
        return self.scalar(sp.sympify(expr))

    def scalar(self, expr):
        # Iterative post-order walk: deep expression trees must not hit Python's recursion limit.
        memo = self._memo
        stack = [(expr, False)]
        while stack:
            node, ready = stack.pop()
            if node in memo:
                continue
            if not ready and node.args and not node.is_Atom:
                stack.append((node, True))
                stack.extend((a, False) for a in node.args if a not in memo)
                continue
            memo[node] = self._node(node)
        return memo[expr]

    def _node(self, node):
        m = self._memo
        if node.is_Symbol:
            raise UnsupportedExpressionError(
                f"symbol {node} has no CasADi input; declare it as an input of the function")
        if node.is_Integer or node.is_Rational or node.is_Float:
            return ca.SX(float(node))
        if node is sp.pi:
            return ca.SX(float(sp.pi))
        if node is sp.E:
            return ca.SX(float(sp.E))
        if node in (sp.true, sp.false):
            return ca.SX(1.0 if node is sp.true else 0.0)
        if isinstance(node, (sp.Add, sp.Mul)):
            # SX.binary builds the node `+` / `*` would (same simplifications), without the operator's
            # overload resolution, which costs several times the node itself on large controllers
            op = ca.OP_ADD if isinstance(node, sp.Add) else ca.OP_MUL
            out = m[node.args[0]]
            for a in node.args[1:]:
                out = ca.SX.binary(op, out, m[a])
            return out
        if isinstance(node, sp.Pow):
            base, exp = node.args
            b = m[base]
            if exp.is_Integer:
                return b ** int(exp)  # CasADi folds small integer powers into sq / products
            if exp == sp.Rational(1, 2):
                return ca.sqrt(b)
            if exp == sp.Rational(-1, 2):
                return 1 / ca.sqrt(b)
            return ca.power(b, m[exp])
        func = type(node)
        if func in _UNARY:
            return _UNARY[func](m[node.args[0]])
        if func is sp.atan2:
            return ca.atan2(m[node.args[0]], m[node.args[1]])
        if func in (sp.Max, sp.Min):
            op = ca.fmax if func is sp.Max else ca.fmin
            out = m[node.args[0]]
            for a in node.args[1:]:
                out = op(out, m[a])
            return out
        if func in _RELATIONAL:
            return _RELATIONAL[func](m[node.args[0]], m[node.args[1]])
        if func is sp.And:
            out = m[node.args[0]]
            for a in node.args[1:]:
                out = ca.logic_and(out, m[a])
            return out
        if func is sp.Or:
            out = m[node.args[0]]
            for a in node.args[1:]:
                out = ca.logic_or(out, m[a])
            return out
        if func is sp.Not:
            return ca.logic_not(m[node.args[0]])
        if func is sp.Piecewise:
            # Fold from the last branch: if c1 then e1 else (if c2 then e2 else …).
            pairs = list(node.args)
            expr_last, cond_last = pairs[-1]
            if cond_last is not sp.true:
                raise UnsupportedExpressionError(
                    f"Piecewise without a final 'True' branch cannot be translated: {node}")
            out = m[expr_last]
            for e, c in reversed(pairs[:-1]):
                out = ca.if_else(m[c], m[e], out)
            return out
        if isinstance(node, ExprCondPair):
            return None  # handled by Piecewise through its children
        raise UnsupportedExpressionError(
            f"no CasADi translation for SymPy node {func.__name__}: {node}")


def to_casadi(expr, symbols: dict):
    """One-shot conversion of ``expr`` (scalar or Matrix) with the given symbol table."""
    return SympyToCasadi(symbols)(expr)


def shape_of(mat) -> tuple:
    """(rows, cols) of a SymPy Matrix (a scalar counts as 1×1)."""
    return tuple(mat.shape) if isinstance(mat, sp.MatrixBase) else (1, 1)


def input_symbols(inputs) -> tuple:
    """``(table, [(name, SX)])`` for SymPy ``inputs`` [(name, Matrix)]: one CasADi SX symbol matrix per
    input, of its shape, and the table from each SymPy entry to its SX entry (what
    :class:`SympyToCasadi` converts with)."""
    table, named = {}, []
    for name, mat in inputs:
        rows, cols = shape_of(mat)
        sym = ca.SX.sym(name, rows, cols)
        for i in range(rows):
            for j in range(cols):
                table[mat[i, j]] = sym[i, j]
        named.append((name, sym))
    return table, named


def to_casadi_function(sf, c_name: str | None = None, cse: bool = True) -> ca.Function:
    """Build the CasADi Function of a :class:`~hydrogen.symbolic.functions.SymbolicFunction`.

    Each input symbol maps to one element of a dense SX input; one converter
    is shared by all outputs so their common subexpressions are one node.
    Intermediates ``(symbols, value)`` are converted in order and bound to their
    symbols; ``value`` may be ``("inverse", M)`` for a numeric matrix inverse or
    ``("solve", A, b)`` for the solution of A x = b.
    """
    table, named = input_symbols(sf.inputs)
    sx_in = [sym for _, sym in named]
    conv = SympyToCasadi(table)
    for symbols, value in getattr(sf, "intermediates", []):
        if isinstance(value, tuple) and value[0] == "inverse":
            # A numeric inverse (CasADi's symbolic QR solve), never a SymPy closed form.
            mat = conv(value[1])
            sx = ca.solve(mat, ca.SX.eye(mat.shape[0]))
        elif isinstance(value, tuple) and value[0] == "solve":
            sx = ca.solve(conv(value[1]), conv(value[2]))  # A x = b without forming A⁻¹
        else:
            sx = conv(value)
        conv.define(symbols, sx)
    sx_out = [conv(sp.Matrix(expr) if not isinstance(expr, sp.MatrixBase) else expr)
              for _, expr in sf.outputs]
    return ca.Function(c_name or sf.name, sx_in, sx_out,
                       [n for n, _ in sf.inputs], [n for n, _ in sf.outputs], {"cse": cse})
