"""Exceptions raised by hydrogen. Each says what went wrong and where."""

__all__ = ["HydrogenError", "ModelError", "InputError", "UnsupportedExpressionError", "CompilerError", "BuildCacheError",
           "StaleGeneratedCodeError", "KinematicsError", "PlantWiringError", "ScenarioError", "IdentificationError",
           "SimulationError", "RunEndedError", "OutputPathError", "FmuError", "MAX_MESSAGE_CHARS"]


#: Longest message an error keeps (characters): a message quoting a huge value (a model array of
#: millions of numbers) is cut in the middle, keeping where it happened and how it ends.
MAX_MESSAGE_CHARS = 4000


def _shorten(message, limit):
    if not isinstance(message, str) or len(message) <= limit:
        return message
    head, tail = message[: limit * 3 // 4], message[-(limit // 5):]
    return f"{head} [... {len(message) - len(head) - len(tail):,} characters cut ...] {tail}"


class HydrogenError(Exception):
    """Base class of every error hydrogen raises on purpose."""

    max_chars = MAX_MESSAGE_CHARS

    def __init__(self, *args):
        super().__init__(*(_shorten(a, self.max_chars) for a in args))


class ModelError(HydrogenError, ValueError):
    """A model file is malformed, incomplete or physically impossible."""


class InputError(HydrogenError, ValueError):
    """An argument of a call does not fit it: the shape, type or values of an array handed to a compiled
    function, an option out of its choices (a ValueError too, as numpy's own would be)."""


class UnsupportedExpressionError(HydrogenError, TypeError):
    """The SymPy → CasADi converter met a node it does not translate."""


class CompilerError(HydrogenError, RuntimeError):
    """No C compiler, the compiler rejected the generated code, or it did not finish in time."""

    max_chars = 20000  # the compiler's own output is the useful part


class BuildCacheError(HydrogenError, RuntimeError):
    """A cached library is corrupt, stale or built for another ABI."""


class StaleGeneratedCodeError(HydrogenError, RuntimeError):
    """Generated C does not match the model or the derivation code."""


class KinematicsError(HydrogenError, ValueError):
    """A pose is outside the workspace, JL is singular, or forward kinematics failed."""


class PlantWiringError(HydrogenError, RuntimeError):
    """The plant's blocks (:mod:`hydrogen.plant`) do not fit together or their contract: a signal read
    that no block writes, one written twice, a cycle, a block's numbers of the wrong size."""


class ScenarioError(HydrogenError, ValueError):
    """A scenario setting (duration, rate, friction, noise, ...) is out of range."""


class IdentificationError(HydrogenError, ValueError):
    """A log cannot be used for identification: a missing column, too few samples, a bad value."""


class SimulationError(HydrogenError, RuntimeError):
    """A simulation diverged; carries the partial result."""

    def __init__(self, message, result=None):
        super().__init__(message)
        self.result = result


class WorkerError(HydrogenError, RuntimeError):
    """A sweep's worker processes could not be started (a process limit) or died abruptly."""


class OutputPathError(HydrogenError, FileExistsError):
    """An output path cannot be written as asked: a file where a folder is needed (or the other way
    round), a folder holding files hydrogen did not write, or a folder that cannot be written."""


class DiskFullError(HydrogenError, OSError):
    """A file could not be written because its disk (or the user's quota on it) is full; names the file."""


class RunEndedError(HydrogenError, IndexError):
    """A stepper asked for a control period past the end of its run (an IndexError too: past the end)."""


class FmuError(HydrogenError, ValueError):
    """An FMU export asked for something an FMU cannot be: an unknown part, a communication step that is
    not a whole number of control periods, no FMI headers (fmpy missing), an unsupported platform."""


class DescriptionNote(UserWarning):
    """How a description was read where it needed a choice (a massless link, a locked joint, a link
    left out of the selected sub-tree): one line, shown once."""
