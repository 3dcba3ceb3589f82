"""hydrogen: symbolic model of a hydraulic Stewart platform → compiled C → control loop."""
from .errors import (BuildCacheError, CompilerError, HydrogenError, KinematicsError,
                     ModelError, SimulationError, StaleGeneratedCodeError,
                     UnsupportedExpressionError)
from .model import Model, load_model

__all__ = [
    "load_model", "Model", "build",
    "HydrogenError", "ModelError", "UnsupportedExpressionError", "CompilerError",
    "BuildCacheError", "StaleGeneratedCodeError", "KinematicsError", "SimulationError",
]
__version__ = "0.1.0"


def build(model=None, **kwargs):
    """Generate if stale, compile if needed, and load: see :func:`hydrogen.runtime.build.build`."""
    from .runtime.build import build as _build
    return _build(model, **kwargs)
