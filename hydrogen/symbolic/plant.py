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
to it has), and writes its law once: ``states(model)`` (its states' symbols, where it declares
``STATES``), ``outputs(c)`` (the signals it gives the others; none: it gives nothing) and
``derivatives(c)`` (its states' rates, one each, where it has states), over a :class:`Composition`
``c``. The outputs run in an order that writes every signal before it is read, each reading only
what its ``READS`` declares; then the derivatives, in :data:`BLOCKS` order, which may read any
signal. A wiring mistake (a signal read that no block writes or that ``READS`` does not declare, one
written twice, an add to a sum already read, a cycle, a state without a rate) is a
:class:`PlantWiringError` naming the block and the signal.
"""
from __future__ import annotations

import sympy as sp

from ..errors import PlantWiringError
from ..plant import BLOCKS, block, plant_inputs
from .kinematics import rate_symbols
from .rigid_body import theta_symbols

__all__ = ["plant_rhs", "Composition", "PlantWiringError"]

#: The signals the plant takes from outside its blocks (its inputs besides x and each block's numbers).
EXTERNAL = ("u", "theta", "gamma1", "gamma2")


class Composition:
    """The signals of the plant's blocks while they are composed, by name: the states, the plant's
    inputs and what each block's ``outputs`` gives; the states' rates and the intermediates (symbols
    bound to values, evaluated first, in order) the blocks produce. ``c[name]`` reads a signal."""

    def __init__(self, model, sums: dict):
        self.model = model
        self.signals, self.rates, self.intermediates = {}, {}, []
        self._sums, self._terms, self._formed = dict(sums), {name: [] for name in sums}, set()
        self.block = None  # the block composing now, for messages
        self.reads = None  # while a block's outputs run: the signals it declares it reads (None: any)
        self.adds = None  # while a block's outputs run: the sums it declares it adds to (None: any)
        self.states = []  # the plant's states by name, in x's order

    def __getitem__(self, name: str):
        if self.reads is not None and name not in self.reads:
            raise PlantWiringError(f"plant block '{self.block}' reads the signal '{name}' in its outputs, which "
                                   "its Symbolic.READS does not declare (the order of the outputs follows READS)")
        if name not in self.signals and name in self._sums:  # a sum: every block adding to it has run
            terms = self._terms[name]
            if not terms:
                raise PlantWiringError(f"plant block '{self.block}' reads the sum '{name}', which no block adds to")
            value = sp.Matrix([sp.Add(*parts) for parts in zip(*terms)])
            self._formed.add(name)
            self.signals[name] = self._bind(name, value, self._sums[name])
        if name not in self.signals:
            raise PlantWiringError(f"plant block '{self.block}' reads the signal '{name}', which no block writes")
        return self.signals[name]

    def _bind(self, name, value, prefix):
        symbols = rate_symbols(prefix, len(value))
        self.intermediates.append((symbols, value))
        return symbols

    def provide(self, name: str, value, prefix: str | None = None) -> None:
        """Write signal ``name``; with ``prefix``, as an intermediate: symbols ``<prefix>_i`` bound to ``value``."""
        if name in self.signals or name in self._sums:
            what = "a sum the blocks add to" if name in self._sums else "written already"
            raise PlantWiringError(f"plant block '{self.block}' writes the signal '{name}', {what}")
        self.signals[name] = value if prefix is None else self._bind(name, value, prefix)

    def add(self, name: str, terms) -> None:
        """Add ``terms`` (one per entry) to the sum ``name``."""
        if name not in self._sums:
            raise PlantWiringError(f"plant block '{self.block}' adds to '{name}', which no block declares a sum")
        if self.adds is not None and name not in self.adds:
            raise PlantWiringError(f"plant block '{self.block}' adds to '{name}', which its Symbolic.ADDS does not "
                                   "declare (its outputs must run before the sum is read: declare it there)")
        if name in self._formed:
            raise PlantWiringError(f"plant block '{self.block}' adds to '{name}' after it was read: add to it in "
                                   "Symbolic.outputs (declared in ADDS), which run before any block reads it")
        self._terms[name].append(list(terms))

    def stage(self, intermediates) -> None:
        """Intermediates ``(symbols, value)`` to evaluate first, in order."""
        self.intermediates.extend(intermediates)

    def rate(self, name: str, value) -> None:
        """The rate of state ``name``."""
        if name in self.rates:
            raise PlantWiringError(f"plant block '{self.block}' gives the rate of '{name}', given already")
        if name not in self.states:
            raise PlantWiringError(f"plant block '{self.block}' gives a rate of '{name}', which is no state of the "
                                   f"plant (its states: {', '.join(self.states)})")
        if len(value) != len(self.signals[name]):
            raise PlantWiringError(f"plant block '{self.block}' gives {len(value)} rate(s) of its state '{name}', "
                                   f"which has {len(self.signals[name])} entries")
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

    def waits_for(mod) -> list:
        return [r for r in _declared(mod, "READS")
                if r not in given and not (r in writers and all(w in done for w in writers[r]))]

    while pending:
        mod = next((m for m in pending if not waits_for(m)), None)
        if mod is None:
            missing = [(_name(m), r) for m in pending for r in waits_for(m) if r not in writers]
            if missing:
                raise PlantWiringError("plant block '{}' reads the signal '{}', which no block writes".format(*missing[0]))
            waits = "; ".join(f"'{_name(m)}' reads {', '.join(repr(r) for r in waits_for(m))}" for m in pending)
            raise PlantWiringError(f"the plant blocks read each other's outputs in a cycle: {waits} (written by "
                                   "blocks still waiting)")
        pending.remove(mod)
        done.add(_name(mod))
        out.append(mod)
    return out


def _name(mod) -> str:
    return mod.__name__.rsplit(".", 1)[-1]


def _no_outputs(c) -> None:
    """A block that gives the others nothing (a state's own rate only)."""


def _check_distinct(owned) -> None:
    """Every symbol of the plant's inputs is its owner's alone (``owned``: pairs of an owner's words and
    its symbols): two blocks' symbols of one name are one symbol to SymPy, which would silently give
    one input's numbers to both. A PlantWiringError naming both owners and the symbol."""
    seen = {}
    for owner, symbols in owned:
        for sym in sp.Matrix(symbols):
            name = str(sym)
            if name in seen and seen[name] != owner:
                raise PlantWiringError(f"{owner} names a symbol '{name}' that {seen[name]} names too: each block's "
                                       "symbols need names of their own (SymPy would take the two for one)")
            if name in seen:
                raise PlantWiringError(f"{owner} names the symbol '{name}' twice: each entry needs a name of its own")
            seen[name] = owner


def _run(c: Composition, what: str, law) -> None:
    """A block's ``Symbolic.<what>`` on the composition: a mistake of its own code on this robot (a
    parameter another actuator kind lacks, a wrong index) is a PlantWiringError naming the block, the
    robot and the error, not a bare traceback from deep in the derivation."""
    try:
        law(c)
    except PlantWiringError:
        raise
    except Exception as exc:  # noqa: BLE001 - any error of a block's own law, reworded once
        raise PlantWiringError(f"plant block '{c.block}': its Symbolic.{what} failed on robot '{c.model.name}': "
                               f"{type(exc).__name__}: {exc} (a block's law joins every robot's plant: it may read "
                               "only what every actuator kind gives)") from exc


def plant_rhs(model):
    """Symbols and right-hand side of the plant: returns (inputs, xdot, intermediates)."""
    m = model.n_cylinders
    mods = [block(name) for name in BLOCKS]
    sums = {k: v for mod in mods for k, v in getattr(mod.Symbolic, "SUMS", {}).items()}
    c = Composition(model, sums)
    for mod in mods:
        c.block = _name(mod)
        names = [st.name for st in mod.STATES]
        states = mod.Symbolic.states(model) if names else {}
        if sorted(states) != sorted(names):
            raise PlantWiringError(f"plant block '{c.block}': Symbolic.states gives {sorted(states)}, its STATES "
                                   f"declare {sorted(names)}")
        for name, symbols in states.items():
            c.provide(name, symbols)
        c.states += names
    x = sp.Matrix([s for mod in mods for st in mod.STATES for s in c.signals[st.name]])
    external = dict(zip(EXTERNAL, (rate_symbols("u", m), theta_symbols(model), rate_symbols("gamma1", m),
                                   rate_symbols("gamma2", m))))
    # each block's input of numbers (plant_inputs), after x, u, theta, gamma1, gamma2
    params = {i.name: block(i.block).Symbolic.input(model) for i in plant_inputs(model)}
    _check_distinct([*((f"plant block '{_name(mod)}' (its state '{st.name}')", c.signals[st.name])
                       for mod in mods for st in mod.STATES),
                     *((f"the plant's input '{k}'", v) for k, v in external.items()),
                     *((f"plant block '{i.block}' (its input '{i.name}')", params[i.name]) for i in plant_inputs(model))])
    c.block = "plant"
    for name, value in {**external, **params}.items():
        c.provide(name, value)
    for mod in _output_order(mods, set(c.signals)):
        c.block, c.reads, c.adds = _name(mod), set(_declared(mod, "READS")), set(_declared(mod, "ADDS"))
        _run(c, "outputs", getattr(mod.Symbolic, "outputs", _no_outputs))
    c.reads = c.adds = None
    for mod in mods:
        c.block = _name(mod)
        if mod.STATES:
            _run(c, "derivatives", mod.Symbolic.derivatives)
        for st in mod.STATES:
            if st.name not in c.rates:
                raise PlantWiringError(f"plant block '{c.block}' gives no rate of its state '{st.name}' (its "
                                       "Symbolic.derivatives sets it with c.rate)")

    xdot = sp.Matrix([r for mod in mods for st in mod.STATES for r in c.rates[st.name]])
    return [("x", x), *external.items(), *params.items()], xdot, c.intermediates
