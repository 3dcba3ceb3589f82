"""Progress of the long steps of a build: generation (SymPy derivation, C) and compilation.

``hydrogen.build(model, progress=callable)`` (and ``simulate``/``stepper`` where they build) calls
``callable(event)`` with a :class:`BuildEvent` at each stage; the command line prints them on
stderr, one line a stage (:func:`print_event`). A library already built gives one ``"loaded"``
event, which the command line does not print.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass

__all__ = ["BuildEvent", "STAGES", "Reporter", "print_event", "c_size"]

#: The stages, in the order a build from scratch reports them.
STAGES = ("generating", "generated", "compiling", "compiled", "built", "loaded")


@dataclass(frozen=True)
class BuildEvent:
    """One stage of a build. ``stage``: one of :data:`STAGES` ("generating"/"compiling" when a long
    step starts, "generated"/"compiled" when it ends, "built" for the whole build, "loaded" when
    the library was already built); ``model``: the model's name; ``detail``: what is done (number
    of functions, size of the C, the library); ``elapsed_s``: seconds the step took (0 at a start)."""

    stage: str
    model: str
    detail: str
    elapsed_s: float


class Reporter:
    """Sends :class:`BuildEvent` s of one model to ``callback`` (None: nowhere), timing each step."""

    def __init__(self, callback, model: str):
        if callback is not None and not callable(callback):
            raise TypeError(f"progress must be a callable taking a BuildEvent, got {type(callback).__name__}")
        self.callback, self.model = callback, model
        self.t0 = time.perf_counter()
        self.stages = []  # the stages reported, in order

    def start(self):
        """A clock for one step: ``clock()`` gives the seconds since."""
        t = time.perf_counter()
        return lambda: time.perf_counter() - t

    def total(self) -> float:
        return time.perf_counter() - self.t0

    def __call__(self, stage: str, detail: str = "", elapsed_s: float = 0.0) -> None:
        self.stages.append(stage)
        if self.callback is not None:
            self.callback(BuildEvent(stage, self.model, detail, float(elapsed_s)))


def c_size(paths) -> str:
    """Total size of the files, as '1.9 MB' or '85 kB' (of C)."""
    n = sum(p.stat().st_size for p in paths if p.is_file())
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.0f} kB"


def print_event(event: BuildEvent, file=None) -> None:
    """The command line's progress: one line on stderr per stage; nothing for a library already built."""
    if event.stage == "loaded":
        return
    out = file or sys.stderr
    if event.stage in ("generating", "compiling"):
        print(f"hydrogen: {event.stage} {event.model}: {event.detail} ...", file=out, flush=True)
    else:
        print(f"hydrogen: {event.stage} {event.model}: {event.detail}, {event.elapsed_s:.1f} s", file=out, flush=True)
