"""The loop's sensors' noise, declared once: the channels of a period's noise row, in order (plain data).

A run's noise is one table, a row per control period, that every engine reads (the C loop, the
Python engine); each channel is the white noise added to one measured signal, its standard deviation
the scenario's setting of that name (a per-actuator one in each actuator's own unit where the
actuator gives it). The columns, the C loop's offsets into the row (``templates/loop.c.j2``), the
Python engine's (:class:`hydrogen.simulation.simulator.PythonStages`), the draw of the table
(:meth:`hydrogen.simulation.simulator.RunPlan.noise`: channel after channel, only those switched on,
so a channel off leaves the others' numbers as they were) and the loop header's comment are read off
:data:`NOISE`. A new sensor's noise is one row there and its use in the sensors' stage; a rig part's output
declares its own sensor's noise (:attr:`hydrogen.plant.PlantState.noise`), a channel after these.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["NoiseChannel", "NOISE", "noise_columns", "noise_width"]


@dataclass(frozen=True)
class NoiseChannel:
    """The noise of one measured signal: ``name`` (the signal: the sensors' output port), ``size`` (a
    robot size of the loop header: ``NL``, ``NPC``, ``NQ``, ``NPS``), ``setting`` (the scenario's
    standard deviation), ``unit``, ``doc`` (what it is measured on, for comments); ``encoders``: only
    on a robot with joint encoders."""

    name: str
    size: str
    setting: str
    unit: str
    doc: str
    encoders: bool = False


#: The noise row's channels, in order. A channel whose size is 0 for a robot (the supply pressure of a
#: constant supply) or that needs joint encoders the robot lacks has no columns.
NOISE = (
    NoiseChannel("l", "NL", "noise_l", "m or rad", "actuator travel"),
    NoiseChannel("pc", "NPC", "noise_p", "Pa", "pressure states"),
    NoiseChannel("q", "NQ", "noise_q", "rad or m", "joint encoders", encoders=True),
    NoiseChannel("ps", "NPS", "noise_ps", "Pa", "supply pressure"),
)


def noise_columns(sizes: dict, encoders: bool, plant=()) -> dict:
    """``{channel name: (first column, count)}`` of the noise row of a robot of ``sizes`` (the loop
    header's: ``{"NL": m, "NPC": ..., "NQ": n, "NPS": ...}``) with or without joint ``encoders``, in
    :data:`NOISE` order, then ``plant``'s (the sensors of its plant's outputs that declare a noise:
    :func:`hydrogen.layout.plant_sensors`); the channels it lacks are left out."""
    out, start = {}, 0
    for ch in (*NOISE, *plant):
        count = int(sizes[ch.size]) if encoders or not ch.encoders else 0
        if count:
            out[ch.name] = (start, count)
            start += count
    return out


def noise_width(sizes: dict, encoders: bool, plant=()) -> int:
    """Numbers in a noise row (``plant``: as :func:`noise_columns`)."""
    return sum(count for _, count in noise_columns(sizes, encoders, plant).values())
