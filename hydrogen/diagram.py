"""The closed loop as blocks wired by port name (plain data: no SymPy, CasADi or numpy).

Each block of the loop declares the ports it reads and writes (name, size in the robot's sizes, unit);
a controller's generated function declares its inputs by name, and :func:`wire` connects each to the
loop output of that name, or to one of the controller's own constant inputs (gains, the description's
numbers), refusing an input that nothing writes and one whose size differs from the port's. The loop
driver (``templates/loop.c.j2``) writes the controller's inputs from :data:`CONTROLLER_PORTS` (the
order of its input slots), the Python engine (:class:`hydrogen.simulation.simulator.PythonStages`)
hands the controller the same ports by name, and the exported programs and FMUs read the same table.

Sizes are the loop header's names: ``NQ`` coordinates, ``NL`` actuators, ``NPC`` pressure states,
``NPS`` the supply pressure states (1 where the supply is a plant state, else 0), ``NXC`` the
controller's own state, ``NX`` the plant state; an integer is a fixed count. A port whose robot size is 0
does not exist for that robot (the measured supply pressure of a constant supply): it is no slot and
nothing writes it.
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import ScenarioError
from .plant.supply import PRESSURE as SUPPLY_PRESSURE

__all__ = ["Port", "Block", "CONTROLLER_PORTS", "SLOTS", "REFERENCE_PORTS", "LOOP_BLOCKS", "port_length",
           "slots", "signals", "wire"]


@dataclass(frozen=True)
class Port:
    """A signal a block reads or writes.

    name : str
        What it is wired by.
    size : tuple
        Its length as a product of the robot's sizes (``("NQ",)``, ``(1,)``).
    unit : str
        SI, per entry ("m or rad" where each coordinate or actuator has its own).
    doc : str
        One line: what it carries.
    c_value : str
        For a controller's input: the loop driver's expression of its value in the control stage
        (``templates/loop.c.j2``; the measured or predicted signal), read by the template.
    """

    name: str
    size: tuple
    unit: str
    doc: str
    c_value: str = ""


def port_length(port: Port, sizes: dict) -> int:
    """Number of entries of ``port`` for ``sizes`` (the robot's: ``{"NQ": n, "NL": m, ...}``)."""
    n = 1
    for t in port.size:
        n *= t if isinstance(t, int) else int(sizes[t])
    return n


_q = Port("q", ("NQ",), "m or rad", "measured pose (forward kinematics or joint encoders; predicted with a delay "
          "predictor)", "q")
_qdot = Port("qdot", ("NQ",), "m/s or rad/s", "measured velocities, JL^-1 ldot at the measured pose", "qdot")
_pc = Port("pc", ("NPC",), "Pa", "measured pressure states (noise, clipped to their range)", "pc")
_l = Port("l", ("NL",), "m or rad", "measured actuator travel (noise, resolution)", "l")
#: The reference and its first three time derivatives, one port each (qd0 … qd3).
REFERENCE_PORTS = tuple(
    Port(f"qd{k}", ("NQ",), "m or rad" + ("", "/s", "/s^2", "/s^3")[k], f"reference, derivative {k}",
         "qd" if k == 0 else f"qd + {'' if k == 1 else f'{k} * '}NQ") for k in range(4))
_xc = Port("xc", ("NXC",), "per block", "the controller's own state (its estimates, observers), fed back", "st->xc")
_adapt = Port("adapt", (1,), "1", "1 once adaptation is on (t >= t_adapt), else 0", "&adapt")
_u_applied = Port("u_applied", ("NL",), "m", "spool commands the valves held over the last period (after the "
                  "computation delay)", "u_prev")
_ps = Port(SUPPLY_PRESSURE, ("NPS",), "Pa", "measured supply pressure (a [supply] state's; noise_ps)", "ps")

#: Every loop signal a controller may take as an input, in the order of the loop's input slots
#: (``<MODEL>_SLOT_<NAME>`` in the loop header, ``slot`` in its configuration, ``P_CTRL_SLOT`` in an
#: exported params.h). A new signal for controllers is one row here and the stage that writes it.
CONTROLLER_PORTS = (_q, _qdot, _pc, _l, *REFERENCE_PORTS, _xc, _adapt, _u_applied, _ps)

#: Every input slot's name, in order (a robot has those of :func:`slots`).
SLOTS = tuple(p.name for p in CONTROLLER_PORTS)


def _exists(port: Port, sizes: dict) -> bool:
    """Whether a robot of ``sizes`` has ``port``: none of its robot sizes is 0 (the controller's own
    state's size is the controller's, not the robot's)."""
    return all(isinstance(t, int) or t == "NXC" or int(sizes[t]) > 0 for t in port.size)


def ports(sizes: dict, plant=()) -> tuple:
    """The controller ports a robot of ``sizes`` has, in slot order: the loop's, then ``plant``, the
    ports of its plant's outputs (:func:`hydrogen.layout.plant_ports`: a rig part's state a controller
    may read)."""
    return tuple(p for p in CONTROLLER_PORTS if _exists(p, sizes)) + tuple(plant)


def slots(sizes: dict, plant=()) -> tuple:
    """The names of the input slots a robot of ``sizes`` has, in order (the loop header's enum)."""
    return tuple(p.name for p in ports(sizes, plant))

_u = Port("u", ("NL",), "m", "spool commands computed this period")
_x = Port("x", ("NX",), "per part", "the plant state (hydrogen.plant.plant_layout)")
_u_valve = Port("u_valve", ("NL",), "m", "spool commands the valves hold over the period (the last one's over "
                "its first delay fraction, then the delayed one)")


@dataclass(frozen=True)
class Block:
    """A block of the loop: what it reads and writes, and whether it is the continuous plant (integrated
    between control instants) or a discrete step (once per control period)."""

    name: str
    doc: str
    inputs: tuple = ()
    outputs: tuple = ()
    continuous: bool = False
    #: the C loop's stage function that runs it (``<model>_<stage>``, templates/loop.c.j2; one stage
    #: may run several blocks in a row)
    c_stage: str = ""


#: The loop's blocks in the order a control period runs them (measure, estimate, reference, control,
#: hold, plant): the Python engine interprets this order, the C loop's stages run it (tested). The controller's inputs are those its generated function declares (wired by
#: :func:`wire`); a delay predictor, when a scenario asks for one, writes the same ports as the
#: estimator and the reference at the time the command reaches the valves.
LOOP_BLOCKS = (
    Block("sensors", "actuator travel (noise, resolution), pressures (noise), the supply pressure where it is a "
          "state, joint encoders where fitted", inputs=(_x,), outputs=(_l, _pc, _ps), c_stage="measure"),
    Block("estimator", "the scenario's estimator of the rates from the travel (or the ideal rate sensor's), pose by "
          "forward kinematics (or encoders), velocities",
          inputs=(_l,), outputs=(_q, _qdot), c_stage="estimate"),
    Block("reference", "the scenario's reference and its derivatives", outputs=REFERENCE_PORTS, c_stage="reference"),
    Block("schedule", "adaptation on from t_adapt", outputs=(_adapt,), c_stage="control"),
    Block("controller", "the chosen controller's generated step (its inputs wired by name)",
          inputs=CONTROLLER_PORTS, outputs=(_u, _xc), c_stage="control"),
    Block("hold", "computation delay and zero-order hold of the spool commands", inputs=(_u,),
          outputs=(_u_applied, _u_valve), c_stage="control"),
    Block("plant", "the fused plant function, RK4 sub-steps over the period", inputs=(_u_valve,), outputs=(_x,),
          continuous=True, c_stage="plant_step"),
)


def signals(q, qdot, pc, l, ref, adapt: bool, ps=None) -> dict:
    """The controller's loop inputs by port name from the measured (or predicted) pose ``q``, velocities
    ``qdot``, pressures ``pc``, travel ``l``, reference ``ref`` (4 rows: value and three derivatives),
    whether adaptation is on and the supply pressure ``ps`` (Pa; None: the supply is constant). The
    controller adds its own ``xc`` and ``u_applied``."""
    out = {"q": q, "qdot": qdot, "pc": pc, "l": l, "adapt": 1.0 if adapt else 0.0}
    out.update((p.name, ref[k]) for k, p in enumerate(REFERENCE_PORTS))
    if ps is not None:
        out[SUPPLY_PRESSURE] = ps
    return out


def wire(owner: str, inputs, constants, sizes: dict, plant=()) -> list:
    """The slot of each of the robot's :func:`slots` in the argument table ``inputs`` of a controller's
    generated function (-1: it does not read that signal), after checking every input is wired.

    ``inputs``: ``[(name, length), ...]`` in the function's argument order; ``constants``: the names of
    its inputs given once per run (gains, static inputs, the description's numbers); ``sizes``: the
    robot's sizes; ``plant``: the ports of its plant's outputs (:func:`ports`). Raises :class:`~hydrogen.errors.ScenarioError` naming ``owner`` and the input when an
    input is neither a loop signal nor a constant (unwired), or a loop signal of another size.
    """
    names = [name for name, _ in inputs]
    present = slots(sizes, plant)
    unwired = [name for name in names if name not in present and name not in constants]
    if unwired:
        raise ScenarioError(
            f"{owner}: no value for its input(s) {', '.join(unwired)}: wired to no loop signal (the loop's "
            f"signals: {', '.join(present)}) and given no value (the description's gains, or the controller's "
            "default_gains/static_inputs)")
    by_name = {p.name: p for p in ports(sizes, plant)}
    for name, length in inputs:
        if name in by_name and name != "xc":  # xc is the controller's own: its size is its layout's
            want = port_length(by_name[name], sizes)
            if int(length) != want:
                raise ScenarioError(f"{owner}: input '{name}' has {int(length)} entries, but the loop's signal "
                                    f"'{name}' ({by_name[name].doc}) has {want} for this robot")
    return [names.index(s) if s in names else -1 for s in present]
