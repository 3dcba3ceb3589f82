"""The closed loop's logs, declared once: what a run records each control period (plain data).

Every row of every log is written after the period's control stage and before the plant moves (the
state the period's measurement was taken of, the command computed from it). Each :class:`LogRow`
names its source in the loop: a field of the period's signals (the C loop's ``<model>_loop_signals``
and the Python engine's of the same name), a part of the plant state
(:func:`hydrogen.plant.plant_layout`), a field of the loop's state, or the actuators' forces from the
pressures. The loop header's log struct and its comments, the C loop's ``write_log``, the ctypes
mirror, the Python engine's writer, the logs' widths and :class:`hydrogen.simulation.simulator.
SimulationResult` are read off :data:`LOGS` (and each plant output, logged under its own name). A new
log of a signal the loop already has is one row here.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["LogRow", "LOGS", "SIGNAL", "PLANT", "STATE", "FORCES", "RESERVED"]

#: Sources: a field of the period's signals, a part of the plant state, a field of the loop's state,
#: the actuators' forces from the pressure states (and the supply pressure where it is a state).
SIGNAL, PLANT, STATE, FORCES = "signal", "plant", "state", "forces"


@dataclass(frozen=True)
class LogRow:
    """One log of the closed loop.

    name : str
        The log's name (the log struct's field, the ``logs`` argument's key of the runtime's loop).
    size : tuple
        Columns, as a product of the loop header's sizes (``("NQ",)``, ``(1,)``; ``"NXC"``: the
        controller's state size). A source with more entries than that gives its first ones.
    unit : str
        SI, per entry.
    doc : str
        What a row holds, for the header's comment and the docs.
    source : tuple
        ``(kind, field)``: :data:`SIGNAL`, :data:`PLANT`, :data:`STATE` and the field or part's name,
        or ``(FORCES, "")``.
    result : str
        The :class:`~hydrogen.simulation.simulator.SimulationResult` field it becomes ("": the
        result's ``signals`` under its name; the controller's state becomes ``states`` and the estimates).
    """

    name: str
    size: tuple
    unit: str
    doc: str
    source: tuple
    result: str = ""


#: The loop's own logs, in the log struct's order (the plant's outputs follow, each under its name).
LOGS = (
    LogRow("t", (1,), "s", "time of the period's start", (SIGNAL, "t"), "t"),
    LogRow("q", ("NQ",), "m or rad", "true pose", (PLANT, "q"), "q"),
    LogRow("q_d", ("NQ",), "m or rad", "reference", (SIGNAL, "qd"), "q_d"),
    LogRow("l", ("NL",), "m or rad", "true actuator travel (cylinder lengths)", (SIGNAL, "l_true"), "leg_lengths"),
    LogRow("f", ("NL",), "N or N m", "actuator forces of the chamber pressures", (FORCES, ""), "leg_forces"),
    LogRow("pc", ("NPC",), "Pa", "pressure states (a three-way cylinder's control pressure, the others' chambers)",
           (PLANT, "pc"), "pressures"),
    LogRow("u", ("NL",), "m", "spool commands computed", (SIGNAL, "u"), "u"),
    LogRow("u_applied", ("NL",), "m", "spool commands the valves held at the end of each period (delay later)",
           (SIGNAL, "u_app"), "u_applied"),
    LogRow("l_meas", ("NL",), "m or rad", "measured actuator travel (noise, resolution)", (SIGNAL, "l_meas"),
           "leg_lengths_measured"),
    LogRow("ldot", ("NL",), "m/s or rad/s", "actuator rates the velocities came from (the estimator's, or the "
           "ideal rate sensor's)", (SIGNAL, "ldot")),
    LogRow("qdot_meas", ("NQ",), "m/s or rad/s", "measured velocities (JL^-1 ldot at the measured pose)",
           (SIGNAL, "qdot_meas")),
    LogRow("xc", ("NXC",), "per block", "controller state", (STATE, "xc")),
)

_unknown = [row.name for row in LOGS if row.source[0] not in (SIGNAL, PLANT, STATE, FORCES)]
if _unknown:
    raise ImportError(f"the log {_unknown[0]!r} (hydrogen.loop_logs) names no source kind of {SIGNAL!r}, {PLANT!r}, "
                      f"{STATE!r}, {FORCES!r}")

#: Names no plant output may take: the loop's own logs.
RESERVED = tuple(row.name for row in LOGS)
