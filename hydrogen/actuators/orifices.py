"""The valve's orifice laws every kind shares (SymPy, with numpy twins), eq. (57) of the paper.

A valve metering edge pair: with spool position u (m) and underlap d (m), one orifice is open for
u ≥ −d with opening (u + d), the other for u ≤ d with opening (d − u). The flow per unit flow gain
through the pair is

    w(u) = (u + d) r_up [u ≥ −d]  +  (u − d) r_down [u ≤ d],

r_up, r_down the roots of the two pressure drops (√Pa): continuous, piecewise linear and increasing
in u (the three branches u < −d, |u| ≤ d, u > d). :func:`branch_inverse` inverts that form for any
positive r_up, r_down, which also covers the sum of such forms with positive weights (a four-way
valve's two chambers). The numpy twins (``*_np``) compute the same numbers, tested equal.
"""
from __future__ import annotations

import numpy as np

from .declarations import sp

__all__ = ["SYMPY", "NUMPY", "orifice_terms", "signed_sqrt_linearised", "branch_inverse", "clipped_root",
           "orifice_terms_np", "signed_sqrt_linearised_np", "branch_inverse_np", "clipped_root_np"]


# --- SymPy (the derivation layer) ---------------------------------------------------------------

def orifice_terms(u, d, up, down):
    """w(u) above as the sum of the two orifices' terms, each where its orifice is open (u ≥ −d:
    root ``up``; u ≤ d: root ``down``): the same values as the three-branch form (a term plus an
    exact zero outside the underlap), for two masked terms instead of four and a sum."""
    return sp.Piecewise(((u + d) * up, sp.Not(sp.Lt(u, -d, evaluate=False), evaluate=False)),
                        (0, True), evaluate=False) \
        + sp.Piecewise(((u - d) * down, sp.Le(u, d, evaluate=False)), (0, True), evaluate=False)


def clipped_root(drop):
    """√max(drop, 0) (√Pa): the root of a measured pressure drop, which noise can make negative;
    for a drop ≥ 0 exactly the root."""
    return sp.sqrt(sp.Max(drop, 0))


def signed_sqrt_linearised(x, x_lin):
    """sign(x)√|x|, replaced by x/√x_lin for |x| < x_lin (finite slope at 0, as hydraulic simulators do).

    Continuous at |x| = x_lin; used by the simulated plant only, never by a controller.
    """
    return sp.Piecewise(
        (x / sp.sqrt(x_lin), sp.Lt(sp.Abs(x), x_lin, evaluate=False)),
        (sp.sign(x) * sp.sqrt(sp.Abs(x)), True),
        evaluate=False,
    )


def branch_inverse(w, d, up, down):
    """The u with (u + d) up [u ≥ −d] + (u − d) down [u ≤ d] = w, on its three branches, for up,
    down > 0 (the caller keeps them away from 0). The form is continuous and increasing in u, so the
    branch is found from its values at u = ±d."""
    w_hi = 2 * d * up      # value at u = +d
    w_lo = -2 * d * down   # value at u = −d
    # evaluate=False: w may be a large controller expression; SymPy must not try to order it.
    return sp.Piecewise(
        (w / up - d, sp.Gt(w, w_hi, evaluate=False)),
        (w / down + d, sp.Lt(w, w_lo, evaluate=False)),
        ((w - d * up + d * down) / (up + down), True),
        evaluate=False,
    )


# --- numpy twins (the numeric layer) --------------------------------------------------------------

def orifice_terms_np(u, d, up, down):
    """Numeric :func:`orifice_terms` (broadcasts)."""
    u = np.asarray(u, float)
    return np.where(u >= -d, (u + d) * up, 0.0) + np.where(u <= d, (u - d) * down, 0.0)


def clipped_root_np(drop):
    """Numeric :func:`clipped_root`."""
    return np.sqrt(np.maximum(drop, 0.0))


def signed_sqrt_linearised_np(x, x_lin):
    """Numeric :func:`signed_sqrt_linearised`."""
    x = np.asarray(x, float)
    return np.where(np.abs(x) < x_lin, x / np.sqrt(x_lin), np.sign(x) * np.sqrt(np.abs(x)))


def branch_inverse_np(w, d, up, down):
    """Numeric :func:`branch_inverse`."""
    w = np.asarray(w, float)
    return np.where(w > 2 * d * up, w / up - d,
                    np.where(w < -2 * d * down, w / down + d, (w - d * up + d * down) / (up + down)))


# --- backends: the same law written once over either layer ----------------------------------------

class _Backend:
    """The operations a two-chamber law needs, in one layer (``SYMPY`` or ``NUMPY``): ``root`` (the
    clipped root), ``smooth_root`` (the plant's), ``floor_root`` (√max(Δp, eps)), ``log``, ``terms``
    (:func:`orifice_terms`) and ``inverse`` (:func:`branch_inverse`)."""

    def __init__(self, name, root, smooth_root, floor_root, log, terms, inverse):
        self.name, self.root, self.smooth_root, self.floor_root = name, root, smooth_root, floor_root
        self.log, self.terms, self.inverse = log, terms, inverse

    def __repr__(self):
        return f"<orifice backend {self.name}>"


#: The SymPy layer (the derivation).
SYMPY = _Backend("sympy", clipped_root, signed_sqrt_linearised,
                 lambda drop, eps: sp.Max(clipped_root(drop), sp.sqrt(sp.Float(eps))),
                 lambda x: sp.log(x), orifice_terms, branch_inverse)
#: The numpy layer (simulator, identification).
NUMPY = _Backend("numpy", clipped_root_np, signed_sqrt_linearised_np,
                 lambda drop, eps: np.maximum(clipped_root_np(drop), np.sqrt(eps)),
                 np.log, orifice_terms_np, branch_inverse_np)
