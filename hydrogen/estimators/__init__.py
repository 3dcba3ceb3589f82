"""The loop's estimators, one module each: what the estimate stage computes the actuators' rates from
(the measured travel l), in place of the ideal rate sensor (JL q̇ at the true pose, in the measure
stage). :data:`ESTIMATORS` finds them; nothing lists them.

An estimator is a module of this package that declares ``NAME`` and, besides (a missing one is an
ImportError naming the module):

* ``POSITION``: its place among the estimators (the order of the loop's configuration and state);
* ``DOC``: what it is, for comments and messages ("fixed-gain Kalman filter on the actuators' travel"),
  and optionally ``LABEL``, its name in the loop header's comments ("the Kalman filter"; else "the
  <NAME> estimator");
* ``SCENARIO_SETTINGS``: the scenario settings it reads (:func:`hydrogen.setting.setting`), and
  optionally ``SWITCH``, one of them (a boolean) that selects it besides the scenario's general
  ``estimator = "<NAME>"`` (:func:`selected`);
* ``STATE``: its part of the loop's state (:class:`LoopState`: a field of the C loop's state struct,
  its ctypes mirror and the Python engine's, size in the loop header's robot sizes: ``(2, "NL")``);
* ``CONFIG``: its numbers in the loop's configuration (:class:`ConfigNumbers`: a ``double[size]``
  field each; the loop header's struct, the runtime's ctypes mirror and fill, ``params.h`` of the
  export and the FMU), with ``CONFIG_DOC`` (their comment) and a switch ``use_<NAME>`` of its own;
* ``design(scenario, h)``: its design for a run at period ``h`` (s), and ``config(design)``: the
  configuration's numbers of that design, ``{field: values}``;
* ``start(l0)``: its state at the first lengths (numpy, of ``STATE``'s shape), and ``C_START``: the
  same in C, per actuator ``i``, with ``l0`` the lengths (a ``const double*``; the exported programs,
  the FMU);
* ``update(state, l_meas, design, h)``: its state after a period that measured ``l_meas`` (numpy),
  ``rate(state)``: the actuators' rates from it, and ``C_UPDATE``: the same statements in C, per
  actuator ``i`` (``st-><STATE>``, ``c-><CONFIG>``, ``c->h``, ``s->l_meas``; they set ``s->ldot[i]``),
  with ``C_COMMENT``: the same operations in the same order, so both engines agree to the bit.

Optionally, where a design is costly (a Riccati equation), ``design_key(scenario, h)``,
``designs(keys)`` and ``remember(designs)``: a sweep's parent solves the designs once and its workers
take them (:func:`designs_for`, :func:`remember`).

The C loop renders each estimator's statements into its estimate stage behind its switch (no
indirection on the hot path); without one selected the measure stage's ideal rate sensor gives the
rates. Plain data at import: no SciPy, no SymPy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ESTIMATORS", "IDEAL", "AUTO", "LoopState", "ConfigNumbers", "Estimate", "estimator", "selected", "estimate_for",
           "switches", "switch_field", "selector_setting", "designs_for", "remember"]

#: The general selector's value for no estimator: the ideal rate sensor.
IDEAL = "ideal"
#: The general selector's default: the estimator an estimator's own switch selects, else the ideal rate
#: sensor (an explicit "ideal" beside a switch that is on is a conflict, not silently the switch's).
AUTO = "auto"


@dataclass(frozen=True)
class LoopState:
    """An estimator's part of the loop's state: ``name`` (the C field ``st-><name>``), ``size`` (a tuple
    of numbers and the loop header's robot sizes, ``NQ``, ``NL``: ``(2, "NL")`` is 2 x NL doubles, row
    after row, as ``start`` gives them) and ``doc`` (the struct's comment)."""

    name: str
    size: tuple
    doc: str


@dataclass(frozen=True)
class ConfigNumbers:
    """A field of the loop's configuration an estimator declares: ``name`` (``c-><name>``, a
    ``double[size]``; params.h's ``P_<NAME>``) and ``size`` (numbers)."""

    name: str
    size: int

    @property
    def ctype(self) -> str:
        return f"double[{self.size}]"

    @property
    def macro(self) -> str:
        return f"P_{self.name.upper()}"


def estimator(name: str):
    """The module of estimator ``name`` (its ``NAME``, whatever its file is called)."""
    try:
        return _MODULES[name]
    except KeyError:
        raise KeyError(f"no estimator {name!r}; the estimators are {', '.join(ESTIMATORS) or 'none'}") from None


def switch_field(name: str) -> str:
    """The loop configuration's switch of estimator ``name`` (``use_kalman``: 1 where the run uses it)."""
    return f"use_{name}"


def switches() -> dict:
    """``{setting: estimator name}`` of the estimators' own boolean switches (``kalman``)."""
    return {estimator(n).SWITCH: n for n in ESTIMATORS if getattr(estimator(n), "SWITCH", None)}


def selector_setting():
    """The scenario's general selector ``estimator`` (:func:`hydrogen.setting.setting`), its meaning
    naming the estimators found."""
    from ..setting import setting
    names = ", ".join(f'"{n}" ({estimator(n).DOC})' for n in ESTIMATORS)
    return setting(AUTO, "", f'the estimator of the actuators\' rates: "{AUTO}" (the one a switch of an estimator '
                   f'selects, else the ideal rate sensor), "{IDEAL}" (the ideal rate sensor)'
                   f"{', ' if names else ''}{names}")


def selected(sc) -> str | None:
    """The estimator scenario ``sc`` selects (its name), or None: the ideal rate sensor. A ScenarioError
    naming the setting for an unknown name or two estimators selected at once."""
    from ..errors import ScenarioError
    general = getattr(sc, "estimator", AUTO)
    if not isinstance(general, str) or (general not in (AUTO, IDEAL) and general not in ESTIMATORS):
        known = ", ".join(f'"{n}"' for n in (AUTO, IDEAL, *ESTIMATORS))
        raise ScenarioError(f"scenario '{sc.name}': estimator = {general!r} is not an estimator; choose one of "
                            f"{known}")
    chosen = {general: "estimator"} if general != AUTO else {}
    for key, name in switches().items():
        if getattr(sc, key) and name not in chosen:
            chosen[name] = f"{key} = true"
    if len(chosen) > 1:
        how = " and ".join(f"{why} ({n})" if why != "estimator" else f'estimator = "{n}"' for n, why in chosen.items())
        off = " or ".join(why.replace("= true", "= false") for why in chosen.values() if why != "estimator")
        what = "the ideal rate sensor and an estimator" if IDEAL in chosen else "two estimators"
        raise ScenarioError(f"scenario '{sc.name}': {how} select {what}; select one (write {off} in the "
                            "scenario to turn a switch off, a [rig]'s too)")
    name = next(iter(chosen), None)
    return None if name == IDEAL else name


@dataclass(frozen=True)
class Estimate:
    """The estimator a run uses: its ``name`` and its ``design`` (its module's ``design(scenario, h)``)."""

    name: str
    design: object

    @property
    def module(self):
        return estimator(self.name)

    def config(self) -> dict:
        """The configuration's numbers of this design, ``{field: float array}``, each of its declared size."""
        mod = self.module
        values = mod.config(self.design)
        out = {}
        for f in mod.CONFIG:
            v = np.asarray(values[f.name], float).ravel()
            if v.size != f.size:
                raise ValueError(f"estimator {self.name!r}: config() gives {v.size} numbers for {f.name}, which "
                                 f"CONFIG declares of size {f.size}")
            out[f.name] = v
        return out


def estimate_for(sc, h) -> Estimate | None:
    """The :class:`Estimate` of scenario ``sc`` at period ``h`` (s), or None: the ideal rate sensor."""
    name = selected(sc)
    return None if name is None else Estimate(name, estimator(name).design(sc, h))


def designs_for(scenarios) -> dict:
    """``{estimator name: designs}`` solved here for ``scenarios`` (pairs of a scenario and its period h,
    s), by each estimator that declares ``designs``: a sweep's parent hands them to its workers."""
    keys = {}
    for sc, h in scenarios:
        try:
            name = selected(sc)
            if name is not None and hasattr(estimator(name), "designs"):
                keys.setdefault(name, []).append(estimator(name).design_key(sc, h))
        except Exception:  # noqa: BLE001 - a scenario that cannot be designed for: its run reports it
            continue
    return {name: estimator(name).designs(k) for name, k in keys.items()}


def remember(designs: dict) -> None:
    """Take the designs :func:`designs_for` solved in another process as this process's own."""
    for name, d in designs.items():
        estimator(name).remember(d)


#: What an estimator module declares (:data:`ESTIMATORS` refuses one lacking any, naming it).
REQUIRED = ("POSITION", "DOC", "SCENARIO_SETTINGS", "STATE", "CONFIG", "CONFIG_DOC", "design", "config", "start",
            "C_START", "update", "rate", "C_UPDATE", "C_COMMENT")

#: The loop's own state fields and configuration (hydrogen.layout): no estimator may take their names.
RESERVED = ("t", "k", "x", "q_meas", "u_hist", "u_app", "xc", "fk_info", "fk_l", "h", "quant_l", "sensor_res",
            "sensor_bias", "numbers")


def _discover() -> tuple:
    from ..registry import discover
    found = discover(__name__, __path__, ("NAME",), lambda mod: mod.NAME, "estimator")
    for name, mod in found.items():
        lacks = [a for a in REQUIRED if not hasattr(mod, a)]
        if lacks:
            raise ImportError(f"estimator {name!r} ({mod.__name__}) does not declare {', '.join(lacks)}")
        if name in (IDEAL, AUTO) or not name.isidentifier():
            raise ImportError(f"estimator {name!r} ({mod.__name__}): NAME must be an identifier other than "
                              f"{IDEAL!r} and {AUTO!r}")
        switch = getattr(mod, "SWITCH", None)
        if switch and switch not in mod.SCENARIO_SETTINGS:
            raise ImportError(f"estimator {name!r} ({mod.__name__}) is selected by SWITCH {switch!r}, which its "
                              "SCENARIO_SETTINGS does not declare")
        if hasattr(mod, "designs") and not all(hasattr(mod, a) for a in ("design_key", "remember")):
            raise ImportError(f"estimator {name!r} ({mod.__name__}) declares designs but not design_key and "
                              "remember")
    for name, mod in found.items():
        if any(not (isinstance(f.size, int) and f.size >= 1) for f in mod.CONFIG):
            raise ImportError(f"estimator {name!r} ({mod.__name__}): each of CONFIG's numbers needs a size of at least 1")
    order = sorted(found, key=lambda n: found[n].POSITION)
    for a, b in zip(order, order[1:]):
        if found[a].POSITION == found[b].POSITION:
            raise ImportError(f"estimators {a!r} and {b!r} declare the same POSITION {found[a].POSITION}")
    owner = {r: "the loop" for r in RESERVED}
    for name in order:
        mod = found[name]
        for field in (mod.STATE.name, switch_field(name), *(f.name for f in mod.CONFIG)):
            if field in owner:
                raise ImportError(f"estimator {name!r} ({mod.__name__}) declares {field!r}, which "
                                  f"{owner[field]} already names")
            owner[field] = f"estimator {name!r}"
    _MODULES.update(found)
    return tuple(order)


#: Each estimator's module by its NAME (:func:`estimator`).
_MODULES = {}
#: The estimators: every module of this package that declares its ``NAME``, in ``POSITION`` order. A new
#: estimator is a module here; nothing lists it.
ESTIMATORS = _discover()
