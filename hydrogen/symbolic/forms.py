"""Which form the rigid body takes: the closed form or the staged one, chosen by cost.

Both forms give the same D, C, G, Y and τ (:mod:`hydrogen.symbolic.rigid_body`); they differ in the
size of the code. A description picks one with ``rigid_body_form`` ("closed", "staged"); "auto" (the
default) derives the rigid-body functions of both forms, converts them to CasADi and keeps the one
with fewer instructions (:func:`form_costs`), ties to the closed form (:data:`FORMS` order). The
counted functions are those the controllers and the simulator evaluate (:data:`COUNTED`); their
totals rank the forms as the controllers' own counts do on the shipped robots and a spatial leg
(``tests/test_forms.py``, ``docs/guide/codegen.md``).

Three cases are decided without counting: a tree the staged form cannot represent (a floating joint)
takes the closed form; a tree at least :data:`STAGED_DEPTH` moving joints deep the staged one,
whose closed form grows about 3.5× per link (its derivation alone would cost minutes by 5 links);
and so does a tree with an oblique joint (:func:`oblique_joints`: a rotated origin or a tilted
axis, as a URDF from CAD has), whose closed form is a product of full rotations.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .constants import folded

__all__ = ["FORMS", "COUNTED", "DECIDING", "STAGED_DEPTH", "rigid_body_form", "form_costs", "with_form", "oblique_joints",
           "turned_joints"]

#: The forms, in the order that breaks a tie of instruction counts.
FORMS = ("closed", "staged")
#: The rigid-body functions whose CasADi instructions decide "auto": q̈ (the simulator's plant; by the
#: articulated-body algorithm in either form wherever there is no floating joint, so it counts the
#: same in both), the regressor Y and D a + C w + G (the controllers' dynamics: counted as the form's
#: own D a + C q̇ + G, not the generated function's Newton-Euler pass) and D itself.
COUNTED = ("mass_matrix", "regressor", "inverse_dynamics", "forward_dynamics")
#: What the decision derives: :data:`COUNTED` but q̈, whose count is the same in both forms where
#: they are compared (a tree the staged form takes: the articulated-body algorithm either way).
DECIDING = ("mass_matrix", "regressor", "inverse_dynamics")
#: The depth (moving joints on one path) from which "auto" stages without counting: on the 4-link
#: chain of benchmarks/bench_scaling.py the staged form is smaller in every function already.
STAGED_DEPTH = 4

_CHOSEN = {}  # baked hash -> form (the decision costs a derivation of both: once per process)


def with_form(model, form: str):
    """``model`` with its ``rigid_body_form`` set to ``form`` (a copy; its baked hash records it)."""
    return dataclasses.replace(model, rigid_body_form=form)


def form_costs(model, form: str, names=COUNTED) -> dict:
    """CasADi instructions (with CSE) of the rigid-body functions ``names`` (of :data:`COUNTED`) of
    ``model`` in ``form`` ("closed" or "staged"), by function name; only those are derived."""
    from ..codegen.sympy_to_casadi import to_casadi_function
    from .body_functions import rigid_body_functions

    return {sf.name: int(to_casadi_function(sf).n_instructions())
            for sf in rigid_body_functions(with_form(model, form), form_dynamics=True, names=names)}


def rigid_body_form(model) -> str:
    """The form ``model``'s rigid body takes: its ``rigid_body_form`` unless "auto", else the closed
    form for a tree the staged form cannot represent, the staged one from :data:`STAGED_DEPTH`
    moving joints deep, and otherwise the one whose :data:`COUNTED` functions total fewer
    instructions (ties: :data:`FORMS` order). Deterministic: counts of the same derivation."""
    forced = getattr(model, "rigid_body_form", "auto")
    if forced != "auto":
        return forced
    key = model.baked_hash()
    if key not in _CHOSEN:
        with folded():  # the same form whether the numbers fold or stay inputs
            _CHOSEN[key] = _cheaper(model)
    return _CHOSEN[key]


def oblique_joints(model) -> list:
    """Names of the joints whose frame is turned off the parent's axes: a moving joint with an origin
    rotation (rpy) that is not zero or an axis that is not a coordinate axis (entries other than 0
    and ±1), and a fixed joint with an origin rotation that a moving joint hangs below (a mount at an
    angle). A URDF exported from CAD is made of them. In the closed form each is a full 3×3 of sines
    and cosines (of symbols, with the numbers as inputs) multiplied along the chain and differentiated
    for C: a 3-DOF leg of such joints derived its closed form's composite law for more than 5 minutes
    against 6 s staged (benchmarks/bench_cold.py). A fixed joint with nothing moving below it (a
    payload, a sensor housing) is not one: the closed form merges its links into the body above
    (:meth:`~hydrogen.symbolic.tree.SymbolicTree.bodies`), where its rotation is a constant."""
    children = {}
    for j in model.joints:
        children.setdefault(j.parent, []).append(j)

    def moves_below(link):
        return any(c.type != "fixed" or moves_below(c.child) for c in children.get(link, ()))

    def oblique(j):
        axis = np.asarray(j.axis, dtype=float)
        turned = bool(np.any(np.asarray(j.origin_rpy, dtype=float) != 0.0))
        if j.type == "fixed":
            return turned and moves_below(j.child)
        return turned or bool(np.any((axis != 0.0) & (np.abs(axis) != 1.0)))
    return [j.name for j in model.joints if j.type in ("revolute", "prismatic", "fixed") and oblique(j)]


def turned_joints(model) -> list:
    """Names of the joints whose frame is turned off the parent's axes (:func:`oblique_joints`), a
    fixed one with nothing moving below it included: where a payload is merged into its body at an
    angle, that body's parameters hold the mount's sines and cosines."""
    oblique = set(oblique_joints(model))
    return [j.name for j in model.joints
            if j.name in oblique or (j.type == "fixed" and np.any(np.asarray(j.origin_rpy, float) != 0.0))]


def _cheaper(model) -> str:
    from .kinematics import pose_symbols
    from .rigid_body import theta_symbols
    from .tree import SymbolicTree

    tree = SymbolicTree(with_form(model, "closed"), pose_symbols(model), theta_symbols(model))
    if not tree.staged_applies():
        return "closed"
    if tree.depth() >= STAGED_DEPTH or oblique_joints(model):
        return "staged"
    totals = {f: sum(form_costs(model, f, DECIDING).values()) for f in FORMS}
    return min(FORMS, key=lambda f: (totals[f], FORMS.index(f)))
