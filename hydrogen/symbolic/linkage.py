"""A cylinder acting through a planar four-bar linkage (an excavator's bucket), SymPy.

All points in the plane of the linkage, in the frame of the link that carries the driven joint's
pivot (the excavator's stick), m; angles in rad, counter-clockwise.

* O2 (origin): the driven revolute joint (stick–bucket); the crank O2→B is rigid with the driven
  link: B = r2 (cos(q + φ0), sin(q + φ0)), q the joint angle, φ0 its offset (``crank_offset``).
* O4 = ``rocker_pivot``: the pivot of the rocker (the idler link) on the carrying link, rocker
  length r4 (``rocker``).
* C: the pin joining rocker and coupler (coupler length r3, C to B), where the cylinder's rod end
  acts; the cylinder's other end is at P = ``cylinder_base`` on the carrying link.
* ``branch`` = +1 or −1: which of the two assemblies (C to the left or to the right of B→O4).

C is the intersection of the circles (B, r3) and (O4, r4): with d = O4 − B, D = |d|,
a = (r3² − r4² + D²)/(2D), h = √(r3² − a²),

    C = B + (a/D) d + branch · (h/D) perp(d),   perp(x, y) = (−y, x),

and the cylinder length l(q) = |C − P|. Its Jacobian by the chain rule,
dl/dq = ((C − P)/l) · (∂C/∂B) dB/dq, dB/dq = r2 (−sin(q + φ0), cos(q + φ0)).
A description gives the linkage as a ``linkage`` table on a ``[[cylinders]]`` entry
(:func:`from_description` turns its points, in the links' frames, into this plane);
:meth:`hydrogen.symbolic.tree.SymbolicTree.cylinder_stages` then uses l(q) and dl/dq for that
cylinder's length and row of JL.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from .constants import baked

__all__ = ["FourBar", "four_bar_length", "from_description", "plane_basis"]


@dataclass(frozen=True)
class FourBar:
    """The linkage geometry (m, rad; see the module docstring)."""

    crank: float            # r2 = |O2 B|
    crank_offset: float     # φ0: angle of O2→B at q = 0
    coupler: float          # r3 = |B C|
    rocker: float           # r4 = |O4 C|
    rocker_pivot: tuple     # O4 (x, y)
    cylinder_base: tuple    # P (x, y)
    branch: int = 1         # ±1, the assembly

    def __post_init__(self):
        for name in ("crank", "coupler", "rocker"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"four-bar linkage: {name} must be a positive length (m), got {v!r}")
        if self.branch not in (1, -1):
            raise ValueError(f"four-bar linkage: branch must be +1 or -1, got {self.branch!r}")
        for name in ("rocker_pivot", "cylinder_base"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (2,) or not np.all(np.isfinite(v)):
                raise ValueError(f"four-bar linkage: {name} must be a point (x, y) in m, got {getattr(self, name)!r}")

    def lengths(self, q) -> np.ndarray:
        """l(q) (m) at the angles ``q`` (rad, array), numerically (NaN where it does not assemble)."""
        q = np.asarray(q, float)
        B = self.crank * np.stack([np.cos(q + self.crank_offset), np.sin(q + self.crank_offset)], -1)
        d = np.asarray(self.rocker_pivot, float) - B
        D = np.linalg.norm(d, axis=-1)
        a = (self.coupler ** 2 - self.rocker ** 2 + D ** 2) / (2 * D)
        with np.errstate(invalid="ignore"):
            h = np.sqrt(self.coupler ** 2 - a ** 2)
        perp = np.stack([-d[..., 1], d[..., 0]], -1)
        C = B + (a / D)[..., None] * d + self.branch * (h / D)[..., None] * perp
        return np.linalg.norm(C - np.asarray(self.cylinder_base, float), axis=-1)

    def symbolic(self, q, name: str | None = None):
        """(l, dl/dq, C) as SymPy expressions of the joint angle ``q`` (a symbol or expression);
        ``name``: the cylinder's, which names the numbers (:func:`four_bar_length`)."""
        return four_bar_length(self, q, name)

    def numbers(self, name: str) -> dict:
        """``{"<name>.linkage.<field>[k]": value}``: the geometry's numbers as the derivation names
        them (m, rad), the ones derived from the description (the crank, its offset, the cylinder
        base in the joint's plane) included."""
        out = {f"{name}.linkage.{k}": float(getattr(self, k)) for k in ("crank", "crank_offset", "coupler", "rocker")}
        for k in ("rocker_pivot", "cylinder_base"):
            out.update({f"{name}.linkage.{k}[{i}]": float(v) for i, v in enumerate(getattr(self, k))})
        return out

    def check_assembles(self, q) -> None:
        """ValueError naming the first angle of ``q`` (rad, array) at which the coupler and rocker
        cannot meet (|r3 − r4| ≤ D ≤ r3 + r4 fails): there the length has no value."""
        q = np.atleast_1d(np.asarray(q, float))
        B = self.crank * np.stack([np.cos(q + self.crank_offset), np.sin(q + self.crank_offset)], -1)
        D = np.linalg.norm(np.asarray(self.rocker_pivot, float) - B, axis=-1)
        bad = (D >= self.coupler + self.rocker) | (D <= abs(self.coupler - self.rocker))
        if bad.any():
            k = int(np.argmax(bad))
            raise ValueError(f"four-bar linkage does not assemble at q = {float(q[k])!r} rad: |B O4| = {D[k]:.6g} m "
                             f"is outside ({abs(self.coupler - self.rocker):.6g}, {self.coupler + self.rocker:.6g}) m")


def four_bar_length(geometry: FourBar, q, name: str | None = None):
    """(l, dl/dq, C): the cylinder length (m), its Jacobian (m/rad) and the rod-end pin C (2-vector).
    ``name`` (the cylinder's) names the numbers as :meth:`FourBar.numbers` does."""
    g = geometry
    num = {k: baked(v, name and k) for k, v in g.numbers(name or "").items()}
    pre = f"{name or ''}.linkage."
    r2, r3, r4, phi0 = (num[pre + k] for k in ("crank", "coupler", "rocker", "crank_offset"))
    O4 = sp.Matrix([num[f"{pre}rocker_pivot[{i}]"] for i in range(2)])
    P = sp.Matrix([num[f"{pre}cylinder_base[{i}]"] for i in range(2)])
    # C as a function of the crank pin B (symbols), then the chain rule through B(q)
    bx, by = sp.symbols("linkage_Bx linkage_By", real=True)
    B = sp.Matrix([bx, by])
    d = O4 - B
    D = sp.sqrt(d.dot(d))
    a = (r3 ** 2 - r4 ** 2 + D ** 2) / (2 * D)
    h = sp.sqrt(r3 ** 2 - a ** 2)
    C_of_B = B + (a / D) * d + g.branch * (h / D) * sp.Matrix([-d[1], d[0]])
    dC_dB = C_of_B.jacobian(B)
    angle = q + phi0
    B_q = sp.Matrix([r2 * sp.cos(angle), r2 * sp.sin(angle)])
    dB_dq = sp.Matrix([-r2 * sp.sin(angle), r2 * sp.cos(angle)])
    at_q = {bx: B_q[0], by: B_q[1]}
    C = C_of_B.subs(at_q)
    rel = C - P
    l = sp.sqrt(rel.dot(rel))
    dl_dq = (rel.T * dC_dB.subs(at_q) * dB_dq)[0, 0] / l
    return l, dl_dq, C


def plane_basis(axis) -> tuple:
    """(e1, e2): an orthonormal basis of the plane normal to the unit ``axis`` (joint frame) with
    e1 × e2 = axis, so that a rotation by q about the axis turns plane coordinates by +q; e1 is the
    joint frame's x axis projected on the plane (its y axis if x is the axis)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    for guess in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        e1 = guess - (guess @ a) * a
        if np.linalg.norm(e1) > 1e-6:
            e1 = e1 / np.linalg.norm(e1)
            return e1, np.cross(a, e1)
    raise ValueError(f"no plane basis for axis {axis!r}")  # pragma: no cover - a is a unit vector


def from_description(joint, cylinder_base, rocker_pivot, crank_pin, coupler: float, rocker: float,
                     branch: int, tolerance: float = 1e-6):
    """The :class:`FourBar` of a description's linkage on revolute ``joint`` (a
    :class:`hydrogen.model.Joint`): ``cylinder_base`` and ``rocker_pivot`` are points in the joint's
    parent link's frame, ``crank_pin`` (where the coupler pins on the driven link) in its child's
    frame at q = 0, m. The plane is the one normal to the joint axis through the joint: a point's
    plane coordinates are (e1 · x, e2 · x) of :func:`plane_basis`, x in the joint frame.

    Returns ``(geometry, offsets)``: ``offsets`` maps each point's name to its coordinate along the
    axis (m); ValueError when they differ by more than ``tolerance`` (the linkage is not planar) or
    the crank pin is on the axis."""
    from ..tree import rpy_matrix
    R_o = rpy_matrix(joint.origin_rpy)
    o = np.asarray(joint.origin_xyz, float)
    a = np.asarray(joint.axis, float) / np.linalg.norm(joint.axis)
    e1, e2 = plane_basis(a)
    pts = {"cylinder base (from.point)": R_o.T @ (np.asarray(cylinder_base, float) - o),
           "rocker_pivot": R_o.T @ (np.asarray(rocker_pivot, float) - o),
           "crank_pin": np.asarray(crank_pin, float)}
    offsets = {k: float(v @ a) for k, v in pts.items()}
    ref = offsets["rocker_pivot"]
    for k, w in offsets.items():
        if abs(w - ref) > tolerance:
            raise ValueError(f"{k} is {w:.6g} m along joint '{joint.name}''s axis and the rocker pivot "
                             f"{ref:.6g} m: the linkage's points must lie in one plane normal to the axis")
    plane = {k: (float(v @ e1), float(v @ e2)) for k, v in pts.items()}
    bx, by = plane["crank_pin"]
    crank = float(np.hypot(bx, by))
    if crank < tolerance:
        raise ValueError(f"crank_pin is on joint '{joint.name}''s axis: the coupler would have no lever")
    geometry = FourBar(crank=crank, crank_offset=float(np.arctan2(by, bx)), coupler=float(coupler),
                       rocker=float(rocker), rocker_pivot=plane["rocker_pivot"],
                       cylinder_base=plane["cylinder base (from.point)"], branch=branch)
    return geometry, offsets
