"""The four-bar linkage's cylinder length l(q) against a geometric construction, dl/dq against
finite differences, and its checks."""
import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq

from hydrogen.symbolic.linkage import FourBar

GEOMETRY = dict(crank=0.35, crank_offset=0.4, coupler=0.55, rocker=0.5, rocker_pivot=(-0.45, 0.1),
                cylinder_base=(-2.0, 0.4))
ANGLES = np.linspace(-1.2, 1.2, 25)


def _constructed_length(g: FourBar, q):
    """l(q) built another way: the rocker angle ψ with |O4 + r4 (cos ψ, sin ψ) − B| = r3 found by
    root bracketing, the assembly picked by the side of B→O4 the pin C lies on."""
    B = g.crank * np.array([np.cos(q + g.crank_offset), np.sin(q + g.crank_offset)])
    O4, P = np.asarray(g.rocker_pivot), np.asarray(g.cylinder_base)
    pin = lambda psi: O4 + g.rocker * np.array([np.cos(psi), np.sin(psi)])  # noqa: E731
    gap = lambda psi: np.linalg.norm(pin(psi) - B) - g.coupler  # noqa: E731
    grid = np.linspace(-np.pi, np.pi, 721)
    vals = [gap(s) for s in grid]
    roots = [brentq(gap, a, b, xtol=1e-15) for a, b, va, vb in zip(grid, grid[1:], vals, vals[1:]) if va * vb < 0]
    assert len(roots) == 2
    d = O4 - B
    for psi in roots:
        C = pin(psi)
        side = np.sign(d[0] * (C - B)[1] - d[1] * (C - B)[0])
        if side == g.branch:
            return np.linalg.norm(C - P)
    raise AssertionError("no assembly on the branch")


@pytest.mark.parametrize("branch", [1, -1])
def test_length_matches_a_geometric_construction(branch):
    g = FourBar(**GEOMETRY, branch=branch)
    q = sp.Symbol("q", real=True)
    l, _, _ = g.symbolic(q)
    fn = sp.lambdify(q, l, "numpy")
    for qk in ANGLES:
        np.testing.assert_allclose(fn(qk), _constructed_length(g, qk), rtol=1e-11)


@pytest.mark.parametrize("branch", [1, -1])
def test_jacobian_matches_finite_differences(branch):
    g = FourBar(**GEOMETRY, branch=branch)
    q = sp.Symbol("q", real=True)
    l, dl, C = g.symbolic(q)
    fl, fdl = sp.lambdify(q, l, "numpy"), sp.lambdify(q, dl, "numpy")
    h = 1e-6
    fd = (fl(ANGLES + h) - fl(ANGLES - h)) / (2 * h)
    np.testing.assert_allclose(fdl(ANGLES), fd, rtol=1e-7, atol=1e-9)
    assert np.ptp(fdl(ANGLES)) > 1e-2  # the lever arm varies with q: a real linkage, not a constant
    # the pin C keeps the coupler and rocker lengths
    fC = sp.lambdify(q, C, "numpy")
    for qk in ANGLES[::6]:
        Ck = np.asarray(fC(qk), float).ravel()
        B = g.crank * np.array([np.cos(qk + g.crank_offset), np.sin(qk + g.crank_offset)])
        np.testing.assert_allclose(np.linalg.norm(Ck - B), g.coupler, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(Ck - np.asarray(g.rocker_pivot)), g.rocker, rtol=1e-12)


def test_a_linkage_that_cannot_assemble_names_the_angle():
    g = FourBar(**{**GEOMETRY, "rocker_pivot": (-1.2, 0.0)})
    with pytest.raises(ValueError, match=r"does not assemble at q = .* rad: \|B O4\| = .* is outside"):
        g.check_assembles(np.linspace(-3, 3, 61))
    FourBar(**GEOMETRY).check_assembles(np.linspace(-3, 3, 61))  # the example closes everywhere


@pytest.mark.parametrize("field,value,message", [
    ("coupler", -0.1, "coupler must be a positive length"),
    ("branch", 0, "branch must be"),
    ("rocker_pivot", (1.0,), "rocker_pivot must be a point"),
])
def test_bad_geometry_is_named(field, value, message):
    with pytest.raises(ValueError, match=message):
        FourBar(**{**GEOMETRY, field: value})
