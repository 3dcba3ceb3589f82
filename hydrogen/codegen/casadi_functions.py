"""SymbolicFunction (SymPy) → casadi.Function (SX), inputs and outputs dense."""
from __future__ import annotations

import casadi as ca

from ..names import NUMBERS
from .sympy_to_casadi import SympyToCasadi, shape_of, to_casadi_function  # noqa: F401 (also its public path)

__all__ = ["to_casadi_function", "semi_implicit_step", "specialisation", "selection", "casadi_function", "shape_of"]


def casadi_function(sf, c_name: str | None = None, cache: dict | None = None) -> ca.Function:
    """The CasADi Function of any derived function: a
    :class:`~hydrogen.symbolic.functions.SymbolicFunction`, a ``Specialisation`` or a
    ``SemiImplicitStep``. ``cache`` (a dict kept by the caller) holds the conversions made, by
    function name, so a function the others are composed from is converted once."""
    from ..symbolic.functions import SemiImplicitStep, Specialisation, SymbolicFunction

    cache = {} if cache is None else cache
    if sf.name not in cache:
        if isinstance(sf, SymbolicFunction) and sf.selects in cache:
            cache[sf.name] = selection(sf, cache[sf.selects], c_name)
        elif isinstance(sf, SymbolicFunction):
            cache[sf.name] = to_casadi_function(sf, c_name)
        elif isinstance(sf, Specialisation):
            cache[sf.name] = specialisation(sf, casadi_function(sf.base, cache=cache), c_name)
        elif isinstance(sf, SemiImplicitStep):
            cache[sf.name] = semi_implicit_step(sf, c_name, cache=cache)
        else:
            raise TypeError(f"not a derived function: {sf!r}")
    fun = cache[sf.name]
    if c_name is None or c_name == fun.name():
        return fun
    # the same graph under the C name (a call of an SX function with SX arguments inlines it)
    args = [ca.SX.sym(fun.name_in(i), fun.sparsity_in(i)) for i in range(fun.n_in())]
    return ca.Function(c_name, args, fun(*args), list(fun.name_in()), list(fun.name_out()), {"cse": True})


def selection(sf, base: ca.Function, c_name: str | None = None) -> ca.Function:
    """The CasADi Function of ``sf``, whose outputs are some of ``base``'s (``sf.selects``: the same
    inputs and intermediates): ``base`` called with its inputs, those outputs kept, CSE again. The
    same C as converting ``sf`` from SymPy (the committed code is generated both ways alike), without
    converting the shared graph a second time."""
    names = list(base.name_in())
    args = [ca.SX.sym(n, base.sparsity_in(i)) for i, n in enumerate(names)]
    outs = dict(zip(base.name_out(), base.call(args)))
    kept = [k for k, _ in sf.outputs]
    return ca.Function(c_name or sf.name, args, [ca.densify(outs[k]) for k in kept], names, kept, {"cse": True})


def specialisation(spec, base: ca.Function, c_name: str | None = None) -> ca.Function:
    """The CasADi Function of a :class:`~hydrogen.symbolic.functions.Specialisation`: ``base``
    called with the fixed entries in place of its inputs' (CasADi folds x·0, 0/x, x/x as it
    builds the graph, so the terms only they fed drop out), the zeroed output rows 0; inputs and
    outputs as ``base``'s, dense."""
    names = list(base.name_in())
    args = [ca.SX.sym(n, base.sparsity_in(i)) for i, n in enumerate(names)]
    actual = [ca.SX(a) for a in args]
    for inp, idx, value in spec.fixed:
        actual[names.index(inp)][idx] = args[names.index(value[0])][value[1]] if isinstance(value, tuple) \
            else float(value)
    outs = base.call(actual)
    out_names = list(base.name_out())
    for out, start, stop in spec.zero:
        j = out_names.index(out)
        outs[j][start:stop] = ca.DM.zeros(stop - start)
    outs = [ca.densify(o) for o in outs]
    return ca.Function(c_name or spec.name, args, outs, names, out_names, {"cse": True})


def semi_implicit_step(step, c_name: str | None = None, cache: dict | None = None) -> ca.Function:
    """The CasADi Function of a :class:`~hydrogen.symbolic.functions.SemiImplicitStep`: the controller's
    inputs, then ``h`` (s), ``xc_lo``, ``xc_hi`` (then the description's numbers, if it takes them); outputs ``u`` = U(y, xc⁺) and ``xc_next`` = xc⁺ =
    clip(xc + h F, xc_lo, xc_hi). Both functions are inlined (SX) in one graph, so CSE computes
    what depends on the measurement only once."""
    ctrl, rates = (casadi_function(f, cache=cache) for f in (step.controller, step.rates))
    names = list(ctrl.name_in())
    args = [ca.SX.sym(n, *ctrl.size_in(i)) for i, n in enumerate(names)]
    ix = names.index("xc")
    h, lo, hi = ca.SX.sym("h"), ca.SX.sym("xc_lo", args[ix].shape), ca.SX.sym("xc_hi", args[ix].shape)
    moved = args[ix] + h * rates(*args)
    # the loop's clip, v < lo ? lo : (v > hi ? hi : v): a NaN rate stays NaN (fmin/fmax would drop it
    # and hide a divergence from the loop's finiteness check)
    xc_next = ca.if_else(moved < lo, lo, ca.if_else(moved > hi, hi, moved))
    u = ctrl(*args[:ix], xc_next, *args[ix + 1:])[0]
    # the description's numbers stay the last input, as in every generated function
    last = [names.index(NUMBERS)] if NUMBERS in names else []
    order = [i for i in range(len(names)) if i not in last]
    return ca.Function(c_name or step.name, [*(args[i] for i in order), h, lo, hi, *(args[i] for i in last)],
                       [u, xc_next], [*(names[i] for i in order), "h", "xc_lo", "xc_hi", *(names[i] for i in last)],
                       ["u", "xc_next"], {"cse": True})
