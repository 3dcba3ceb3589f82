"""The reference kinds: one module each, registered here (like :mod:`hydrogen.actuators`).

A scenario's reference q_d(t) (generalized coordinates, SI: m or rad) is the neutral pose ``bias``
plus what one kind adds to it. A reference module declares

* ``KEY``: the key of the description's ``reference`` table that selects it (``reference.<KEY> =
  ...``), and ``SYNTAX``: that entry's form, for the description reference and messages;
* ``Reference``: a frozen dataclass whose first field is ``bias`` (n,), with ``parse(value, axis,
  bias)`` (a classmethod: the instance from the description's value; ``axis(c)`` resolves a
  coordinate name or index), ``__call__(t)`` (q_d and its first three derivatives at t, each (n,)),
  ``positions(t)`` and ``velocities(t)`` (vectorised over an array of times, (k, n)),
  ``amplitude()`` (per coordinate, the scale of the max-error percentages), ``frequencies()`` (Hz
  of its periodic content: empty for one that is not periodic), ``check(fail, axis, finite)`` (each
  field the C loop reads valid, else ``fail(field, what, value)``), ``config()`` (its values of
  ``FIELDS``) and ``STEP_RESPONSE`` (True: judged and plotted as a step response);
* ``FIELDS``: its part of the C loop's configuration (name, C type, params.h macro), ``COMMENT``
  (the header's words for them), ``IDLE``: the values that add nothing (a scenario whose reference is
  another kind) and ``C_BODY``: the C statements that add its q_d and derivatives into ``qd`` (4 x NQ)
  at time ``t`` from the configuration ``c``, indexing only what its runtime check allowed.

Adding a kind: write the module and its tests; the registry finds it (every module of this package
that declares ``KEY`` and ``Reference``), and the description reader, the checks, the C loop, its
configuration and the exported params.h take it from there. A kind given as a table of rows (a
coordinate, then numbers: the sines' terms, the moves) takes its ``FIELDS``, ``IDLE``, ``sizes``,
``axes``, ``config`` and row checks from one :class:`~hydrogen.references._table.RowTable`.
"""
from __future__ import annotations

import numpy as np

from ..registry import discover

__all__ = ["KINDS", "kind", "reference_kind", "BIAS_FIELD", "config_fields", "config_values", "config_sizes",
           "config_axes", "c_bodies", "syntax"]

#: The configuration field every kind adds to: the neutral pose (n,).
BIAS_FIELD = ("bias", "const double*", "P_REF_BIAS")


def _discover(path=__path__, package=__name__) -> dict:
    """``{KEY: module}`` of every module of this package declaring a kind, by key (a stable order:
    the loop's configuration lists the kinds' fields in it). ``path``, ``package``: where to look."""
    return dict(sorted(discover(package, path, ("KEY", "Reference"), lambda m: m.KEY, "reference kind").items()))


_REGISTRY = _discover()

#: The reference kinds, by the description key that selects each.
KINDS = tuple(_REGISTRY)


def kind(key: str):
    """The module of the reference kind selected by ``reference.<key>``; KeyError if there is none."""
    return _REGISTRY[key]


def reference_kind(ref):
    """The module whose ``Reference`` ``ref`` is; None for anything else."""
    return next((m for m in _REGISTRY.values() if type(ref) is m.Reference), None)


def syntax() -> str:
    """The description's forms of a reference, one per kind: "sines = [...] or step = {...}"."""
    return " or ".join(f"{m.KEY} = {m.SYNTAX}" for m in _REGISTRY.values())


def config_fields() -> tuple:
    """(comment, fields) of the reference's part of the loop configuration: the bias, then each kind's
    fields (name, C type, params.h macro), in the registry's order."""
    comment = ("reference: bias + " + ",\n * plus ".join(m.COMMENT for m in _REGISTRY.values())
               + "\n * (a coordinate outside 0..NQ-1 is ignored: the runtime refuses it before a run)")
    fields = (BIAS_FIELD, *(f for m in _REGISTRY.values() for f in m.FIELDS))
    return comment, fields


def config_values(ref) -> dict:
    """Every reference field of the loop configuration for the reference ``ref``: its bias, its own
    kind's values, every other kind's idle ones."""
    own = reference_kind(ref)
    out = {"bias": np.asarray(ref.bias, float)}
    for m in _REGISTRY.values():
        out.update(ref.config() if m is own else m.IDLE)
    return out


def config_sizes(values: dict) -> dict:
    """The number of entries each kind's configuration arrays must hold, from the configuration's
    ``values`` (the bias's is the robot's: the caller's)."""
    return {k: v for m in _REGISTRY.values() for k, v in m.sizes(values).items()}


def config_axes(values: dict) -> list:
    """Every coordinate index the C loop's reference function reads from the configuration ``values``."""
    return [a for m in _REGISTRY.values() for a in m.axes(values)]


def c_bodies() -> tuple:
    """Each kind's C statements of the loop's reference function, in the registry's order."""
    return tuple(m.C_BODY for m in _REGISTRY.values())
