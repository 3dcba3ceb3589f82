"""The plant's chamber-pressure states of a model: one contiguous block per actuator, its kind's
``STATES`` in order (``pc`` for a three-way cylinder; ``pA``, ``pB`` for a four-way one).

The controllers' ``pc`` input, the plant state's pressure part, the pressure noise and the ``pc``
log are this vector (Pa). Plain data (no SymPy): the numeric layer and the templates use it.
"""
from __future__ import annotations

import numpy as np

from .actuators import actuator
from .actuators.declarations import state_bounds

__all__ = ["blocks", "n_pressures", "state_names", "bounds", "uniform_three_way", "split", "forces",
           "equilibrium"]

_THREE_WAY = "three_way_cylinder"


def blocks(model) -> list:
    """[(start, stop)] of each cylinder's block in the pressure vector."""
    out, start = [], 0
    for c in model.cylinders:
        k = len(actuator(c.kind).STATES)
        out.append((start, start + k))
        start += k
    return out


def n_pressures(model) -> int:
    """Number of pressure states (the sum of the actuators' state counts)."""
    return sum(len(actuator(c.kind).STATES) for c in model.cylinders)


def state_names(model) -> list:
    """``"<cylinder>.<state>"`` of each pressure state, in vector order."""
    return [f"{c.name}.{s.name}" for c in model.cylinders for s in actuator(c.kind).STATES]


def bounds(model) -> tuple:
    """(lower, upper) arrays (n_pressures,), Pa: each state's bounds from its kind (e.g. [0, P_s]
    for p_c, [P_t, P_s] for p_A, p_B), the simulator's clip."""
    pairs = [b for c in model.cylinders
             for b in state_bounds(actuator(c.kind).STATES, actuator(c.kind).parameters(c.table))]
    return np.array([p[0] for p in pairs], float), np.array([p[1] for p in pairs], float)


def uniform_three_way(model) -> bool:
    """True when every actuator is a three-way cylinder (one pressure per cylinder)."""
    return all(c.kind == _THREE_WAY for c in model.cylinders)


def split(model, p) -> list:
    """The blocks of pressure vector(s) ``p`` (..., n_pressures) as tuples of arrays, per cylinder."""
    p = np.asarray(p, float)
    return [tuple(p[..., j] for j in range(a, b)) for a, b in blocks(model)]


def forces(model, p, ps=None) -> np.ndarray:
    """Actuator forces (..., m), N (N·m), from pressure vector(s) ``p`` (the numeric laws), at the
    supply pressure ``ps`` (Pa, one per row of ``p``: a supply state's) or, when None, each actuator's
    own ``supply_pressure`` (a three-way cylinder's rod side is at the supply pressure)."""
    return force_law(model)(p, ps)


def force_law(model):
    """:func:`forces` of ``model`` as a function of ``(p, ps=None)``, each actuator's law and parameters
    looked up once (a loop calls it every period)."""
    laws = [(a, b, actuator(c.kind).Numeric.force, actuator(c.kind).parameters(c.table))
            for (a, b), c in zip(blocks(model), model.cylinders)]

    def law(p, ps=None):
        p = np.asarray(p, float)
        supply = {} if ps is None else {"supply_pressure": np.asarray(ps, float)}
        return np.stack([force(tuple(p[..., j] for j in range(a, b)), {**par, **supply}) for a, b, force, par in laws],
                        axis=-1)
    return law


def equilibrium(model, f) -> np.ndarray:
    """A pressure vector whose forces are ``f`` (m,): each kind's ``equilibrium_pressures``."""
    out = []
    for fi, c in zip(np.asarray(f, float), model.cylinders):
        out += [float(v) for v in actuator(c.kind).Numeric.equilibrium_pressures(fi, actuator(c.kind).parameters(c.table))]
    return np.array(out)
