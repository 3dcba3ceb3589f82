"""The simulated plant: rigid bodies driven by the cylinders, chamber pressures (56)-(57).

The plant's blocks (:mod:`hydrogen.plant`) composed into one right-hand side, wired by the names of
the signals they hand each other (:class:`Composition`). x is their states in the layout's order
(:func:`hydrogen.plant.plant_layout`: [q (n), q̇ (n), pressures (one block per actuator, its kind's
states: p_c of a three-way cylinder, p_A, p_B of a four-way one), spool (m), spool rate (m), and the
supply pressure p_s (Pa) where the supply is not constant]); input u = spool command (m, metres),
then theta, gamma1, gamma2 and each block's input of numbers (:func:`hydrogen.plant.plant_inputs`:
``friction``, ``valve``).

Each block's ``Symbolic`` declares the signals its outputs read (``READS``), write (``WRITES``) and add
to (``ADDS``: a sum a block declares in ``SUMS``, formed as one intermediate once every block adding
to it has), and writes its law once: ``outputs(c)`` (the signals it gives the others) and
``derivatives(c)`` (its states' rates), both over a :class:`Composition` ``c``. The outputs run in an
order that writes every signal before it is read; then the derivatives, in :data:`BLOCKS` order.
"""
from __future__ import annotations

import sympy as sp

from ..plant import BLOCKS, block, plant_inputs
from .kinematics import rate_symbols
from .rigid_body import theta_symbols

__all__ = ["plant_rhs", "Composition", "PlantWiringError"]

#: The signals the plant takes from outside its blocks (its inputs besides x and each block's numbers).
EXTERNAL = ("u", "theta", "gamma1", "gamma2")


class PlantWiringError(RuntimeError):
    """The plant's blocks do not compose: a signal read that no block writes, written twice, or a cycle."""


class Composition:
    """The signals of the plant's blocks while they are composed, by name: the states, the plant's
    inputs and what each block's ``outputs`` gives; the states' rates and the intermediates (symbols
    bound to values, evaluated first, in order) the blocks produce. ``c[name]`` reads a signal."""

    def __init__(self, model, sums: dict):
        self.model = model
        self.signals, self.rates, self.intermediates = {}, {}, []
        self._sums, self._terms = dict(sums), {name: [] for name in sums}
        self.block = None  # the block composing now, for messages

    def __getitem__(self, name: str):
        if name not in self.signals and name in self._sums:  # a sum: every block adding to it has run
            terms = self._terms[name]
            value = sp.Matrix([sp.Add(*parts) for parts in zip(*terms)])
            self.provide(name, value, prefix=self._sums[name])
        if name not in self.signals:
            raise PlantWiringError(f"plant block '{self.block}' reads the signal '{name}', which no block writes")
        return self.signals[name]

    def provide(self, name: str, value, prefix: str | None = None) -> None:
        """Write signal ``name``; with ``prefix``, as an intermediate: symbols ``<prefix>_i`` bound to ``value``."""
        if name in self.signals:
            raise PlantWiringError(f"plant block '{self.block}' writes the signal '{name}', written already")
        if prefix is not None:
            symbols = rate_symbols(prefix, len(value))
            self.intermediates.append((symbols, value))
            value = symbols
        self.signals[name] = value

    def add(self, name: str, terms) -> None:
        """Add ``terms`` (one per entry) to the sum ``name``."""
        if name not in self._sums:
            raise PlantWiringError(f"plant block '{self.block}' adds to '{name}', which no block declares a sum")
        self._terms[name].append(list(terms))

    def stage(self, intermediates) -> None:
        """Intermediates ``(symbols, value)`` to evaluate first, in order."""
        self.intermediates.extend(intermediates)

    def rate(self, name: str, value) -> None:
        """The rate of state ``name``."""
        self.rates[name] = value


def _declared(mod, what: str) -> tuple:
    return tuple(getattr(mod.Symbolic, what, ()))


def _output_order(mods: list, given: set) -> list:
    """The blocks in an order that writes every signal before a block's outputs read it: :data:`BLOCKS`
    order where it does (the first ready block each time)."""
    writers = {}
    for mod in mods:
        for name in _declared(mod, "WRITES") + _declared(mod, "ADDS"):
            writers.setdefault(name, []).append(_name(mod))
    pending, done, out = list(mods), set(), []
    while pending:
        for mod in pending:
            if all(r in given or (r in writers and all(w in done for w in writers[r]))
                   for r in _declared(mod, "READS")):
                break
        else:
            missing = sorted({(_name(m), r) for m in pending for r in _declared(m, "READS")
                              if r not in given and r not in writers})
            if missing:
                raise PlantWiringError("plant block '{}' reads the signal '{}', which no block writes".format(*missing[0]))
            raise PlantWiringError(f"the plant blocks {', '.join(_name(m) for m in pending)} read each other's "
                                   "outputs in a cycle")
        pending.remove(mod)
        done.add(_name(mod))
        out.append(mod)
    return out


def _name(mod) -> str:
    return mod.__name__.rsplit(".", 1)[-1]


def plant_rhs(model):
    """Symbols and right-hand side of the plant: returns (inputs, xdot, intermediates)."""
    m = model.n_cylinders
    mods = [block(name) for name in BLOCKS]
    sums = {k: v for mod in mods for k, v in getattr(mod.Symbolic, "SUMS", {}).items()}
    c = Composition(model, sums)
    for mod in mods:
        c.block = _name(mod)
        for name, symbols in getattr(mod.Symbolic, "states", lambda model: {})(model).items():
            c.provide(name, symbols)
    x = sp.Matrix([s for mod in mods for st in mod.STATES for s in c.signals[st.name]])
    external = dict(zip(EXTERNAL, (rate_symbols("u", m), theta_symbols(model), rate_symbols("gamma1", m),
                                   rate_symbols("gamma2", m))))
    # each block's input of numbers (plant_inputs), after x, u, theta, gamma1, gamma2
    params = {i.name: block(i.block).Symbolic.input(model) for i in plant_inputs(model)}
    for name, value in {**external, **params}.items():
        c.provide(name, value)
    for mod in _output_order(mods, set(c.signals)):
        c.block = _name(mod)
        mod.Symbolic.outputs(c)
    for mod in mods:
        c.block = _name(mod)
        mod.Symbolic.derivatives(c)
    xdot = sp.Matrix([r for mod in mods for st in mod.STATES for r in c.rates[st.name]])
    return [("x", x), *external.items(), *params.items()], xdot, c.intermediates
