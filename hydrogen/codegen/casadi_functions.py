"""SymbolicFunction (SymPy) → casadi.Function (SX), inputs and outputs dense."""
from __future__ import annotations

import casadi as ca
import sympy as sp

from .sympy_to_casadi import SympyToCasadi

__all__ = ["to_casadi_function", "semi_implicit_step", "shape_of"]


def shape_of(mat) -> tuple:
    """(rows, cols) of a SymPy Matrix (a scalar counts as 1×1)."""
    return tuple(mat.shape) if isinstance(mat, sp.MatrixBase) else (1, 1)


def semi_implicit_step(step, c_name: str | None = None) -> ca.Function:
    """The CasADi Function of a :class:`~hydrogen.symbolic.functions.SemiImplicitStep`: the controller's
    inputs, then ``h`` (s), ``xc_lo``, ``xc_hi``; outputs ``u`` = U(y, xc⁺) and ``xc_next`` = xc⁺ =
    clip(xc + h F, xc_lo, xc_hi). Both functions are inlined (SX) in one graph, so CSE computes
    what depends on the measurement only once."""
    ctrl, rates = to_casadi_function(step.controller), to_casadi_function(step.rates)
    names = list(ctrl.name_in())
    args = [ca.SX.sym(n, *ctrl.size_in(i)) for i, n in enumerate(names)]
    ix = names.index("xc")
    h, lo, hi = ca.SX.sym("h"), ca.SX.sym("xc_lo", args[ix].shape), ca.SX.sym("xc_hi", args[ix].shape)
    moved = args[ix] + h * rates(*args)
    # the loop's clip, v < lo ? lo : (v > hi ? hi : v): a NaN rate stays NaN (fmin/fmax would drop it
    # and hide a divergence from the loop's finiteness check)
    xc_next = ca.if_else(moved < lo, lo, ca.if_else(moved > hi, hi, moved))
    u = ctrl(*args[:ix], xc_next, *args[ix + 1:])[0]
    return ca.Function(c_name or step.name, [*args, h, lo, hi], [u, xc_next], [*names, "h", "xc_lo", "xc_hi"],
                       ["u", "xc_next"], {"cse": True})


def to_casadi_function(sf, c_name: str | None = None, cse: bool = True) -> ca.Function:
    """Build the CasADi Function of a :class:`~hydrogen.symbolic.functions.SymbolicFunction`.

    Each input symbol maps to one element of a dense SX input; one converter
    is shared by all outputs so their common subexpressions are one node.
    Intermediates ``(symbols, value)`` are converted in order and bound to their
    symbols; ``value`` may be ``("inverse", M)`` for a numeric matrix inverse or
    ``("solve", A, b)`` for the solution of A x = b.
    """
    table, sx_in = {}, []
    for name, mat in sf.inputs:
        rows, cols = shape_of(mat)
        sym = ca.SX.sym(name, rows, cols)
        for i in range(rows):
            for j in range(cols):
                table[mat[i, j]] = sym[i, j]
        sx_in.append(sym)
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
