"""Exceptions raised by hydrogen. Each says what went wrong and where."""


class HydrogenError(Exception):
    """Base class of every error hydrogen raises on purpose."""


class ModelError(HydrogenError, ValueError):
    """A model file is malformed, incomplete or physically impossible."""


class UnsupportedExpressionError(HydrogenError, TypeError):
    """The SymPy → CasADi converter met a node it does not translate."""


class CompilerError(HydrogenError, RuntimeError):
    """No C compiler, or the compiler rejected the generated code."""


class BuildCacheError(HydrogenError, RuntimeError):
    """A cached library is corrupt, stale or built for another ABI."""


class StaleGeneratedCodeError(HydrogenError, RuntimeError):
    """Generated C does not match the model or the derivation code."""


class KinematicsError(HydrogenError, ValueError):
    """A pose is outside the workspace, JL is singular, or forward kinematics failed."""


class ScenarioError(HydrogenError, ValueError):
    """A scenario setting (duration, rate, friction, noise, ...) is out of range."""


class IdentificationError(HydrogenError, ValueError):
    """A log cannot be used for identification: a missing column, too few samples, a bad value."""


class SimulationError(HydrogenError, RuntimeError):
    """A simulation diverged; carries the partial result."""

    def __init__(self, message, result=None):
        super().__init__(message)
        self.result = result
