"""The simulated plant's blocks: one module each, and the plant state's layout read off them.

A block is a module of this package that declares (:data:`BLOCKS` finds it; nothing lists it)

* ``POSITION``: its place among the blocks (the order of x and of the plant's inputs);
* ``STATES``: its parts of the plant state x (:class:`PlantState`: name, size in terms of the robot,
  unit, bounds, meaning), in order; a block with no state (friction) declares none;
* ``PARAMETERS``: the numbers its law takes besides the state (:class:`PlantParameter`); a block
  whose numbers are a plant input of their own also declares ``INPUT`` (the input's name: the
  argument of ``plant_rhs``, the loop configuration's field, the FMU's variables' prefix),
  ``input_parameters(structure)`` (those of :data:`PARAMETERS` a robot's plant takes, when some are
  structure) and ``values(scenario, model)`` (the run's numbers, from the settings the block declares
  in ``SCENARIO_SETTINGS`` and the description): :func:`plant_inputs` and :func:`input_values` read
  them for the loop, the Python engine, the exported programs and the FMU;
* ``Symbolic``: its law over SymPy, once, with the signals it reads, writes and adds to
  (``READS``, ``WRITES``, ``ADDS``; ``SUMS``), its ``outputs`` and ``derivatives``:
  :mod:`hydrogen.symbolic.plant` composes the blocks by those names into the one fused
  ``plant_rhs``; and ``Numeric``, its numpy twin where the numeric layer needs one (tested equal).

x is the blocks' states in :data:`BLOCKS` order: [q, q̇ (:mod:`.mechanics`), the chamber pressures
(:mod:`.chambers`: each actuator kind's ``STATES``, :mod:`hydrogen.pressures`), spool, spool rate
(:mod:`.valve`), and the supply pressure p_s (:mod:`.supply`) only where the supply is not constant].
A part of size 0 (a constant supply's) has no slot: the layout is the one without it. Every user of
x's parts (the Python and C loops, the FMU, the exported programs, the divergence message) reads
:func:`plant_layout`. Plain data: importing this package imports the blocks' declarations, not SymPy.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

import numpy as np

from ..loop_logs import RESERVED as LOG_NAMES  # the run's own logs: no plant output takes their names
from ..setting import is_number

__all__ = ["FUNCTION", "BLOCKS", "SIZES", "PlantState", "PlantParameter", "PlantInput", "Slot", "block", "plant_layout",
           "state_size", "slot", "entry_names", "describe_entries", "state_vector", "initial_state", "outputs",
           "sensor_numbers", "plant_inputs", "input_values",
           "input_record", "actuator_settings", "structure_flag"]


#: The generated function the blocks are composed into (:mod:`hydrogen.symbolic.plant`): the plant
#: state's rate. Its manifest entry records the hash of this folder, so an edit of a block derives
#: it alone again (:func:`hydrogen.codegen.generate.plant_hash`).
FUNCTION = "plant_rhs"


#: The robot sizes a plant state's size is given in: what each entry stands for.
SIZES = {"n": "coordinates", "m": "actuators", "n_pressures": "pressure states",
         "supply": "supplies (1 where the supply is not constant, else 0)"}


@dataclass(frozen=True)
class PlantState:
    """A part of the plant state x as a block declares it.

    name
        Its name (``q``, ``pc``, ``spool_rate``): the symbols' prefix and the layout's key.
    size
        One entry per what: a key of :data:`SIZES` (``"n"``: per coordinate, ``"m"``: per actuator,
        ``"n_pressures"``: per pressure state).
    unit
        One unit for every entry, or a rule taking the model and giving one per entry.
    doc
        What it is, for messages and comments.
    lower, upper
        Each entry's range (±inf: none): a number, or a rule taking the model and giving one per
        entry. The plant's integration holds the pressure states within theirs; every part's are its
        range in the FMU's variables (and the pressures' the log checks').
    initial
        Each entry's value where a run starts (the Python and C loops, the exported programs, the
        FMU's start parameter), unless the run sets the part itself (the pose, the pressures holding it
        still): a number, a rule taking the model and giving one per entry, or the name of a scenario
        setting (a string: the block's own, in its ``SCENARIO_SETTINGS``) whose value it takes.
    output
        The plant's output: logged by both loops under its name, the run's result's ``plant[name]``,
        columns of its CSV log and, in the plant FMU, outputs ``<name>.<entry>`` with start
        parameters ``<name>_start.<entry>``; a port a controller may read by its name.
    noise
        For an output: the name of the block's scenario setting (in its ``SCENARIO_SETTINGS``) that is
        the standard deviation of its sensor, in its unit: a channel of the noise row after the
        loop's own (:mod:`hydrogen.sensors`), which the controller's reading carries; empty: an ideal
        sensor (its true value).
    resolution
        For an output with a sensor (``noise``): the name of the block's scenario setting that is the
        sensor's resolution, in its unit (0: none; one number, or one per entry where the setting
        takes ``entries``): the reading, noise included, is rounded to its grid as the actuators'
        travel sensors round theirs (``quantization_l``); empty: no rounding.
    bias
        For an output with a sensor: the name of the block's scenario setting that is the sensor's
        constant offset, in its unit (one number, or one per entry): the reading is the true value
        plus the bias plus the noise, then rounded; empty: none.
    """

    name: str
    size: str
    unit: object
    doc: str
    lower: object = -math.inf
    upper: object = math.inf
    initial: object = 0.0
    output: bool = False
    noise: str = ""
    resolution: str = ""
    bias: str = ""

    @property
    def label(self) -> str:
        """Its name as the comments write it ("spool rate")."""
        return self.name.replace("_", " ")


@dataclass(frozen=True)
class PlantParameter:
    """A number a block's law takes: ``name``, ``unit`` (a string, or a rule taking an actuator's
    :class:`~hydrogen.actuators.declarations.Travel` for a per-actuator parameter in that actuator's own
    unit), ``doc``; ``per_actuator``: one per actuator (else one for the rig).

    ``ideal``: its value in the controller's own model (the delay predictor's: the block doing nothing,
    or keeping its law finite). ``lower`` (``strict``: it must exceed it) and ``upper`` (a number, a
    rule taking the scenario; None: none): the range a run's value keeps (:func:`input_values` refuses
    one outside it, naming the block's input, the actuator and the parameter), which the FMU declares."""

    name: str
    unit: object
    doc: str
    per_actuator: bool = False
    ideal: float = 0.0
    lower: float | None = None
    strict: bool = False
    upper: object = None

    def unit_of(self, travel=None) -> str:
        """Its unit (for a per-actuator parameter, on an actuator of ``travel``)."""
        return self.unit(travel) if callable(self.unit) else self.unit

    def upper_of(self, scenario):
        """Its upper bound in ``scenario`` (None: none)."""
        return self.upper(scenario) if callable(self.upper) else self.upper


@dataclass(frozen=True)
class PlantInput:
    """A plant input a block declares: ``name`` (``plant_rhs``'s argument, the loop configuration's
    field), ``block`` (its module's name), the ``parameters`` a robot's plant takes, per actuator,
    actuator after actuator, and ``doc`` (the block's ``INPUT_DOC``: where the numbers come from)."""

    name: str
    block: str
    parameters: tuple
    doc: str = ""

    @property
    def width(self) -> int:
        """Numbers per actuator."""
        return len(self.parameters)

    @property
    def ideal(self) -> tuple:
        """One actuator's numbers in the controller's own model (the delay predictor's)."""
        return tuple(p.ideal for p in self.parameters)


@dataclass(frozen=True)
class Slot:
    """A part of x in a model's layout: ``name``, its ``block`` (module name), ``size_name`` (a key of
    :data:`SIZES`), ``start`` and ``size`` (entries), per-entry ``units``, ``lower``, ``upper`` and
    ``entries`` (what each entry belongs to: a coordinate, an actuator, a pressure state), ``doc``,
    per-entry ``initial`` values (NaN where a scenario setting gives them: ``initial_setting``),
    ``output``, ``noise``, ``resolution`` and ``bias`` (:class:`PlantState`)."""

    name: str
    block: str
    size_name: str
    start: int
    size: int
    units: tuple
    lower: tuple
    upper: tuple
    entries: tuple
    doc: str
    initial: tuple = ()
    output: bool = False
    initial_setting: str | None = None
    noise: str = ""
    resolution: str = ""
    bias: str = ""

    @property
    def stop(self) -> int:
        return self.start + self.size

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)

    @property
    def label(self) -> str:
        """Its name as the comments write it ("spool rate")."""
        return self.name.replace("_", " ")


def block(name: str):
    """The module of plant block ``name``."""
    return importlib.import_module(f"{__name__}.{name}")


def structure_flag(structure, key: str) -> bool:
    """Whether ``structure`` (a model, or a manifest's model summary) has the structure ``key`` (an
    attribute of the model, a key of the summary: ``seal_friction``)."""
    return bool(structure.get(key) if isinstance(structure, dict) else getattr(structure, key))


def plant_inputs(structure) -> tuple:
    """The plant's inputs the blocks declare (:class:`PlantInput`), in :data:`BLOCKS` order, for a
    robot's ``structure``: its model (each block's ``input_parameters``), or its manifest's model
    summary (the parameters recorded there at generation, :func:`input_record`; a summary without the
    record: each block's rule on it). They follow ``plant_rhs``'s x, u, theta, gamma1 and gamma2."""
    recorded = structure.get("plant_inputs") if isinstance(structure, dict) else None
    out = []
    for name in BLOCKS:
        mod = block(name)
        if getattr(mod, "INPUT", None):
            if recorded is not None and mod.INPUT in recorded:
                by_name = {p.name: p for p in mod.PARAMETERS}
                unknown = [k for k in recorded[mod.INPUT] if k not in by_name]
                if unknown:
                    from ..errors import PlantWiringError
                    raise PlantWiringError(f"the manifest records parameter(s) {unknown} of the plant input "
                                           f"'{mod.INPUT}', which block '{name}' does not declare: generate the "
                                           "robot's code again")
                pars = tuple(by_name[k] for k in recorded[mod.INPUT])
            else:
                pars = tuple(mod.input_parameters(structure))
            out.append(PlantInput(mod.INPUT, name, pars, getattr(mod, "INPUT_DOC", "")))
    return tuple(out)


def actuator_settings() -> dict:
    """``{key: check}`` of what a scenario may give per actuator for the blocks (``actuators.<name>.<key>``:
    the valve's spool response, the friction's row or seal table), each block's ``ACTUATOR_SETTINGS``;
    ``check(scenario, actuator name, value)`` raises a ScenarioError naming it, or returns True where
    the value is to be checked as the scenario's own field of that name (a friction row). The block's
    ``values`` reads the value from the scenario's ``actuators`` itself."""
    out = {}
    for name in BLOCKS:
        out.update(getattr(block(name), "ACTUATOR_SETTINGS", {}))
    return out


def input_record(model) -> dict:
    """``{input: [parameter names]}`` of ``model``'s plant inputs: what a manifest records, so that the
    loop's layout reads each input's width off the manifest whatever structure decides it."""
    return {i.name: [p.name for p in i.parameters] for i in plant_inputs(model)}


def input_values(scenario, model) -> dict:
    """Each plant input's numbers for a run of ``scenario`` on ``model``: ``{name: (m, width) array}``,
    each block's own rule (its ``values``), in the actuators' own units. A ScenarioError for a number
    outside the range its parameter declares, naming the input, the actuator and the parameter."""
    from ..errors import PlantWiringError, ScenarioError
    out = {}
    for i in plant_inputs(model):
        values = np.asarray(block(i.block).values(scenario, model), float)
        if values.shape != (model.n_cylinders, i.width):
            raise PlantWiringError(f"plant block '{i.block}': values() gives numbers of shape {values.shape}, its "
                                   f"input '{i.name}' takes ({model.n_cylinders}, {i.width}) (actuators, parameters)")
        for a, row in zip(model.cylinders, values):
            for par, v in zip(i.parameters, row.tolist()):
                hi = par.upper_of(scenario)
                low = par.lower is not None and (v <= par.lower if par.strict else v < par.lower)
                if not np.isfinite(v) or low or (hi is not None and v > hi):
                    rng = (f"{'>' if par.strict else '>='} {par.lower!r}" if par.lower is not None else "")
                    rng += (" and " if rng and hi is not None else "") + (f"<= {hi!r}" if hi is not None else "")
                    unit = par.unit_of(a.travel)
                    raise ScenarioError(f"scenario '{scenario.name}': {i.name}.{a.name}.{par.name} = {v!r} must be "
                                        f"finite{' and ' + rng if rng else ''}{f' ({unit})' if unit else ''}")
        out[i.name] = values
    return out


def _sizes(model) -> dict:
    """The size of each :data:`SIZES` entry for ``model``, and the names of its entries."""
    from ..pressures import state_names
    coords, cyls, press = list(model.coordinate_names), [c.name for c in model.cylinders], state_names(model)
    return {"n": coords, "m": cyls, "n_pressures": press, "supply": block("supply").entries(model)}


def _per_entry(value, model, size: int) -> tuple:
    v = value(model) if callable(value) else value
    if isinstance(v, (str, int, float)):
        return (v,) * size
    v = tuple(v)
    if len(v) != size:
        raise ValueError(f"a plant state declares {len(v)} entries, its size is {size}")
    return v


def plant_layout(model, blocks=None) -> tuple:
    """The plant state's layout of ``model``: one :class:`Slot` per declared state, in x's order (the
    states of each block of ``blocks``, module objects; None: :data:`BLOCKS`). Plain data."""
    mods = [block(b) for b in BLOCKS] if blocks is None else list(blocks)
    names = _sizes(model)
    out, start = [], 0
    for mod in mods:
        for st in mod.STATES:
            entries = tuple(names[st.size])
            size = len(entries)
            if not size:
                continue
            lower = tuple(float(v) for v in _per_entry(st.lower, model, size))
            upper = tuple(float(v) for v in _per_entry(st.upper, model, size))
            setting = st.initial if isinstance(st.initial, str) else None  # a scenario's, per run
            initial = (math.nan,) * size if setting else tuple(float(v) for v in _per_entry(st.initial, model, size))
            out.append(Slot(st.name, mod.__name__.rsplit(".", 1)[-1], st.size, start, size,
                            _per_entry(st.unit, model, size), lower, upper, entries, st.doc, initial, st.output,
                            setting, st.noise, st.resolution, st.bias))
            start += size
    return tuple(out)


def state_size(layout) -> int:
    """Number of entries of x."""
    return sum(s.size for s in layout)


def slot(layout, name: str) -> Slot:
    """The part ``name`` of a layout."""
    for s in layout:
        if s.name == name:
            return s
    raise KeyError(f"the plant state has no part {name!r}; it has {', '.join(s.name for s in layout)}")


def entry_names(layout) -> list:
    """``"<part>[<entry>]"`` of every entry of x, in order ("q[x]", "pc[leg1.pc]", "spool[leg1]")."""
    return [f"{s.name}[{e}]" for s in layout for e in s.entries]


def describe_entries(layout, indices) -> str:
    """Entries ``indices`` of x named by their part and what they belong to, for a message."""
    names = entry_names(layout)
    return ", ".join(names[i] for i in np.asarray(indices, int).tolist())


def state_vector(layout, **parts) -> np.ndarray:
    """x with each of ``parts`` (name: values, in its unit) at its place in ``layout``, 0 elsewhere."""
    x = np.zeros(state_size(layout))
    for name, values in parts.items():
        x[slot(layout, name).slice] = values
    return x


def initial_state(layout, scenario=None, **parts) -> np.ndarray:
    """x where a run of ``scenario`` starts: each of ``parts`` (name: values) at its place in ``layout``,
    every other part at its declared initial values (:attr:`PlantState.initial`; one a scenario setting
    gives, from ``scenario``)."""
    x = np.array([v for s in layout for v in s.initial], float)
    for s in layout:
        if s.initial_setting and s.name not in parts:
            if scenario is None:
                raise ValueError(f"the plant state's part {s.name!r} starts at the scenario's "
                                 f"{s.initial_setting}: give the scenario")
            value = getattr(scenario, s.initial_setting)
            try:
                given = np.asarray(value, float)
                if given.ndim and given.shape != (s.size,):  # a list is one value per entry, no fewer
                    raise ValueError(given.shape)
                x[s.slice] = np.broadcast_to(given, (s.size,))
            except (TypeError, ValueError):
                from ..errors import ScenarioError
                raise ScenarioError(f"scenario '{scenario.name}': {s.initial_setting} = {value!r}, the start of the "
                                    f"plant's {s.name} ({s.block}), must be one number or {s.size}") from None
    for name, values in parts.items():
        x[slot(layout, name).slice] = values
    return x


def sensor_numbers(layout, scenario, kind: str) -> dict:
    """``{output: values per entry}`` of each plant output with a sensor (:attr:`PlantState.noise`), in
    ``layout`` order: its ``kind`` ("resolution" or "bias", in the output's unit) from ``scenario``'s
    setting of that name (:attr:`PlantState.resolution`, :attr:`PlantState.bias`; zeros where the output
    declares none)."""
    out = {}
    for s in layout:
        if not s.noise:
            continue
        setting = getattr(s, kind)
        value = 0.0 if not setting else getattr(scenario, setting)
        entries = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
        # a setting declared without a check reaches here as given: finite reals only (no NaN reading)
        real = all(is_number(v) and math.isfinite(v)
                   for v in entries)
        given = np.asarray(value, float) if real else None
        if given is None or (given.ndim and given.shape != (s.size,)):
            from ..errors import ScenarioError
            raise ScenarioError(f"scenario '{scenario.name}': {setting} = {value!r}, the {kind} of the "
                                f"plant's {s.name} sensor ({s.block}), must be one finite number or {s.size}")
        out[s.name] = np.broadcast_to(given, (s.size,)).astype(float)
    return out


def outputs(layout) -> tuple:
    """The parts of ``layout`` that are the plant's outputs (:attr:`PlantState.output`), in order."""
    return tuple(s for s in layout if s.output)


def _check_sensors(name: str, mod) -> None:
    """A block's declared sensors (:attr:`PlantState.noise`): each of an output, its noise one of the
    block's ``SCENARIO_SETTINGS``; else an ImportError naming the block, the state and what is wrong."""
    for st in mod.STATES:
        if st.noise and not st.output:
            raise ImportError(f"plant block {name!r} gives its state {st.name!r} a sensor's noise {st.noise!r}, "
                              "but the state is no output (output=True): a sensor reads an output")
        if st.noise and st.noise not in getattr(mod, "SCENARIO_SETTINGS", {}):
            raise ImportError(f"plant block {name!r} gives its state {st.name!r} the sensor's noise setting "
                              f"{st.noise!r}, which its SCENARIO_SETTINGS does not declare")
        for kind in ("resolution", "bias"):
            setting = getattr(st, kind)
            if setting and not st.noise:
                raise ImportError(f"plant block {name!r} gives its state {st.name!r} a sensor's {kind} {setting!r}, "
                                  "but no sensor (noise=...: its noise setting, 0 for none)")
            if setting and setting not in getattr(mod, "SCENARIO_SETTINGS", {}):
                raise ImportError(f"plant block {name!r} gives its state {st.name!r} the sensor's {kind} setting "
                                  f"{setting!r}, which its SCENARIO_SETTINGS does not declare")


def _discover() -> tuple:
    from ..registry import discover
    found = discover(__name__, __path__, ("POSITION", "STATES", "Symbolic"), lambda mod: mod.__name__.rsplit(".", 1)[-1],
                     "plant block")
    order = sorted(found, key=lambda name: found[name].POSITION)
    for a, b in zip(order, order[1:]):
        if found[a].POSITION == found[b].POSITION:
            raise ImportError(f"plant blocks {a!r} and {b!r} declare the same POSITION {found[a].POSITION}")
    inputs = {}
    for name in order:
        mod = found[name]
        key = getattr(mod, "INPUT", None)
        if key and key in inputs:
            raise ImportError(f"plant blocks {inputs[key]!r} and {name!r} declare the same INPUT {key!r}")
        inputs[key] = name
        for declared, needs in (("INPUT", ("PARAMETERS", "input_parameters", "values", "Symbolic.input")),
                                ("STATES", ("Symbolic.states", "Symbolic.derivatives"))):
            if not getattr(mod, declared, None):
                continue
            lacks = [a for a in needs if not hasattr(mod.Symbolic if a.startswith("Symbolic.") else mod,
                                                     a.removeprefix("Symbolic."))]
            if lacks:
                raise ImportError(f"plant block {name!r} ({mod.__name__}) declares {declared} but not "
                                  f"{', '.join(lacks)}")
        unknown = [st.initial for st in mod.STATES if isinstance(st.initial, str)
                   and st.initial not in getattr(mod, "SCENARIO_SETTINGS", {})]
        if unknown:
            raise ImportError(f"plant block {name!r} starts a state at the scenario setting {unknown[0]!r}, which "
                              "its SCENARIO_SETTINGS does not declare")
        _check_sensors(name, mod)
        taken = [st.name for st in mod.STATES if st.output and st.name in RESERVED_OUTPUTS]
        if taken:
            raise ImportError(f"plant block {name!r} declares the output {taken[0]!r}, a name the run's logs "
                              f"already use ({', '.join(RESERVED_OUTPUTS)})")
    return tuple(order)


#: The run's own logs and CSV columns (hydrogen.loop_logs): no plant output may take their name.
RESERVED_OUTPUTS = LOG_NAMES


#: The plant's blocks: every module of this package that declares its ``POSITION``, ``STATES`` and
#: ``Symbolic``, in ``POSITION`` order: the order of x (their states) and of the plant's inputs (their
#: numbers). A new block is a module here; nothing lists it.
BLOCKS = _discover()
