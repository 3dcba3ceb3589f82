"""hydrogen: symbolic model of a hydraulic robot → compiled C → controller and simulator loop."""
from .errors import (BuildCacheError, CompilerError, HydrogenError, IdentificationError, InputError,
                     KinematicsError,
                     ModelError, ScenarioError, SimulationError, StaleGeneratedCodeError,
                     OutputPathError, UnsupportedExpressionError, WorkerError)
from .model import Model, load_model, models

__all__ = [
    "load_model", "models", "Model", "build", "simulate", "stepper", "sweep", "identify",
    "HydrogenError", "ModelError", "InputError", "UnsupportedExpressionError", "CompilerError",
    "BuildCacheError", "StaleGeneratedCodeError", "KinematicsError", "SimulationError", "ScenarioError",
    "OutputPathError", "IdentificationError", "WorkerError",
]
__version__ = "0.1.0"


def build(model=None, **kwargs):
    """Generate if stale, compile if needed, and load: see :func:`hydrogen.runtime.build.build`."""
    from .runtime.build import build as _build
    return _build(model, **kwargs)




def simulate(scenario="paper-sim", controller="adaptive-robust", *, model=None, dyn=None, progress=None,
             **overrides):
    """Run a scenario in closed loop and return a :class:`~hydrogen.simulation.simulator.SimulationResult`
    (with ``seeds=``, one run per noise seed: a :class:`~hydrogen.simulation.seeds.SeedResults`).

    ``scenario``: one of the model's scenarios, or ``<scenario>.<variant>`` (an unknown name lists them).
    ``controller``: one of ``hydrogen.controllers.CONTROLLERS`` that the model's description lists.
    ``model``: a built-in name (``hydrogen.models()``), a path or a Model (default: ubc_stewart). ``overrides`` may set
    ``duration`` (s), ``gains`` (dict), or any scenario field; ``seeds`` (a count N: seeds 0..N-1, or a
    list), ``max_workers`` and ``executor`` run the scenario over noise seeds in parallel (see
    :func:`hydrogen.simulation.simulator.simulate`). ``dyn`` defaults to
    ``build(model)``, built once per process and model; ``progress`` is passed to that build (see
    :func:`hydrogen.runtime.build.build`).
    """
    from .runtime.build import dynamics_for
    from .simulation.simulator import simulate as _simulate
    return _simulate(dynamics_for("simulate", model, dyn, progress=progress, controller=controller), scenario,
                     controller, **overrides)


def default_dynamics(model=None, progress=None, controller=None, numbers=None):
    """The compiled dynamics of ``model``, built once per process: see
    :func:`hydrogen.runtime.build.default_dynamics`."""
    from .runtime.build import default_dynamics as _default_dynamics
    return _default_dynamics(model, progress, controller, numbers)


def stepper(scenario="paper-sim", controller="adaptive-robust", *, model=None, dyn=None, progress=None,
            **overrides):
    """A :class:`~hydrogen.simulation.simulator.Stepper`: the closed loop one control period per call
    (``progress``: as for :func:`simulate`)."""
    from .runtime.build import dynamics_for
    from .simulation.simulator import Stepper
    return Stepper(dynamics_for("stepper", model, dyn, progress=progress, controller=controller), scenario,
                   controller, **overrides)


def sweep(runs, *, executor=None, max_workers=None, model=None, progress=False, seeds=None, results=False):
    """Run many simulations in parallel (``seeds``: each entry over noise seeds, its distribution in
    its place): see :func:`hydrogen.simulation.sweep.sweep`."""
    from .simulation.sweep import sweep as _sweep
    return _sweep(runs, executor=executor, max_workers=max_workers, model=model, progress=progress, seeds=seeds,
                  results=results)


def identify(log, model=None, *, dyn=None, **options):
    """Estimate θ (and γ) by least squares from a rig's log (leg lengths, pressures, spool commands):
    see :func:`hydrogen.identification.identify` for the log's columns, the pipeline and ``options``."""
    from .identification import identify as _identify
    return _identify(log, model, dyn=dyn, **options)
