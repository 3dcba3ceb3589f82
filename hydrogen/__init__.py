"""hydrogen: symbolic model of a hydraulic Stewart platform → compiled C → control loop."""
from .errors import (BuildCacheError, CompilerError, HydrogenError, KinematicsError,
                     ModelError, SimulationError, StaleGeneratedCodeError,
                     UnsupportedExpressionError)
from .model import Model, load_model

__all__ = [
    "load_model", "Model", "build", "simulate",
    "HydrogenError", "ModelError", "UnsupportedExpressionError", "CompilerError",
    "BuildCacheError", "StaleGeneratedCodeError", "KinematicsError", "SimulationError",
]
__version__ = "0.1.0"


def build(model=None, **kwargs):
    """Generate if stale, compile if needed, and load: see :func:`hydrogen.runtime.build.build`."""
    from .runtime.build import build as _build
    return _build(model, **kwargs)


_DEFAULT_DYN = {}


def simulate(scenario="paper-sim", controller="adaptive-robust", *, model=None, dyn=None, **overrides):
    """Run a scenario in closed loop and return a :class:`~hydrogen.simulation.simulator.SimulationResult`.

    ``scenario``: paper-sim, z-1hz, z-2hz, psi-1hz or z-step. ``controller``:
    backstepping, adaptive-robust, adaptive-observer or p. ``overrides`` may set
    ``duration`` (s), ``gains`` (dict), or any scenario field. ``dyn`` defaults to
    ``build(model)``, built once per process and model.
    """
    from .simulation.simulator import simulate as _simulate
    if dyn is None:
        m = model if isinstance(model, Model) else load_model(model)
        key = m.source, m.baked_hash()
        if key not in _DEFAULT_DYN:
            _DEFAULT_DYN[key] = build(m)
        dyn = _DEFAULT_DYN[key]
    return _simulate(dyn, scenario, controller, **overrides)
