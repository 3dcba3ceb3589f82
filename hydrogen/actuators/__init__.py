"""The actuator kinds: one module each, registered here (like :mod:`hydrogen.controllers`).

An actuator module declares

* ``NAME`` (the kind, as a model file will name it) and ``DOC``;
* ``MOTION``: ``"prismatic"`` (its coordinate x is a length l, m) or ``"revolute"`` (a joint angle, rad);
* ``TRAVEL``: its coordinate's quantity, unit, force unit and range key
  (:data:`~hydrogen.actuators.declarations.LENGTH`, :data:`~hydrogen.actuators.declarations.ANGLE`, or
  :data:`~hydrogen.actuators.declarations.ROTATION`: unlimited, no range):
  every message about its travel, every per-actuator rig setting, FMU variable and log column takes
  its units from it;
* ``STATES``: its chamber pressure states (:class:`~hydrogen.actuators.declarations.State`: name, unit,
  bounds), in the order the laws take them as the tuple ``p``;
* ``PARAMETERS``: its constants and their defaults (:class:`~hydrogen.actuators.declarations.Parameter`);
  ``parameters(source)`` reads them from a cylinder or a mapping, ``stacked(sources)`` as arrays;
* ``COUPLING_GAIN``: the default Γ_τ⁻¹ of the controllers' force loop, in the kind's force per
  coordinate (N/m for a cylinder), or None where no default is sound: the description must give
  ``Gtau_inv`` (a torque loop in N·m/rad weighs the force error by the square of a lever no actuator
  of its own carries);
* ``SENSORS``: what the robot measures on it (:class:`~hydrogen.actuators.declarations.Sensor`);
* ``Symbolic`` (SymPy, the derivation layer) and ``Numeric`` (numpy twins, tested equal), each with
  the same laws, ``P`` the parameters by name, spool u in m, β and c the paper's γ = [β, βc]:

  - ``force(p, P)``: the force (N) or torque (N·m) from the pressures;
  - ``chamber_forces(p, P)``: each chamber's signed force (torque), summing to ``force``: the seal
    friction's pressure load (:mod:`hydrogen.plant.friction`);
  - ``pressure_rates(x, xdot, p, u, beta, c, P, smooth=True)``: the plant's ṗ (Pa/s), with the
    simulator's smooth orifice law (``smooth``) or the controllers' law with clipped drops;
  - ``f0(x, xdot, p, P)``, ``g0(x, p, u, P)``: ḟ = β f0 + βc g0, g0 increasing in u;
  - ``valve_inverse(y, x, p, P, eps)``: the u with g0 = y, closed form on every branch;
  - ``spring_rate(x, P)`` = −∂f0/∂ẋ (β times it: the oil column's stiffness), ``f0_potential(x, P)``
    (Φ with dΦ/dt = f0);
  - ``equilibrium_pressures(force, P)``: pressures (a tuple, ``STATES`` order) whose force is
    ``force``; ``force_range(P)``: the forces reachable with every pressure within its bounds.

Adding a kind: write the module and its tests; the registry finds it (every module of this package
that declares ``NAME`` and ``Symbolic``), and tests/test_actuators.py runs the physics checks on it
from its example in tests/data/actuators/. Importing this package does not import SymPy.
"""
from __future__ import annotations

from ..errors import ModelError
from ..registry import discover

__all__ = ["KINDS", "DEFAULT_KIND", "actuator", "baked_parameters"]

#: The kind of a cylinder whose description names none: the paper's actuator.
DEFAULT_KIND = "three_way_cylinder"


#: What a kind's module declares besides ``NAME`` and ``Symbolic`` (the module doc above): a module
#: that lacks one is refused when the package is imported, naming it, instead of failing later where
#: a run first reads it.
DECLARES = ("DOC", "MOTION", "TRAVEL", "STATES", "PARAMETERS", "COUPLING_GAIN", "SENSORS", "Numeric", "parameters",
            "stacked")


def _discover(path=__path__, package=__name__) -> dict:
    """``{NAME: module}`` of every module of this package that declares a kind (``NAME`` and
    ``Symbolic``): the default kind first, then by name, so lists of kinds read the same on every
    machine whatever order the file system gives. ``path``, ``package``: where to look (this package).
    An ImportError names a kind's module that lacks one of :data:`DECLARES`."""
    found = discover(package, path, ("NAME", "Symbolic"), lambda m: m.NAME, "actuator kind")
    for name, mod in found.items():
        missing = [a for a in DECLARES if not hasattr(mod, a)]
        if missing:
            raise ImportError(f"actuator kind {name!r} ({mod.__name__}) does not declare {', '.join(missing)}: "
                              "every kind declares them (hydrogen/actuators/__init__.py says what each is)")
    return {k: found[k] for k in sorted(found, key=lambda k: (k != DEFAULT_KIND, k))}


_REGISTRY = _discover()

#: The actuator kinds: the default (the paper's three-way cylinder) first, then by name.
KINDS = tuple(_REGISTRY)


def actuator(kind: str):
    """The module of actuator ``kind``; a :class:`~hydrogen.errors.ModelError` listing the known
    kinds if there is none."""
    try:
        return _REGISTRY[kind]
    except (KeyError, TypeError):
        raise ModelError(f"unknown actuator kind {kind!r}; known kinds: {', '.join(KINDS)}") from None


def baked_parameters(cylinder) -> dict:
    """The parameters of ``cylinder`` (a model's, any kind) by name as the derivation holds them
    (:func:`~hydrogen.symbolic.constants.baked_table`): numbers, or symbols of the numbers' table,
    and an exact 0 where a parameter declared ``zero_is_structure`` is 0 (no leakage: its terms drop out)."""
    from ..symbolic.constants import baked_table
    from .declarations import exact_zeros
    mod = actuator(cylinder.kind)
    values = mod.parameters(cylinder.table)
    return baked_table(values, cylinder.name, exact_zeros(mod.PARAMETERS, values))
