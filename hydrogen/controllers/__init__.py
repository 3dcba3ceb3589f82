"""The controllers: one module each, registered here.

A controller module defines

* ``SPEC``, its :class:`~hydrogen.controllers.spec.ControllerSpec` (name, main gain and search grid,
  whether it knows the true parameters or is the baseline), and ``NAME``, ``DOC`` from it;
* ``state_layout(model)``: the blocks of its state xc in order, each a
  :class:`~hydrogen.controllers.spec.StateBlock` (unpacking as ``(block, size)``) declaring its role
  and what to lower when it diverges (the message of a diverged run names them);
* ``default_gains(model, scale)``: its gains (numpy arrays, SI), ``scale`` being the
  per-coordinate inertia scale of the model;
* ``static_inputs(dyn, theta0, gamma0)``: numeric inputs computed once per run (may be empty);
* optionally ``complete_gains(gains, scale)``: the gains with those its defaults leave NaN derived
  from the others (after the robot's tables and the caller's overrides are applied);
* ``derive(model)``: its symbolic derivation (imports SymPy when called), returning
  :class:`~hydrogen.symbolic.control_laws.ControllerParts` whose inputs name the signals it needs
  (``q``, ``qdot``, ``pc``, ``l``, ``qd0`` … ``qd3``, ``xc``, ``adapt``) besides its gains.

The generated C function is ``ctrl_<module name>``; a controller with a state also gets
``ctrl_<module name>_rates``, the same inputs and its state rate ``xc_dot`` alone, and
``ctrl_<module name>_step``, the loop's semi-implicit period in one call. A controller with the
composite adaptation's state blocks (:func:`hydrogen.controllers.common.composite_layout`) also
gets the three as ``ctrl_<module name>_lean…``: the same inputs and state with the composite
terms left out (their rates fixed at 0), which the runtime runs when those rates are 0. Adding a controller: write the module (the
registry finds every module of this package that declares ``SPEC``; its ``rank`` orders it, a new
one after the shipped ones), add its tests. Importing this package imports neither SymPy nor CasADi.
"""
from __future__ import annotations

import importlib
import pkgutil

import numpy as np

from ..errors import HydrogenError
from .spec import ControllerSpec, StateBlock

__all__ = ["CONTROLLERS", "controller", "spec", "baseline", "adapts", "has_lean", "function_name", "rates_function_name",
           "step_function_name", "function_owner", "gain_names", "COMMON_GAINS", "LEAN", "ControllerSpec", "StateBlock",
           "ESTIMATE_BLOCKS"]

#: The controller-state blocks that hold parameter estimates, in the order they are reported.
ESTIMATE_BLOCKS = ("theta_hat", "gamma1_hat", "gamma2_hat")

#: The variant of an adaptive controller without the composite adaptation terms.
LEAN = "lean"


def _discover(package: str, path) -> dict:
    """Every module of ``package`` (its ``__path__`` ``path``) that declares ``SPEC``, by user name, in the
    order functions are generated: by the spec's rank, then by module name."""
    found = [importlib.import_module(f"{package}.{info.name}") for info in pkgutil.iter_modules(path)]
    found = sorted((m for m in found if hasattr(m, "SPEC")), key=lambda m: (m.SPEC.rank, m.__name__))
    registry = {}
    for m in found:
        if m.SPEC.name in registry:
            raise HydrogenError(f"{m.__file__}: controller name '{m.SPEC.name}' is already declared by "
                                f"{registry[m.SPEC.name].__file__}")
        registry[m.SPEC.name] = m
    return registry


_REGISTRY = _discover(__name__, __path__)

#: User-facing controller names.
CONTROLLERS = tuple(_REGISTRY)

#: The description's ``[gains.<this>]`` table, whose gains apply to every controller that has them.
COMMON_GAINS = "common"


def controller(name: str):
    """The module of controller ``name`` (KeyError if unknown)."""
    return _REGISTRY[name]


def spec(name: str) -> ControllerSpec:
    """The :class:`ControllerSpec` of controller ``name`` (KeyError if unknown)."""
    return _REGISTRY[name].SPEC


def gain_names(kind, model) -> frozenset:
    """Names of the gains of controller ``kind`` for ``model``: those its defaults define, the only ones
    a description's ``[gains.<kind>]`` or the caller may set (KeyError if the controller is unknown)."""
    return frozenset(controller(kind).default_gains(model, np.ones(model.n)))


def baseline() -> str:
    """The name of the baseline controller (the fixed-gain comparison; exactly one is registered)."""
    (name,) = [n for n, m in _REGISTRY.items() if m.SPEC.baseline]
    return name


def adapts(name: str, model) -> bool:
    """Whether controller ``name`` estimates parameters on ``model`` (its state holds θ̂ or γ̂)."""
    return any(block in ESTIMATE_BLOCKS for block, _ in _REGISTRY[name].state_layout(model))


def has_lean(name: str, model) -> bool:
    """Whether controller ``name`` has a lean variant on ``model``: its state holds the composite
    adaptation's blocks (:func:`hydrogen.controllers.common.lean_variant`)."""
    from .common import lean_variant

    return lean_variant(_REGISTRY[name].state_layout(model)) is not None


def function_name(name: str, variant: str | None = None) -> str:
    """Name of the generated function of controller ``name``: ``ctrl_<module>``, or
    ``ctrl_<module>_<variant>`` for a variant (:data:`LEAN`)."""
    base = "ctrl_" + _REGISTRY[name].__name__.rsplit(".", 1)[1]
    return base if variant is None else f"{base}_{variant}"


def rates_function_name(name: str, variant: str | None = None) -> str:
    """Name of the rates-only generated function of controller ``name`` (one with a state):
    ``ctrl_<module>[_<variant>]_rates``, the same inputs as :func:`function_name`'s, output ``xc_dot`` alone."""
    return function_name(name, variant) + "_rates"


def step_function_name(name: str, variant: str | None = None) -> str:
    """Name of the semi-implicit step of controller ``name`` (one with a state):
    ``ctrl_<module>[_<variant>]_step``, the controller's inputs then ``h``, ``xc_lo``, ``xc_hi``; outputs the
    command ``u`` at the updated state and that state ``xc_next``."""
    return function_name(name, variant) + "_step"


def function_owner(fname: str):
    """``(controller, variant)`` whose generated function is named ``fname`` (its controller, rates
    or step function; variant None or :data:`LEAN`), or None for a function of no controller."""
    for kind in CONTROLLERS:
        for variant in (None, LEAN):
            if fname in (function_name(kind, variant), rates_function_name(kind, variant),
                         step_function_name(kind, variant)):
                return kind, variant
    return None
