"""Robot descriptions: a kinematic tree of rigid links, hydraulic cylinders between links, and
which inertial parameters the controllers adapt. Loaded from TOML (the tree written there, or
read from a URDF file the TOML names) and validated.

A model is plain data. The tree, the cylinders' geometry and their hydraulic constants
(A, a, L, P_s, d, the orifice threshold) and every inertial parameter that is NOT adapted are
baked into the generated C (changing them regenerates code). The adapted parameters θ and the
hydraulic parameters γ = [β, βc] per cylinder are runtime inputs of every generated function,
so the adaptive controllers can feed their estimates and a user can change them without
regenerating. Units are SI; base frame z up; a link's frame sits at its parent joint.

Generalized coordinates q are the joints' coordinates in tree order: one per revolute or
prismatic joint, six per floating joint ([x, y, z, ψ, θ, φ], position in the parent frame and
R = Rz(φ) Ry(θ) Rx(ψ)), none for a fixed joint.
"""
from __future__ import annotations

import hashlib
import json
import os
import stat
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from types import SimpleNamespace

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

import numpy as np

from .actuators import DEFAULT_KIND as _DEFAULT_KIND
from .actuators.declarations import PIN_LENGTH as _PIN_LENGTH, TURNS as _TURNS
from .errors import ModelError
from .plant.supply import Supply
from .schema import default as _default, keys as _keys
from .tree import fixed_path

__all__ = ["Model", "Link", "Joint", "Cylinder", "load_model", "is_shipped", "default_model_path", "models",
           "model_path", "INERTIAL_PARAMETERS", "JOINT_TYPES"]

DEFAULT_MODEL = "ubc_stewart"
#: Pinocchio's dynamic parameters of a link: mass, first moments m·c (link frame, kg m) and the
#: inertia about the link frame's origin (link axes, kg m²).
INERTIAL_PARAMETERS = ("mass", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: Joint type -> number of coordinates. URDF's "continuous" is read as revolute.
JOINT_TYPES = {"revolute": 1, "prismatic": 1, "fixed": 0, "floating": 6}
FLOATING_COORDINATES = ("x", "y", "z", "psi", "theta", "phi")
#: The rigid body's forms a description may ask for (``rigid_body_form``; hydrogen.symbolic.forms).
RIGID_BODY_FORMS = ("auto", "closed", "staged")


@dataclass(frozen=True)
class Quantity:
    """A physical quantity of a description: its sign rule ("positive", "nonnegative" or None),
    the plausible range [low, high] of every value (SI), its unit and where that range is declared
    (named in the message that refuses a value outside)."""

    sign: str | None
    low: float
    high: float
    unit: str
    source: str = "hydrogen.model.QUANTITIES"


#: The physical quantities a description gives besides its actuators' constants (each kind declares
#: those with their ranges: :class:`hydrogen.actuators.declarations.Range`), with plausible ranges
#: (SI). Generous enough for any real machine, from micro-actuators (milligram links) to 100-t
#: excavators, presses and draglines; a value outside is a slip of unit or a typo (1e308 overflows the
#: plant's arithmetic), refused with the range.
QUANTITIES = {
    # m/s^2: 0 (a horizontal or orbital machine) .. 30 (above Jupiter's 24.8)
    "gravity": Quantity("nonnegative", 0.0, 30.0, "m/s^2"),
    # kg per link: 1 mg .. 1000 t (a dragline's boom)
    "mass": Quantity("positive", 1e-6, 1e6, "kg"),
    # kg m^2, a link's principal moments: a 1 mg link 1 um across (1e-18) .. 1000 t at 100 m (1e10)
    "inertia": Quantity("positive", 1e-18, 1e10, "kg m^2"),
    # m: joint origins, centres of mass and cylinder pins, in their frame: within 1 km
    "position": Quantity(None, -1e3, 1e3, "m"),
    # rad: a joint origin's roll, pitch and yaw: within two turns either way
    "angle": Quantity(_TURNS.sign, _TURNS.low, _TURNS.high, "rad"),
    # m: a linkage's rocker and coupler, pin to pin, as a cylinder's length
    "pin_length": Quantity(_PIN_LENGTH.sign, _PIN_LENGTH.low, _PIN_LENGTH.high, "m"),
}
#: A URDF link's inertial is a placeholder, taken as massless with a note, when it is not a rigid
#: body's (inertia not positive definite or breaking the triangle inequality, or a mass under the
#: plausible range) and yet at most PLACEHOLDER_MASS kg with every principal moment at most
#: PLACEHOLDER_INERTIA kg m² in magnitude: exporters write one where a link is a frame (every entry
#: 1e-6, or all zero). Massless, it changes D by at most PLACEHOLDER_MASS r² + 3 PLACEHOLDER_INERTIA
#: (r, m, its distance from a joint axis).
PLACEHOLDER_MASS = 1e-3
PLACEHOLDER_INERTIA = 1e-5
#: Cylinder constants (each declared by the three-way kind): [hydraulics] gives defaults, each [[cylinders]] entry may
#: override them.
HYDRAULIC_KEYS = ("piston_area", "rod_area", "chamber_length", "supply_pressure", "underlap", "flow_gain",
                  "bulk_modulus", "orifice_linear_below", "stroke", "leakage")
#: The actuator kind of a cylinder that names none (``kind``, in [[cylinders]] or [hydraulics]).
DEFAULT_KIND = _DEFAULT_KIND
#: The constants every cylinder kind has, held as :class:`Cylinder` fields (the rest of a kind's
#: parameters are in ``Cylinder.params``); ``stroke`` is the pair (stroke_min, stroke_max).
SHARED_KEYS = ("supply_pressure", "underlap", "flow_gain", "bulk_modulus", "orifice_linear_below", "stroke")
#: Order between two constants of one cylinder: (smaller, larger, strict, why). The loader refuses a
#: description that breaks one; the exported programs (C and FMU) refuse edited numbers that do.
CYLINDER_ORDER = (
    ("rod_area", "piston_area", True, "the rod side's annulus is the piston area less the rod's section"),
    ("chamber_length", "stroke_min", True, "the control chamber keeps a positive volume at the shortest length"),
    ("annulus_area", "cap_area", False, "the annulus is the cap area less the rod's section"),
    ("tank_pressure", "supply_pressure", True, "oil flows from supply to tank"),
    ("stroke_min", "stroke_max", True, "[shortest, longest] length"),
    ("angle_min", "angle_max", True, "[lowest, highest] angle"),
)
#: The smallest positive double: the low end of a range "> 0" (closed ranges hold every rule).
POSITIVE = 5e-324
#: Largest description file read (the TOML and the URDF it names), bytes: the shipped ones are a few kB.
MAX_DESCRIPTION_BYTES = 16 * 1024 * 1024
_MAX_QUOTE = 200  # characters of a bad value quoted in an error message


def _quote(value) -> str:
    text = repr(value)
    return text if len(text) <= _MAX_QUOTE else text[:_MAX_QUOTE] + f"... ({len(text)} characters)"


def default_model_path() -> Path:
    """Path of the default model file shipped inside the package."""
    return model_path(DEFAULT_MODEL)


def _data_dir() -> Path:
    return Path(str(resources.files("hydrogen") / "data"))


def models() -> list:
    """Names of the built-in models (``hydrogen.load_model(name)`` loads one)."""
    return sorted(p.stem for p in _data_dir().glob("*.toml"))


def model_path(name_or_path) -> Path:
    """The file of a built-in model given its name, or ``name_or_path`` itself as a path."""
    text = str(name_or_path)
    if text in models():
        return _data_dir() / f"{text}.toml"
    return Path(text)


@dataclass(frozen=True)
class Link:
    """A rigid link: mass (kg), centre of mass ``com`` (link frame, m), ``inertia`` (3×3, kg m²)
    about the centre of mass in link axes."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def parameters(self) -> dict:
        """Pinocchio's dynamic parameters: mass, m·c and the inertia about the link origin."""
        m, c, I = self.mass, np.asarray(self.com, float), np.asarray(self.inertia, float)
        Io = I + m * (c @ c * np.eye(3) - np.outer(c, c))
        return {"mass": m, "mcx": m * c[0], "mcy": m * c[1], "mcz": m * c[2],
                "Ixx": Io[0, 0], "Ixy": Io[0, 1], "Iyy": Io[1, 1], "Ixz": Io[0, 2], "Iyz": Io[1, 2],
                "Izz": Io[2, 2]}


@dataclass(frozen=True)
class Joint:
    """A joint from ``parent`` to ``child``: origin (xyz m, rpy rad) in the parent frame, unit
    ``axis`` in the joint frame (revolute, prismatic). ``limit``: the URDF ``<limit>`` (or the TOML
    ``limit`` table) as ``{"lower", "upper", "velocity", "effort"}`` in the joint's units (rad or m,
    rad/s or m/s, N m or N), each key only where given; references are checked against the position
    and velocity limits before a run. Not compiled into C."""

    name: str
    type: str
    parent: str
    child: str
    origin_xyz: np.ndarray
    origin_rpy: np.ndarray
    axis: np.ndarray
    limit: dict = field(default_factory=dict, compare=False)

    @property
    def dof(self) -> int:
        """Number of generalized coordinates the joint contributes (JOINT_TYPES)."""
        return JOINT_TYPES[self.type]


@dataclass(frozen=True)
class Cylinder:
    """A cylinder pinned at ``point_from`` on ``link_from`` and ``point_to`` on ``link_to`` (each in
    its link's frame, m); its length l is pin to pin, within [stroke_min, stroke_max].

    ``kind``: its actuator kind (:mod:`hydrogen.actuators`), e.g. the default three-way-valve cylinder
    (the control chamber, cap side of area A, has volume A (l − L); the rod side, area a, is at P_s;
    force f = p_c A − P_s a). The fields hold what every kind shares (:data:`SHARED_KEYS`: supply, valve
    and oil constants, the travel's range); ``params`` holds the kind's own constants by parameter name,
    SI (a three-way cylinder's piston_area, rod_area, chamber_length, leakage; a four-way cylinder's
    areas and dead volumes; a vane's displacement), as every kind alike. A kind with unlimited travel
    (its TRAVEL not ``limited``) has ``stroke_min`` = −∞ and ``stroke_max`` = ∞."""

    name: str
    link_from: str
    point_from: np.ndarray
    link_to: str
    point_to: np.ndarray
    supply_pressure: float
    underlap: float
    flow_gain: float
    bulk_modulus: float
    orifice_linear_below: float
    stroke_min: float
    stroke_max: float
    kind: str = DEFAULT_KIND
    params: dict = field(default_factory=dict)
    #: a joint actuator's (rotary) joint: its coordinate is the joint's angle, its row of JL that
    #: joint's unit vector; link_from/link_to are the joint's parent and child, the points 0
    joint: str | None = None
    #: a cylinder acting through a planar four-bar linkage: the revolute joint it drives
    #: (link_from is that joint's parent, point_from the cylinder's base on it; link_to the child,
    #: point_to the crank pin where the coupler pins on it) and the linkage's geometry in the
    #: joint's plane (:class:`hydrogen.symbolic.linkage.FourBar`); its length is the linkage's l(q)
    linkage_joint: str | None = None
    linkage: object = None
    #: its datasheet valve's spool response, SI (the description's ``valve``; None: the rig's valve
    #: settings): ``{name: value}`` of each of :data:`hydrogen.plant.valve.PARAMETERS`
    valve: dict | None = None
    #: its seal friction, in its own unit (the description's ``friction`` table, keys of
    #: :data:`hydrogen.plant.friction.KEYS`, each only where given; None: the rig's friction alone)
    friction: dict | None = None

    @property
    def seal_terms(self) -> tuple:
        """(Stribeck dip, pressure load): the seal friction terms its description declares, structure
        (baked, :func:`hydrogen.plant.friction.terms_of`); (False, False) without a friction table."""
        from .plant.friction import terms_of
        return terms_of(self.friction)

    @property
    def valve_limits(self) -> tuple:
        """(saturation, dead band): the plant terms its datasheet valve needs, structure (baked): a
        full opening > 0, an overlap > 0; (False, False) without a datasheet valve."""
        if self.valve is None:
            return (False, False)
        return (self.valve["full_opening"] > 0, self.valve["overlap"] > 0)

    @property
    def travel(self):
        """Its kind's TRAVEL (:class:`~hydrogen.actuators.declarations.Travel`): what its coordinate is
        (a length in m, an angle in rad) and what its range is called, for every message about it."""
        from .actuators import actuator
        return actuator(self.kind).TRAVEL

    @property
    def table(self) -> dict:
        """Every parameter of its kind by name (SI), for ``actuator(kind).parameters(table)``."""
        from .actuators import actuator
        pars = actuator(self.kind).PARAMETERS
        # a parameter neither in params nor a field (a three-way cylinder built without its optional
        # constants) takes its declared default
        return {p.name: self.params[p.name] if p.name in self.params else getattr(self, p.name, p.default)
                for p in pars}


#: The Cylinder fields (what every kind shares); a kind's own constants are in its ``params``.
_CYLINDER_FIELDS = frozenset(f.name for f in fields(Cylinder))


def _stack(name):
    def get(self):
        values = [getattr(c, name) if name in _CYLINDER_FIELDS else c.params.get(name) for c in self.cylinders]
        missing = [c for c, v in zip(self.cylinders, values) if v is None]
        if missing:  # a key of another actuator kind (e.g. piston_area on a four-way cylinder)
            c = missing[0]
            raise AttributeError(f"{self.source}: '{name}' is not a parameter of cylinder '{c.name}' (kind {c.kind}); "
                                 f"its parameters are model.cylinders[{self.cylinders.index(c)}].table")
        return np.array(values, float)
    return property(get, doc=f"Per-cylinder {name} (m,), SI (cylinders whose kind has it).")


@dataclass(frozen=True)
class Model:
    """A hydraulic manipulator. All values SI; see the module docstring."""

    name: str
    gravity: float
    root: str
    links: tuple
    joints: tuple
    cylinders: tuple
    coordinate_names: tuple
    neutral_pose: np.ndarray
    theta_names: tuple
    theta_min: np.ndarray
    theta_max: np.ndarray
    gamma1_min: float
    gamma1_max: float
    gamma2_min: float
    gamma2_max: float
    joint_encoders: bool = False
    scale: np.ndarray = None
    #: ``[control] friction_compensation``: the controllers that can compensate friction
    #: (backstepping, adaptive-robust, adaptive-observer) are generated with it (a deviation from the
    #: paper, its coefficients gains; docs/guide/controllers.md). Off: the paper's laws, as generated.
    friction_compensation: bool = False
    # The controller the figures and their table call "nonlinear" ([figures] nonlinear); default the
    # paper's experiments' controller (Theorem 3). Checked against the controllers where it is used.
    figures_nonlinear: str = field(default="adaptive-robust", compare=False)
    gains: dict = field(default_factory=dict, repr=False, compare=False)
    scenarios: dict = field(default_factory=dict, repr=False, compare=False)
    # [variants.<name>]: scenario fields (and gains) set over any scenario run as "<scenario>.<name>"
    variants: dict = field(default_factory=dict, repr=False, compare=False)
    # "auto" (chosen by cost), "closed" or "staged": the rigid body's form (hydrogen.symbolic.forms)
    rigid_body_form: str = "auto"
    # the controllers generated for this robot, in the registry's order (the description's
    # ``controllers``; default all): what a whole generation holds, what a run may ask for
    controllers: tuple = field(default=None, compare=False)
    # [supply]: what feeds the valves (hydrogen.plant.supply); constant: each actuator's supply_pressure
    supply: Supply = field(default_factory=Supply)

    def __post_init__(self):
        if self.controllers is None:  # a Model made in code: every controller
            from .controllers import CONTROLLERS
            object.__setattr__(self, "controllers", tuple(CONTROLLERS))

    def not_listed(self, controller: str) -> str:
        """The message for a controller this description does not list (its ``controllers``)."""
        return (f"{self.source}: controllers: controller '{controller}' is not generated for '{self.name}' (its "
                f"description lists {', '.join(self.controllers)}); add it to controllers to run it (a shipped "
                "robot's: in a copy of its description, or in code dataclasses.replace(model, "
                f"controllers=(*model.controllers, '{controller}')))")
    source: str = "<memory>"
    urdf: Path | None = None
    raw: dict = field(default=None, repr=False, compare=False)

    # --- sizes ---------------------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of generalized coordinates."""
        return len(self.coordinate_names)

    @property
    def coordinate_units(self) -> tuple:
        """"m" or "rad" per coordinate (prismatic and floating translations are lengths)."""
        out = []
        for j in self.joints:
            out += {"revolute": ["rad"], "prismatic": ["m"], "fixed": [],
                    "floating": ["m"] * 3 + ["rad"] * 3}[j.type]
        return tuple(out)

    def coordinate_limits(self) -> dict:
        """Per coordinate (arrays of n): ``lower``, ``upper`` (rad or m) and ``velocity`` (rad/s or
        m/s) from the joints' limits; ±inf where a joint gives none (and for floating joints)."""
        out = {"lower": [], "upper": [], "velocity": []}
        for j in self.joints:
            for _ in range(j.dof):
                lim = j.limit if j.type in ("revolute", "prismatic") else {}
                out["lower"].append(lim.get("lower", -np.inf))
                out["upper"].append(lim.get("upper", np.inf))
                out["velocity"].append(lim.get("velocity", np.inf))
        return {k: np.array(v, float) for k, v in out.items()}

    def coordinate_joint(self, i: int) -> str:
        """The name of the joint coordinate ``i`` belongs to."""
        k = 0
        for j in self.joints:
            if k + j.dof > i:
                return j.name
            k += j.dof
        raise IndexError(i)

    @property
    def n_cylinders(self) -> int:
        """Number of cylinders (one per coordinate)."""
        return len(self.cylinders)

    @property
    def n_theta(self) -> int:
        """Number of adapted inertial parameters θ."""
        return len(self.theta_names)

    def link(self, name: str) -> Link:
        """The moving link called ``name``."""
        return next(lk for lk in self.links if lk.name == name)

    # --- parameters -----------------------------------------------------------------------
    @property
    def theta(self) -> np.ndarray:
        """True values of the adapted inertial parameters θ (``theta_names``), SI."""
        return np.array([self.link(n.split(".")[0]).parameters()[n.split(".")[1]] for n in self.theta_names])

    @property
    def gamma(self) -> np.ndarray:
        """True hydraulic parameters (2, m): rows γ1 = β (Pa) and γ2 = βc per cylinder."""
        return np.array([[c.bulk_modulus for c in self.cylinders],
                         [c.bulk_modulus * c.flow_gain for c in self.cylinders]])

    piston_area = _stack("piston_area")
    rod_area = _stack("rod_area")
    chamber_length = _stack("chamber_length")
    supply_pressure = _stack("supply_pressure")
    underlap = _stack("underlap")
    flow_gain = _stack("flow_gain")
    bulk_modulus = _stack("bulk_modulus")
    orifice_linear_below = _stack("orifice_linear_below")
    leg_min = _stack("stroke_min")
    leg_max = _stack("stroke_max")

    @property
    def seal_friction(self) -> bool:
        """Whether an actuator declares seal friction terms (:attr:`Cylinder.seal_terms`): the plant's
        input ``friction`` then has every actuator's seal numbers too
        (:func:`hydrogen.plant.friction.parameters_of`)."""
        return any(any(c.seal_terms) for c in self.cylinders)

    def inertial_parameters(self) -> dict:
        """Every link's dynamic parameters: ``"link.param"`` -> value (see INERTIAL_PARAMETERS)."""
        return {f"{lk.name}.{k}": v for lk in self.links for k, v in lk.parameters().items()}

    # --- the part compiled into C ---------------------------------------------------------
    def baked(self) -> dict:
        """The part of the model compiled into C: the tree, the cylinders (without β and c, which
        are runtime γ), the inertial parameters that are not adapted, gravity."""
        adapted = set(self.theta_names)
        return {
            "name": self.name, "gravity": self.gravity, "root": self.root,
            "joints": [[j.name, j.type, j.parent, j.child, np.asarray(j.origin_xyz).tolist(),
                        np.asarray(j.origin_rpy).tolist(), np.asarray(j.axis).tolist()] for j in self.joints],
            "inertial": {k: (None if k in adapted else v) for k, v in self.inertial_parameters().items()},
            "theta_names": list(self.theta_names),
            "cylinders": [_baked_cylinder(c) for c in self.cylinders],
            "coordinates": list(self.coordinate_names),
            # recorded only when forced, so an "auto" model's hash is what it always was ("auto" is a
            # function of the rest and of the derivation code, which the derivation hash covers)
            **({"rigid_body_form": self.rigid_body_form} if self.rigid_body_form != "auto" else {}),
            # recorded only when on: the generated controllers differ, and a model without it hashes as before
            **({"friction_compensation": True} if self.friction_compensation else {}),
            # recorded only when not constant: a robot on a constant supply hashes as before
            **({"supply": [self.supply.kind, dict(sorted(self.supply.values.items()))]}
               if not self.supply.constant else {}),
        }

    def baked_hash(self) -> str:
        """SHA-256 of the baked part, canonical JSON (floats by repr), so equal models hash equal."""
        text = json.dumps(self.baked(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def rigid_body_form_chosen(self) -> str:
        """The form the rigid body takes, "closed" or "staged": ``rigid_body_form``, or for "auto"
        the cheaper (:func:`hydrogen.symbolic.forms.rigid_body_form`, once per process). The
        derivation's tree asks its model: choosing derives trees of both forms, so it is made here,
        above the tree, not by the tree itself."""
        from .symbolic.forms import rigid_body_form
        return rigid_body_form(self)

    def structure(self) -> dict:
        """:meth:`baked` with every number replaced by its class: 0, 1 and -1 stay (the derivation
        holds them exact: a zero coordinate, a unit axis), any other becomes "x". Two descriptions of
        equal structure differ in numbers only, which a parametric derivation takes as inputs."""
        def mask(v):
            if isinstance(v, bool) or v is None or isinstance(v, str):
                return v
            if isinstance(v, (int, float)):
                return float(v) + 0.0 if float(v) in (0.0, 1.0, -1.0) else "x"  # + 0.0: -0.0 is 0
            if isinstance(v, dict):
                return {k: mask(x) for k, x in v.items()}
            return [mask(x) for x in v]
        return mask(self.baked())

    def numbers(self) -> dict:
        """The description's numbers by the names the derivation gives them when it leaves them
        as symbols (:func:`hydrogen.symbolic.constants.numbers_as_symbols`): ``gravity`` (m/s²);
        ``<joint>.origin_xyz[k]`` (m), ``.origin_rpy[k]`` (rad), ``.axis[k]``; ``<link>.<parameter>``
        (kg, kg m, kg m², link frame); ``<cylinder>.from[k]``, ``.to[k]`` (m, the link's frame),
        ``.<parameter>`` (its kind's, SI) and ``.linkage.<field>`` (m, rad). A derivation reads
        the subset it needs; a number it holds exact (a zero, a unit axis entry) is structure."""
        return {name: value for name, (value, _) in self._numbered().items()}

    def number_ranges(self) -> dict:
        """``{name: (low, high)}`` of every number of :meth:`numbers` (SI, inclusive; None: unbounded):
        the range the loader holds it to (QUANTITIES, or an actuator kind's declaration), or, for one it derives (the inertia about the
        link origin, m·c, a linkage's plane geometry), the range those checks imply. An exported
        program (C, FMU) refuses an edited number outside it."""
        return {name: rng for name, (_, rng) in self._numbered().items()}

    def number_orders(self) -> list:
        """``(smaller, larger, strict, why)``: the rules of CYLINDER_ORDER between two numbers of one
        cylinder, the numbers by name (both of :meth:`numbers`)."""
        names = self._numbered()
        return [(f"{c.name}.{a}", f"{c.name}.{b}", strict, why) for c in self.cylinders
                for a, b, strict, why in CYLINDER_ORDER if f"{c.name}.{a}" in names and f"{c.name}.{b}" in names]

    def _numbered(self) -> dict:
        """``{name: (value, (low, high))}``: :meth:`numbers` with :meth:`number_ranges`, made together
        so the two always name the same numbers."""
        from .actuators import actuator

        def span(q):
            return (float(q.low), float(q.high))

        pos, mass, inertia = QUANTITIES["position"], QUANTITIES["mass"], QUANTITIES["inertia"]
        mc = mass.high * pos.high  # |m c| per axis, c within the position range
        # about the origin: I_oo = I_cc + m (c_j^2 + c_k^2) and I_oj = I_cj - m c_o c_j, where a
        # diagonal entry of I_c is inside its principal moments and an off-diagonal one inside the largest
        inertial = {"mass": span(mass), "mcx": (-mc, mc), "mcy": (-mc, mc), "mcz": (-mc, mc),
                    **{k: (inertia.low, inertia.high + 2 * mc * pos.high) for k in ("Ixx", "Iyy", "Izz")},
                    **{k: (-(inertia.high + mc * pos.high), inertia.high + mc * pos.high)
                       for k in ("Ixy", "Ixz", "Iyz")}}
        # a linkage's lengths as the loader reads them, its crank > 0, its angle of atan2; its plane
        # points are differences of positions in rotated frames: any finite value
        linkage = {"crank": (POSITIVE, None), "crank_offset": (-np.pi, np.pi),
                   "coupler": span(QUANTITIES["pin_length"]), "rocker": span(QUANTITIES["pin_length"])}
        ranges = {"origin_xyz": span(pos), "origin_rpy": span(QUANTITIES["angle"]),
                  "axis": (-1.0, 1.0),  # a unit vector's entries
                  "from": span(pos), "to": span(pos)}

        def vector(name, key, values):
            return {f"{name}.{key}[{k}]": (float(v), ranges[key]) for k, v in enumerate(values)}

        out = {"gravity": (float(self.gravity), span(QUANTITIES["gravity"]))}
        for j in self.joints:
            for key in ("origin_xyz", "origin_rpy", "axis"):
                out.update(vector(j.name, key, getattr(j, key)))
        for lk in self.links:  # a massless link (a URDF frame link) is held to none: 0 is its only value
            out.update({f"{lk.name}.{k}": (float(v), inertial[k] if lk.mass else (0.0, 0.0))
                        for k, v in lk.parameters().items()})
        for c in self.cylinders:
            out.update(vector(c.name, "from", c.point_from))
            out.update(vector(c.name, "to", c.point_to))
            for k, v in actuator(c.kind).parameters(c.table).items():
                q = declared_range(c.kind, k)
                out[f"{c.name}.{k}"] = (float(v), (None, None) if q is None else span(q))
            if c.linkage is not None:
                for k, v in c.linkage.numbers(c.name).items():
                    field = k[len(f"{c.name}.linkage."):]
                    out[k] = (v, linkage.get(field, (None, None)))
        for k, v in self.supply.numbers().items():  # none for a constant supply
            q = supply_range(k[len("supply."):])
            out[k] = (v, (None, None) if q is None else span(q))
        return out


def _baked_cylinder(c: Cylinder) -> list:
    """What a cylinder bakes into the derivation, the same list for every kind: its pins, the hydraulic
    constants, its kind with its parameters and travel, then what only some have (a linkage, a joint,
    a datasheet valve's limits, seal terms), each appended only when present."""
    from .actuators import actuator
    from .actuators.declarations import exact_zeros
    pars = actuator(c.kind).PARAMETERS
    # a parameter whose 0 is structure is left out at 0, so a description without leakage hashes as one with 0
    skip = exact_zeros(pars, c.table) | {p.name for p in pars if p.gamma}  # γ: runtime, not baked
    params = {k: v for k, v in sorted(c.params.items()) if k not in skip}
    out = [c.name, c.link_from, np.asarray(c.point_from).tolist(), c.link_to, np.asarray(c.point_to).tolist(),
           c.supply_pressure, c.underlap, c.orifice_linear_below, c.kind, params, [c.stroke_min, c.stroke_max]]
    if c.joint is not None:
        out += [["joint", c.joint]]
    if c.linkage is not None:
        g = c.linkage
        out += [["linkage", c.linkage_joint, g.crank, g.crank_offset, g.coupler, g.rocker, list(g.rocker_pivot),
                 list(g.cylinder_base), g.branch]]
    if any(c.valve_limits):  # the plant's valve terms differ
        out += [["valve_limits", *c.valve_limits]]
    if any(c.seal_terms):  # the plant's friction terms differ
        out += [["seal_terms", *c.seal_terms]]
    return out


# ------------------------------------------------------------------------------------------
# Parsing and validation


def _is_number(v) -> bool:
    # numpy's integers too (a dict made in Python: np.float64 is a float already)
    return isinstance(v, (int, float, np.integer)) and not isinstance(v, (bool, np.bool_))


class _Reader:
    """Reads typed values out of parsed TOML, every error naming the file and the key."""

    def __init__(self, source: str):
        self.source = source

    def error(self, where: str, msg: str) -> ModelError:
        return ModelError(f"{self.source}: {where}: {msg}")

    def number(self, where, value, constraint=None) -> float:
        if not _is_number(value):
            raise self.error(where, f"expected a number, got {type(value).__name__} {_quote(value)}")
        return self._check(where, np.array(float(value)), constraint, value).item()

    def vector(self, where, value, size=None, constraint=None) -> np.ndarray:
        if not isinstance(value, list) or not all(_is_number(x) for x in value) \
                or (size is not None and len(value) != size):
            want = f"a list of {size} numbers" if size is not None else "a list of numbers"
            raise self.error(where, f"expected {want}, got {_quote(value)}")
        return self._check(where, np.array(value, float), constraint, value)

    def _check(self, where, arr, constraint, value):
        """``constraint``: a sign rule ("positive", "nonnegative"), a :class:`Quantity` or the name of
        one of QUANTITIES, or None."""
        quantity = constraint if isinstance(constraint, Quantity) else QUANTITIES.get(constraint)
        sign = quantity.sign if quantity is not None else constraint
        if not np.all(np.isfinite(arr)):
            raise self.error(where, f"must be finite, got {_quote(value)}")
        if sign == "positive" and not np.all(arr > 0):
            raise self.error(where, f"must be > 0, got {_quote(value)}")
        if sign == "nonnegative" and not np.all(arr >= 0):
            raise self.error(where, f"must be >= 0, got {_quote(value)}")
        if quantity is not None:
            _in_range(self, where, arr, quantity)
        return arr

    def name(self, where, value) -> str:
        if not isinstance(value, str) or not value:
            raise self.error(where, f"expected a name (string), got {_quote(value)}")
        return value

    def label(self, where, value) -> str:
        """A name written into generated files (:func:`hydrogen.names.check_name`)."""
        from .names import check_name
        return check_name(value, f"{self.source}: {where}")

    def table(self, data, key, where=None, required=True) -> dict:
        value = data.get(key)
        if value is None:
            if required:
                raise ModelError(f"{self.source}: missing table [{key}]" if where is None
                                 else f"{self.source}: {where}: missing key '{key}'")
            return {}
        if not isinstance(value, dict):
            raise self.error(where or f"[{key}]", f"expected a table, got {_quote(value)}")
        return value

    def known(self, data: dict, keys, where: str, renamed=None):
        for key in data:
            if key not in keys and key in (renamed or {}):
                raise self.error(where, f"'{key}' is now {renamed[key]}")
            if key not in keys:
                raise self.error(where, f"unknown key '{key}' (known: {', '.join(sorted(keys))})")

    def require(self, data: dict, key: str, where: str):
        if key not in data:
            raise self.error(where, f"missing key '{key}'")
        return data[key]


def _in_range(r: _Reader, where, arr, q: Quantity):
    outside = np.asarray(arr, float)[(arr < q.low) | (arr > q.high)]
    if outside.size:
        raise r.error(where, f"{outside[0]:.6g} {q.unit} is outside the plausible range [{q.low:.6g}, "
                             f"{q.high:.6g}] {q.unit} of any hydraulic machine ({q.source})")


def check_model_name(source: str, value) -> str:
    """A model name becomes C symbols and file names (:func:`hydrogen.names.check_identifier`)."""
    from .names import check_identifier
    return check_identifier(value, f"{source}: name")


def _inertia_matrix(r: _Reader, where, value) -> np.ndarray:
    v = r.vector(where, value)
    if v.size == 3:
        I = np.diag(v)
    elif v.size == 6:  # Ixx Iyy Izz Ixy Ixz Iyz
        I = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    else:
        raise r.error(where, f"expected [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], got {_quote(value)}")
    return _positive_inertia(r, where, I)


def _positive_inertia(r: _Reader, where, I, hint: str = "") -> np.ndarray:
    """``I`` (kg m²) checked as a rigid body's; ``hint`` ends the message of a refusal."""
    eig = np.linalg.eigvalsh(I)
    if not np.all(eig > 0):
        raise r.error(where, f"the inertia tensor must be positive definite (principal moments {eig.tolist()}){hint}")
    # the triangle inequality of a physical body's principal moments
    if eig[0] + eig[1] < eig[2] * (1 - 1e-9):
        raise r.error(where, f"principal moments {eig.tolist()} violate I1 + I2 >= I3 (no rigid body has them){hint}")
    _in_range(r, f"{where} (principal moments)", eig, QUANTITIES["inertia"])
    return I


def _tree_from_toml(r: _Reader, data: dict):
    links, joints = [], []
    raw_links = data.get("links")
    if not isinstance(raw_links, list) or not raw_links:
        raise r.error("[[links]]", "expected at least one [[links]] table (or a 'urdf' file)")
    for i, lk in enumerate(raw_links):
        w = f"[[links]] #{i + 1}"
        if not isinstance(lk, dict):
            raise r.error(w, f"expected a table, got {_quote(lk)}")
        name = r.name(f"{w} name", r.require(lk, "name", w))
        w = f"[[links]] '{name}'"
        r.known(lk, _keys("[[links]]"), w)
        raw = r.require(lk, "mass", w)
        if isinstance(raw, (int, float)) and not isinstance(raw, bool) and raw == 0:
            # a frame (a sensor, a tool point), as a URDF link without an inertial: no com, no inertia
            given = [k for k, sizes in (("com", (3,)), ("inertia", (3, 6))) if k in lk and not _all_zero(lk[k], sizes)]
            if given:
                raise r.error(f"{w} mass", f"must be > 0, or 0 for a massless frame with no {' and no '.join(given)} "
                                           f"(got {given[0]} = {_quote(lk[given[0]])})")
            links.append(Link(name, 0.0, np.zeros(3), np.zeros((3, 3))))
            continue
        mass = r.number(f"{w} mass", raw, "mass")
        com = r.vector(f"{w} com", lk.get("com", _default("[[links]]", "com")), 3, "position")
        inertia = _inertia_matrix(r, f"{w} inertia", r.require(lk, "inertia", w))
        links.append(Link(name, mass, com, inertia))
    raw_joints = data.get("joints")
    if not isinstance(raw_joints, list) or not raw_joints:
        raise r.error("[[joints]]", "expected at least one [[joints]] table")
    for i, jt in enumerate(raw_joints):
        w = f"[[joints]] #{i + 1}"
        if not isinstance(jt, dict):
            raise r.error(w, f"expected a table, got {_quote(jt)}")
        name = r.name(f"{w} name", r.require(jt, "name", w))
        w = f"[[joints]] '{name}'"
        r.known(jt, _keys("[[joints]]"), w)
        jtype = _joint_type(r, w, r.require(jt, "type", w))
        limit = r.table(jt, "limit", f"{w}", required=False)
        r.known(limit, set(LIMIT_KEYS), f"{w} limit")
        joints.append(Joint(name, jtype, r.name(f"{w} parent", r.require(jt, "parent", w)),
                            r.name(f"{w} child", r.require(jt, "child", w)),
                            r.vector(f"{w} origin_xyz", jt.get("origin_xyz", _default("[[joints]]", "origin_xyz")), 3,
                                     "position"),
                            r.vector(f"{w} origin_rpy", jt.get("origin_rpy", _default("[[joints]]", "origin_rpy")), 3,
                                     "angle"),
                            _axis(r, f"{w} axis", jt.get("axis", _default("[[joints]]", "axis"))),
                            _limit(r, f"{w} limit", {k: v for k, v in limit.items()})))
    return links, joints


def _all_zero(value, sizes) -> bool:
    """Whether a description's list is ``sizes`` (one of them) zeros: a massless frame's com or inertia
    written out."""
    return isinstance(value, list) and len(value) in sizes and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and v == 0 for v in value)


#: The keys of a joint limit (URDF ``<limit>`` attributes, TOML ``limit`` table), joint units.
LIMIT_KEYS = ("lower", "upper", "velocity", "effort")


def _limit(r: _Reader, where, given: dict) -> dict:
    """A joint's limits, checked: numbers, velocity and effort > 0, lower < upper where both given."""
    out = {}
    for k, v in given.items():
        out[k] = r.number(f"{where} {k}", v, "positive" if k in ("velocity", "effort") else None)
    if "lower" in out and "upper" in out and not out["lower"] < out["upper"]:
        raise r.error(where, f"lower {out['lower']} must be < upper {out['upper']}")
    return out


def _joint_type(r: _Reader, where, value) -> str:
    t = r.name(f"{where} type", value)
    t = "revolute" if t == "continuous" else t
    if t not in JOINT_TYPES:
        raise r.error(f"{where} type", f"joint type '{t}' is not supported (supported: revolute, continuous, "
                                      f"prismatic, fixed, floating; planar and spherical are not)")
    return t


def _axis(r: _Reader, where, value) -> np.ndarray:
    a = r.vector(where, list(map(float, value)) if isinstance(value, (list, np.ndarray)) else value, 3)
    if not np.any(a != 0):
        raise r.error(where, "the joint axis must not be zero")
    a = a / np.max(np.abs(a))  # first, so the norm of huge components does not overflow
    return a / np.linalg.norm(a)


#: The numbers of a URDF that hydrogen reads, checked (with the element named) before
#: :mod:`hydrogen.urdf` turns them into links and joints: element -> {path below it: {attribute: (count, quantity of QUANTITIES or None)}}; the
#: ``limit`` and ``dynamics`` numbers, which hydrogen does not use yet, only as numbers.
_URDF_NUMBERS = {
    "link": {"inertial/origin": {"xyz": (3, "position"), "rpy": (3, "angle")},
             "inertial/mass": {"value": (1, "mass")},
             "inertial/inertia": {k: (1, None) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}},
    "joint": {"origin": {"xyz": (3, "position"), "rpy": (3, "angle")}, "axis": {"xyz": (3, None)},
              "limit": {k: (1, "any") for k in ("lower", "upper", "effort", "velocity")},
              "dynamics": {k: (1, "any") for k in ("damping", "friction")}},
}


def _tree_from_urdf(path: Path, data: bytes, select):
    """Links and joints of URDF file ``path`` (its bytes ``data``) that ``select(link names, joints)``
    keeps (it returns the names of the links kept: :func:`_kept_links`): parsed strictly by
    :mod:`hydrogen.urdf` (lxml, no entities), the whole file's structure checked, then the numbers
    and inertias of what is kept only, each element named (a file must still be URDF: a number that
    is not one is refused anywhere, as any URDF reader does). Joint origins are the file's numbers (a
    rotation matrix would round the rpy)."""
    from .urdf import load_robot, parse_xml  # lxml, strict, no entities

    root = parse_xml(path, data)
    ur = _Reader(str(path))
    kept = select([el.get("name") for el in root.findall("link")], _check_urdf(ur, root))
    numbers = _check_urdf_elements(ur, root, kept)
    robot = load_robot(path, data)
    by_child = {j.child: j for j in robot.joints if j.parent in kept and j.child in kept}

    def moved_by(name):  # the moving joint the link hangs from (through fixed joints), None if static
        path = fixed_path(by_child, name)
        top = path[-1].parent if path else name
        return by_child[top].name if top in by_child else None  # None: the root or fixed to it

    links = []
    for lk in robot.links:
        w = f"link '{lk.name}'"
        if lk.name not in by_child:
            continue  # the root or a link left out (or a loose link, named by the tree check)
        massless = Link(lk.name, 0.0, np.zeros(3), np.zeros((3, 3)))
        joint = moved_by(lk.name)
        if joint is None or lk.inertial is None or lk.inertial.mass is None or lk.inertial.mass == 0:
            # a placeholder on the fixed base, or a massless frame link (Pinocchio accepts both): mass 0
            links.append(massless)
            if joint is not None:
                _note(f"{path}: {w} has no mass: it moves as a frame only" + (
                    f" (joint '{joint}' it moves with must move a link with mass)" if by_child[lk.name].type == "fixed"
                    else " (its parent joint must move a link with mass below it)"))
            continue
        T = np.asarray(lk.inertial.origin if lk.inertial.origin is not None else np.eye(4), float)
        mass = numbers["link", lk.name]["inertial/mass", "value"]
        I = T[:3, :3] @ np.asarray(lk.inertial.inertia, float) @ T[:3, :3].T
        try:
            links.append(Link(lk.name, ur.number(f"{w} <inertial><mass value>", mass, "mass"), T[:3, 3].copy(),
                              _positive_inertia(ur, f"{w} inertia", I, hint=(
                                  f"; it moves with joint '{joint}', so it enters the dynamics (massless placeholders: "
                                  f"mass <= {PLACEHOLDER_MASS:g} kg, principal moments <= {PLACEHOLDER_INERTIA:g} "
                                  "kg m^2; a link on a fixed joint can be left out with [tree] drop)"))))
        except ModelError:
            moments = np.abs(np.linalg.eigvalsh(I))
            if not (mass <= PLACEHOLDER_MASS and moments.max() <= PLACEHOLDER_INERTIA):
                raise
            links.append(massless)
            _note(f"{path}: {w} has a placeholder inertial (mass {mass:g} kg, principal moments up to "
                  f"{moments.max():.3g} kg m^2, not a rigid body's): taken as massless, it moves as a frame only")
    joints = []
    for jt in robot.joints:
        if jt.parent not in kept or jt.child not in kept:
            continue
        w = f"joint '{jt.name}'"
        jtype = _joint_type(ur, w, jt.type)
        given = numbers["joint", jt.name]
        axis = jt.axis if jt.axis is not None else [1.0, 0.0, 0.0]
        lim = jt.limit
        limit = {} if lim is None else {k: getattr(lim, k) for k in LIMIT_KEYS if getattr(lim, k) is not None}
        if jtype == "revolute" and jt.type == "continuous":  # URDF: a continuous joint's bounds are ignored
            limit = {k: v for k, v in limit.items() if k not in ("lower", "upper")}
        joints.append(Joint(jt.name, jtype, jt.parent, jt.child, given.get(("origin", "xyz"), np.zeros(3)),
                            given.get(("origin", "rpy"), np.zeros(3)),
                            _axis(ur, f"{w} <axis xyz>", list(np.asarray(axis, float))),
                            _limit(ur, f"{w} <limit>", limit)))
    return links, joints


def _check_urdf(ur: _Reader, root) -> list:
    """Check a parsed URDF's structure (names, joints' types and links); every error names the
    element. Returns the joints (name, type, parent, child) the sub-tree is selected from."""
    if root.tag != "robot":
        raise ur.error("root element", f"<{root.tag}> is not <robot name=\"...\">: this is not a URDF file")
    if not root.get("name"):
        raise ur.error("root element <robot>", "lacks the attribute 'name'")
    names = {"link": [], "joint": []}
    for kind in names:
        for i, el in enumerate(root.findall(kind)):
            name = el.get("name")
            if not name:
                raise ur.error(f"<{kind}> #{i + 1}", "lacks the attribute 'name'")
            if name in names[kind]:
                raise ur.error(f"{kind} '{name}'", f"is defined twice ({kind} names must be distinct)")
            names[kind].append(name)
    links = names["link"]
    joints = []
    for el in root.findall("joint"):
        w = f"joint '{el.get('name')}'"
        if not el.get("type"):
            raise ur.error(w, "lacks the attribute 'type'")
        ends = {}
        for end in ("parent", "child"):
            e = el.find(end)
            if e is None or not e.get("link"):
                raise ur.error(w, f"lacks <{end} link=\"...\">")
            if e.get("link") not in links:
                raise ur.error(w, f"names {end} link '{e.get('link')}' that is not defined "
                                  f"(links: {', '.join(links)})")
            ends[end] = e.get("link")
        joints.append(SimpleNamespace(name=el.get("name"), type=el.get("type"), **ends))
    return joints


def _check_urdf_elements(ur: _Reader, root, kept) -> dict:
    """Check the links named in ``kept``, and the joints between two of them, of a parsed URDF; every
    error names the element. Returns the numbers of _URDF_NUMBERS given: (element, name) ->
    {(path, attribute): value}."""
    numbers = {}
    for el in root.findall("link"):
        if el.get("name") not in kept:
            continue
        numbers["link", el.get("name")] = _urdf_numbers(ur, f"link '{el.get('name')}'", el, _URDF_NUMBERS["link"])
        inertial = el.find("inertial")
        if inertial is None:
            continue
        w = f"link '{el.get('name')}' <inertial>"
        mass, inertia = inertial.find("mass"), inertial.find("inertia")
        if mass is not None and mass.get("value") is None:
            raise ur.error(w, "its <mass> lacks the attribute 'value'")
        if inertia is None:
            raise ur.error(w, "lacks <inertia ixx=... ixy=... ixz=... iyy=... iyz=... izz=...>")
        absent = [k for k in _URDF_NUMBERS["link"]["inertial/inertia"] if inertia.get(k) is None]
        if absent:  # a lenient reader would take 1 or 0 for them
            raise ur.error(w, f"its <inertia> lacks the attribute(s) {', '.join(absent)} (URDF requires all six)")
    for el in root.findall("joint"):
        if el.find("parent").get("link") not in kept or el.find("child").get("link") not in kept:
            continue
        w = f"joint '{el.get('name')}'"
        numbers["joint", el.get("name")] = _urdf_numbers(ur, w, el, _URDF_NUMBERS["joint"])
        mimic = el.find("mimic")
        if mimic is not None:
            raise ur.error(w, f"mimics joint '{mimic.get('joint')}' (<mimic>): mimic joints are not supported "
                              "(their coordinate would be taken as independent); make the joint fixed, or remove "
                              "the <mimic> element to give it a coordinate and a cylinder of its own")
    return numbers


def _urdf_numbers(ur: _Reader, where, element, spec) -> dict:
    out = {}
    for sub, attributes in spec.items():
        e = element.find(sub)
        if e is None:
            continue
        for attr, (count, quantity) in attributes.items():
            text = e.get(attr)
            if text is None:
                continue
            w = f"{where} <{'><'.join(sub.split('/'))} {attr}>"
            try:
                values = [float(x) for x in text.split()]
            except ValueError:
                values = None
            if values is None or len(values) != count:
                raise ur.error(w, f"expected {'a number' if count == 1 else f'{count} numbers'}, got {_quote(text)}")
            if quantity == "mass" and 0 <= values[0] <= PLACEHOLDER_MASS:
                pass  # a massless link (a frame) or a placeholder's mass: checked with the tree
            elif quantity != "any":
                values = ur.vector(w, values, count, quantity)
            out[sub, attr] = values[0] if count == 1 else np.asarray(values, float)
    return out


def _matrix_rpy(R) -> np.ndarray:
    """Roll, pitch, yaw with R = Rz(y) Ry(p) Rx(r) (URDF's convention)."""
    p = np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0]))
    return np.array([np.arctan2(R[2, 1], R[2, 2]), p, np.arctan2(R[1, 0], R[0, 0])])


def _locked(j: Joint, value: float) -> Joint:
    """``j`` held at ``value`` (rad or m) as a fixed joint: its motion folded into the origin."""
    from .tree import axis_rotation, rpy_matrix

    xyz, R = np.asarray(j.origin_xyz, float), rpy_matrix(j.origin_rpy)
    if j.type == "revolute":
        R = R @ axis_rotation(j.axis, value)
    else:
        xyz = xyz + R @ (np.asarray(j.axis, float) * value)
    return Joint(j.name, "fixed", j.parent, j.child, xyz, _matrix_rpy(R), np.asarray(j.axis, float))


def _kept_links(r: _Reader, spec: dict, link_names, joints) -> set:
    """The names of the links a description keeps ([tree]): ``base`` = a link whose sub-tree alone is
    kept, that link becoming the fixed root (what is above it and beside it is left out); ``drop`` =
    fixed joints left out with the sub-tree below them (a sensor frame, a tool). ``joints``: a tree's
    or a URDF's (name, type, parent, child); a note names the links left out."""
    r.known(spec, _keys("[tree]"), "[tree]")
    link_names = set(link_names) | {j.parent for j in joints} | {j.child for j in joints}
    children = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j)

    def below(top):  # top and the links under it
        out, frontier = {top}, [top]
        while frontier:
            for j in children.get(frontier.pop(), []):
                if j.child not in out:
                    out.add(j.child)
                    frontier.append(j.child)
        return out

    kept = link_names
    base = spec.get("base")
    if base is not None:
        base = r.name("[tree] base", base)
        if base not in link_names:
            raise r.error("[tree] base", f"no link '{base}' (links: {', '.join(sorted(link_names))})")
        kept = below(base)
        if kept != link_names:
            _note(f"{r.source}: [tree] base = '{base}': links {sorted(link_names - kept)} are left out (not below "
                  "the base)")
    drop = spec.get("drop", [])
    if not isinstance(drop, list) or not all(isinstance(d, str) and d for d in drop):
        raise r.error("[tree] drop", f"expected a list of joint names, got {_quote(drop)}")
    by_name = {j.name: j for j in joints if j.child in kept and j.parent in kept}
    fixed = sorted(n for n, j in by_name.items() if j.type == "fixed")
    for name in drop:
        j = by_name.get(name)
        if j is None or j.type != "fixed":
            what = f"joint '{name}' is {j.type}" if j is not None else f"no joint '{name}' in the tree kept"
            raise r.error("[tree] drop", f"{what}: only a fixed joint can be dropped (fixed joints: "
                                         f"{', '.join(fixed) or 'none'}; [tree] locked holds a moving one)")
    if drop:
        gone = {n for name in drop for n in below(by_name[name].child)}
        kept = kept - gone
        _note(f"{r.source}: [tree] drop = {drop}: links {sorted(gone)} are left out (below the dropped joints)")
    return kept


def _select_tree(r: _Reader, links, joints, spec: dict, kept=None):
    """The part of a tree a description keeps ([tree]): the links :func:`_kept_links` keeps (``kept``
    when already selected, as a URDF is, with its base's name) and the joints between them, then
    ``locked`` = {joint = position} holds those joints fixed (rad or m: the other legs of a
    quadruped, a gripper)."""
    if not spec:
        return links, joints
    if kept is None:
        kept = _kept_links(r, spec, [lk.name for lk in links], joints)
    base = spec.get("base")
    links = [lk for lk in links if lk.name in kept and lk.name != base]
    joints = [j for j in joints if j.parent in kept and j.child in kept]
    locked = spec.get("locked", {})
    if not isinstance(locked, dict):
        raise r.error("[tree] locked", f"expected a table {{ joint = position }}, got {_quote(locked)}")
    names = {j.name: j for j in joints}
    for jn, value in locked.items():
        if jn not in names:
            raise r.error(f"[tree] locked.{jn}", f"no joint '{jn}' in the tree kept (joints: "
                                                 f"{', '.join(sorted(names))})")
        if names[jn].type not in ("revolute", "prismatic"):
            raise r.error(f"[tree] locked.{jn}", f"joint '{jn}' is {names[jn].type}: only revolute and prismatic "
                                                 "joints can be locked")
        lim = names[jn].limit
        v = r.number(f"[tree] locked.{jn}", value)
        if not lim.get("lower", -np.inf) <= v <= lim.get("upper", np.inf):
            raise r.error(f"[tree] locked.{jn}", f"{v} is outside the joint's limits [{lim.get('lower')}, "
                                                 f"{lim.get('upper')}]")
    return links, [_locked(j, float(locked[j.name])) if j.name in locked else j for j in joints]


def _check_moving_mass(r: _Reader, root, links, joints):
    """Every moving joint must move some mass (else D is singular): massless links are frames only."""
    mass = {lk.name: lk.mass for lk in links}
    below = {}
    for j in reversed(joints):  # tree order reversed: children before parents
        below[j.child] = mass.get(j.child, 0.0) + sum(below.get(k.child, 0.0) for k in joints if k.parent == j.child)
    for j in joints:
        if j.dof and not below[j.child] > 0:
            raise r.error(f"joint '{j.name}'", f"moves no mass: link '{j.child}' and every link below it are "
                                               "massless (give one an <inertial> with a mass, or lock the joint)")


def _note(text: str):
    """One line about how a description was read (a massless link, a locked joint): a warning."""
    import warnings

    from .errors import DescriptionNote
    warnings.warn(text, DescriptionNote, stacklevel=3)


def _order_tree(r: _Reader, links, joints, where):
    """Joints in tree order (parents before children), the root link's name; checks the tree."""
    # Every name of the tree reaches generated C, FMUs and logs: one rule, for TOML and URDF alike.
    for lk in links:
        r.label(f"link {lk.name!r}" if isinstance(lk.name, str) else "link name", lk.name)
    for j in joints:
        r.label(f"joint {j.name!r}", j.name)
        r.label(f"joint '{j.name}' parent", j.parent)
        r.label(f"joint '{j.name}' child", j.child)
    names = [lk.name for lk in links]
    for n in names:
        if names.count(n) > 1:
            raise r.error(where, f"link '{n}' is defined twice")
    joint_names = set()
    for j in joints:
        if j.name in joint_names:
            raise r.error(where, f"joint '{j.name}' is defined twice (joint names must be distinct)")
        joint_names.add(j.name)
    seen_children = {}
    for j in joints:
        if j.child in seen_children:
            raise r.error(f"joint '{j.name}'", f"link '{j.child}' already has a parent joint "
                                               f"('{seen_children[j.child]}'): a loop or a second parent")
        if j.parent == j.child:
            raise r.error(f"joint '{j.name}'", f"joins link '{j.parent}' to itself")
        seen_children[j.child] = j.name
    parents = {j.parent for j in joints}
    roots = sorted(parents - set(seen_children))
    if len(roots) != 1:
        if not roots:
            raise r.error(where, "the joints form a loop: every link has a parent joint, so there is no fixed root")
        parent_of = "; ".join(f"'{rt}' is the parent of joint(s) {[j.name for j in joints if j.parent == rt]}"
                              for rt in roots)
        raise r.error(where, f"the tree has several roots {roots}: every link but one must hang from a joint "
                             f"({parent_of}: a misspelt parent?)")
    root = roots[0]
    link_names = set(names) | {root}
    for j in joints:
        if j.child not in link_names:
            raise r.error(f"joint '{j.name}'", f"child link '{j.child}' is not defined")
    ordered, frontier = [], [root]
    by_parent = {}
    for j in joints:
        by_parent.setdefault(j.parent, []).append(j)
    while frontier:
        p = frontier.pop(0)
        for j in by_parent.get(p, []):
            ordered.append(j)
            frontier.append(j.child)
    if len(ordered) != len(joints):
        done = {j.name for j in ordered}
        loose = [j.name for j in joints if j.name not in done]
        raise r.error(where, f"joints {loose} are not connected to the root '{root}' (a loop in the tree)")
    moving = [lk for lk in links if lk.name != root]
    for lk in moving:
        if lk.name not in seen_children:
            raise r.error(f"link '{lk.name}'", "no joint connects it to the tree")
    return root, tuple(ordered), tuple(moving)


def declared_range(kind: str, key: str) -> Quantity | None:
    """The range of constant ``key`` of an actuator of ``kind``, from the kind's own declarations
    (a parameter's :class:`~hydrogen.actuators.declarations.Range`, or its travel's limits for the
    travel key and its ends), with its unit; None where the kind declares none."""
    from .actuators import actuator
    mod = actuator(kind)
    travel = mod.TRAVEL
    par = next((p for p in mod.PARAMETERS if p.name == key), None)
    if par is not None:
        rng, unit = par.range, par.unit
    elif key == travel.key or key in travel.ends:
        rng, unit = travel.limits, travel.unit
    else:
        return None
    return None if rng is None else Quantity(rng.sign, rng.low, rng.high, unit, f"declared in {mod.__name__}")


def supply_range(key: str) -> Quantity | None:
    """The range of ``[supply]`` key ``key`` as the supply block declares it, with its unit."""
    from .plant import supply as sup
    par = next((p for p in sup.PARAMETERS if p.name == key), None)
    if par is None or par.range is None:
        return None
    rng = par.range
    return Quantity(rng.sign, rng.low, rng.high, par.unit, f"declared in {sup.__name__}")


def _supply(r: _Reader, data: dict, cylinders) -> Supply:
    """The [supply] table: its kind, and that kind's keys (each in its declared range; defaults
    filled in; the oil's bulk_modulus the actuators' when they share one)."""
    from .plant import supply as sup
    table = r.table(data, "supply", required=False)
    r.known(table, _keys("[supply]"), "[supply]")
    kind = table.get("kind", sup.DEFAULT_KIND)
    if not isinstance(kind, str) or kind not in sup.KINDS:
        raise r.error("[supply] kind", f"unknown supply kind {_quote(kind)}; known kinds: {', '.join(sup.KINDS)}")
    takes = sup.NEEDS[kind]
    for key in table:
        if key != "kind" and key not in takes:
            raise r.error(f"[supply] {key}", f"a '{kind}' supply takes no {key}"
                          + (f" (it takes {', '.join(takes)})" if takes else ""))
    if kind == sup.DEFAULT_KIND:
        return Supply()
    values = {}
    for par in sup.PARAMETERS:
        name, where = par.name, f"[supply] {par.name}"
        if name not in takes:
            continue
        if name in table:
            value = table[name]
        elif name == "bulk_modulus":
            shared = sorted({c.bulk_modulus for c in cylinders})
            if len(shared) != 1:
                raise r.error("[supply]", f"missing key 'bulk_modulus' (Pa): the actuators' bulk_modulus differ "
                              f"({', '.join(f'{b:g}' for b in shared)} Pa), so the supply's oil needs its own")
            value = shared[0]
        elif name == "precharge_pressure" and values["accumulator_volume"] == 0.0:
            continue
        elif par.default is not None:
            value = par.default
        else:
            why = " (an accumulator needs its gas precharge)" if name == "precharge_pressure" else ""
            raise r.error("[supply]", f"missing key '{name}' ({par.unit}: {par.doc}) of a '{kind}' supply{why}")
        values[name] = r.number(where, value, supply_range(name))
    if "precharge_pressure" in table and values["accumulator_volume"] == 0.0:
        raise r.error("[supply] precharge_pressure", "given without an accumulator: set accumulator_volume > 0, "
                      "or leave precharge_pressure out")
    for low in ("set_pressure", "precharge_pressure"):
        if low in values and values[low] >= values["relief_pressure"]:
            raise r.error(f"[supply] {low}", f"{values[low]:g} Pa must be below relief_pressure "
                          f"{values['relief_pressure']:g} Pa (else the relief valve opens first)")
    nominal = {c.name: c.supply_pressure for c in cylinders}
    if len(set(nominal.values())) != 1:
        first = next(iter(nominal))
        other = next(k for k, v in nominal.items() if v != nominal[first])
        raise r.error(f"cylinder '{other}' supply_pressure", f"{nominal[other]:g} Pa differs from cylinder "
                      f"'{first}''s {nominal[first]:g} Pa: every actuator draws on the one [supply] (kind '{kind}'), "
                      "whose starting pressure is their shared supply_pressure")
    return Supply(kind, values)


def _travel(kind: str) -> tuple:
    """The travel key of ``kind`` (``stroke`` for a length, ``angle`` for a joint angle, as [min, max])
    and its ends' parameter names: the kind's own declaration (``TRAVEL``)."""
    from .actuators import actuator
    travel = actuator(kind).TRAVEL
    return (travel.key, *travel.ends)


def _motion(kind: str) -> str:
    """``kind``'s MOTION: "revolute" for a joint actuator (its coordinate a joint's angle)."""
    from .actuators import actuator
    return actuator(kind).MOTION


def _kind_keys(kind: str) -> tuple:
    """The description keys of a cylinder of actuator ``kind``: its parameters, with the travel
    limits as one key ``stroke`` = [shortest, longest] (m, as the three-way cylinder's) or, for a
    joint actuator, ``angle`` = [lowest, highest] (rad)."""
    if kind == DEFAULT_KIND:
        return HYDRAULIC_KEYS
    from .actuators import actuator
    key, *ends = _travel(kind)
    names = [p.name for p in actuator(kind).PARAMETERS if p.name not in ends]
    return (*names, key) if key is not None else tuple(names)


def _cylinder_kinds() -> tuple:
    """The actuator kinds a [[cylinders]] entry may name."""
    from .actuators import KINDS
    return KINDS


def _kind(r: _Reader, where: str, value) -> str:
    kinds = _cylinder_kinds()
    if not isinstance(value, str) or value not in kinds:
        raise r.error(where, f"unknown actuator kind {_quote(value)}; known kinds: {', '.join(kinds)}")
    return value


def _cylinders(r: _Reader, data: dict, link_names: set, root_note: str = "", joints: tuple = ()):
    """The [[cylinders]]; ``root_note`` follows the list of links when a cylinder names a link the tree
    lacks (where the root comes from, when a misspelt parent may have made it)."""
    defaults = r.table(data, "hydraulics", required=False)
    all_keys = {"kind"}.union(*(_kind_keys(k) for k in _cylinder_kinds()))
    r.known(defaults, all_keys | {"valve", "friction"}, "[hydraulics]")
    default_kind = _kind(r, "[hydraulics] kind", defaults["kind"]) if "kind" in defaults else DEFAULT_KIND
    raw = data.get("cylinders")
    if not isinstance(raw, list) or not raw:
        raise r.error("[[cylinders]]", "expected one [[cylinders]] table per coordinate")
    out, names, used = [], set(), {"kind", "valve", "friction"}
    for i, cy in enumerate(raw):
        w = f"[[cylinders]] #{i + 1}"
        if not isinstance(cy, dict):
            raise r.error(w, f"expected a table, got {_quote(cy)}")
        name = r.label(f"{w} name", r.require(cy, "name", w))
        w = f"[[cylinders]] '{name}'"
        if name in names:
            raise r.error(w, "a second cylinder of this name")
        names.add(name)
        kind = _kind(r, f"{w} kind", cy["kind"]) if "kind" in cy else default_kind
        keys = _kind_keys(kind)
        used.update(keys)
        if _motion(kind) == "revolute":
            out.append(_joint_actuator(r, w, cy, defaults, kind, keys, joints))
            continue
        r.known(cy, {"name", "from", "to", "linkage", "kind", "valve", "friction", *keys},
                w if kind == DEFAULT_KIND else f"{w} (kind {kind})")
        if "linkage" in cy and "to" in cy:
            raise r.error(w, "give either 'to' (the rod end pinned on a link) or 'linkage' (the rod end on a "
                             "four-bar linkage), not both")
        ends = []
        for end in (("from",) if "linkage" in cy else ("from", "to")):
            e = r.require(cy, end, w)
            we = f"{w} {end}"
            if not isinstance(e, dict):
                raise r.error(we, f"expected {{ link = ..., point = [x, y, z] }}, got {_quote(e)}")
            r.known(e, _keys("[[cylinders]] from/to"), we)
            link = r.name(f"{we}.link", r.require(e, "link", we))
            if link not in link_names:
                raise r.error(f"{we}.link", f"link '{link}' is not in the tree (links: "
                                            f"{', '.join(sorted(link_names))}{root_note})")
            ends.append((link, r.vector(f"{we}.point", r.require(e, "point", we), 3, "position")))
        linkage = {}
        if "linkage" in cy:
            linkage = _linkage(r, w, cy["linkage"], ends[0], joints)
            linkage_joint = linkage.pop("joint")
            ends.append((linkage_joint.child, linkage.pop("crank_pin")))
        if ends[0][0] == ends[1][0]:
            raise r.error(w, f"both ends are on link '{ends[0][0]}': a cylinder must join two links")
        vals = _cylinder_values(r, w, cy, defaults, kind, keys)
        smin, smax = (float(v) for v in vals.pop("stroke"))
        if smin >= smax:
            raise r.error(f"{w} stroke", f"must be [shortest, longest] with shortest < longest, got {[smin, smax]}")
        if linkage:
            _check_linkage(r, w, linkage, smin, smax, linkage_joint)
        _check_order(r, w, {**vals, "stroke_min": smin, "stroke_max": smax}, kind)
        valve, seals = vals.pop("valve"), _seal_friction(r, w, cy, defaults)
        shared = {k: vals.pop(k) for k in SHARED_KEYS if k in vals}
        out.append(Cylinder(name, ends[0][0], ends[0][1], ends[1][0], ends[1][1], stroke_min=smin, stroke_max=smax,
                            kind=kind, params=vals, valve=valve, friction=seals, **linkage, **shared))
    unused = sorted(set(defaults) - used)
    if unused:
        kinds = sorted({c.kind for c in out})
        raise r.error(f"[hydraulics] {unused[0]}", f"is a parameter of no cylinder's kind ({', '.join(kinds)})")
    return tuple(out)


#: Joint angles (per joint range) at which a linkage is checked when a description is loaded.
LINKAGE_CHECK_POINTS = 2001


def _linkage(r: _Reader, w: str, table, base: tuple, joints) -> dict:
    """A cylinder's ``linkage`` table: the Cylinder fields ``linkage_joint``, ``linkage`` (a
    :class:`~hydrogen.symbolic.linkage.FourBar` in the joint's plane) and, for the caller, the
    joint (its child is the driven link) and the crank pin. ``base`` = (link, point) of the cylinder's ``from``."""
    wl = f"{w} linkage"
    if not isinstance(table, dict):
        raise r.error(wl, f"expected a table {{ joint, rocker_pivot, rocker, coupler, crank_pin, branch }}, "
                          f"got {_quote(table)}")
    r.known(table, _keys("[[cylinders]] linkage"), wl)
    jname = r.name(f"{wl}.joint", r.require(table, "joint", wl))
    joint = _revolute_joint(r, f"{wl}.joint", jname, joints, "a linkage cylinder")
    if base[0] != joint.parent:
        raise r.error(f"{w} from.link", f"is '{base[0]}', but a linkage cylinder's base must be on the link that "
                                        f"carries joint '{jname}''s pivot, '{joint.parent}'")
    pivot = r.vector(f"{wl}.rocker_pivot", r.require(table, "rocker_pivot", wl), 3, "position")
    crank_pin = r.vector(f"{wl}.crank_pin", r.require(table, "crank_pin", wl), 3, "position")
    lengths = {k: r.number(f"{wl}.{k}", r.require(table, k, wl), "pin_length") for k in ("rocker", "coupler")}
    branch = r.require(table, "branch", wl)
    if branch not in (1, -1) or isinstance(branch, bool) or not isinstance(branch, int):
        raise r.error(f"{wl}.branch", f"expected 1 or -1 (which of the linkage's two assemblies), got {_quote(branch)}")
    from .symbolic.linkage import from_description
    try:
        geometry, _ = from_description(joint, base[1], pivot, crank_pin, lengths["coupler"], lengths["rocker"],
                                       branch)
    except ValueError as exc:
        raise r.error(wl, str(exc)) from None
    return {"linkage_joint": jname, "linkage": geometry, "joint": joint, "crank_pin": crank_pin}


def _check_linkage(r: _Reader, w: str, linkage: dict, smin: float, smax: float, joint):
    """A linkage closes over its joint's whole range, its cylinder stays inside the stroke there and
    never passes a dead centre (dl/dq = 0), so it drives the joint over the range."""
    wl = f"{w} linkage"
    jname, g = linkage["linkage_joint"], linkage["linkage"]
    lo, hi = joint.limit.get("lower"), joint.limit.get("upper")
    if lo is None or hi is None:
        raise r.error(f"{wl}.joint", f"joint '{jname}' has no position limits (lower, upper): a linkage is "
                                     "checked over its joint's range, so give them (URDF <limit>, TOML limit)")
    if not lo < hi:
        raise r.error(f"{wl}.joint", f"joint '{jname}''s limits [{lo}, {hi}] rad leave it no range to move "
                                     "the linkage over: give lower < upper")
    q = np.linspace(lo, hi, LINKAGE_CHECK_POINTS)
    try:
        g.check_assembles(q)
    except ValueError as exc:
        raise r.error(wl, f"{exc} (joint '{jname}''s range is [{lo}, {hi}] rad)") from None
    l = g.lengths(q)
    tol = 1e-9 * max(1.0, smax)
    if l.min() < smin - tol or l.max() > smax + tol:
        k = int(np.argmax((l < smin - tol) | (l > smax + tol)))
        raise r.error(wl, f"over joint '{jname}''s range [{lo}, {hi}] rad the cylinder spans "
                          f"[{l.min():.6g}, {l.max():.6g}] m, outside its stroke [{smin}, {smax}] m (first at "
                          f"q = {q[k]:.6g} rad, l = {l[k]:.6g} m): the linkage cannot close over the stroke")
    dl = np.gradient(l, q)
    if not (np.all(dl > 0) or np.all(dl < 0)):
        k = int(np.argmin(np.abs(dl)))
        raise r.error(wl, f"the cylinder passes a dead centre (dl/dq = 0) at q = {q[k]:.6g} rad inside joint "
                          f"'{jname}''s range [{lo}, {hi}] rad: it cannot drive the joint through it")


def _revolute_joint(r: _Reader, where: str, jname: str, joints, what: str):
    """The revolute joint ``jname`` that ``what`` (e.g. "a rotary actuator") drives; else an error at
    ``where`` naming the joint's type (a fixed one, or one [tree] locked, has no coordinate to move)."""
    joint = next((j for j in joints if j.name == jname), None)
    if joint is not None and joint.type == "revolute":
        return joint
    revolute = ", ".join(j.name for j in joints if j.type == "revolute") or "none"
    if joint is None:
        raise r.error(where, f"'{jname}' is not a revolute joint of the tree (revolute joints: {revolute})")
    raise r.error(where, f"{what} needs a revolute joint; '{jname}' is {joint.type} (revolute joints: {revolute})")


def _joint_actuator(r: _Reader, w: str, cy: dict, defaults: dict, kind: str, keys, joints) -> Cylinder:
    """A [[cylinders]] entry of a joint actuator (rotary, motor): ``joint`` names a revolute joint of the
    tree; its angle range is its travel's key, or none for unlimited travel (−∞, ∞)."""
    r.known(cy, {"name", "joint", "kind", "valve", "friction", *keys}, f"{w} (kind {kind})")
    jname = r.name(f"{w} joint", r.require(cy, "joint", f"{w} (kind {kind})"))
    joint = _revolute_joint(r, f"{w} joint", jname, joints, f"a {kind} actuator")
    vals = _cylinder_values(r, w, cy, defaults, kind, keys)
    valve = vals.pop("valve")
    key, *ends = _travel(kind)
    amin, amax, limits = -np.inf, np.inf, {}
    if key is not None:
        amin, amax = (float(v) for v in vals.pop(key))
        if amin >= amax:
            raise r.error(f"{w} {key}", f"must be [lowest, highest] with lowest < highest, got {[amin, amax]}")
        limits = dict(zip(ends, (amin, amax)))
    _check_order(r, w, vals, kind)
    shared = {k: vals.pop(k) for k in SHARED_KEYS if k in vals}
    zero = np.zeros(3)
    return Cylinder(cy["name"], joint.parent, zero, joint.child, zero, stroke_min=amin, stroke_max=amax, kind=kind,
                    params={**vals, **limits}, joint=jname, valve=valve, friction=_seal_friction(r, w, cy, defaults),
                    **shared)


def _cylinder_values(r: _Reader, w: str, cy: dict, defaults: dict, kind: str, keys) -> dict:
    """The constants ``keys`` of cylinder ``w`` (kind ``kind``): its own, else [hydraulics]', else the
    kind's declared default; each checked against the range its kind declares for it."""
    from .actuators import actuator
    fallback = {p.name: p.default for p in actuator(kind).PARAMETERS if p.default is not None}
    valve, derived = _datasheet_valve(r, w, cy, defaults, kind)
    vals = {"valve": valve}
    for key in keys:
        if key in derived:
            vals[key] = derived[key]
            continue
        if key in cy:
            value, wk = cy[key], f"{w} {key}"
        elif key in defaults:
            value, wk = defaults[key], f"[hydraulics] {key}"
        elif key in fallback:
            value, wk = fallback[key], f"{w} {key} (default)"
        else:
            raise r.error(w, f"missing key '{key}' (give it here or in [hydraulics])")
        quantity = declared_range(kind, key)
        if key == _travel(kind)[0]:
            vals[key] = r.vector(wk, value, 2, quantity)
        else:
            vals[key] = r.number(wk, value, quantity)
    return vals


def _valve_ranges() -> dict:
    """A datasheet valve's keys with their ranges and units, as the valve block declares them
    (:data:`hydrogen.plant.valve.DATASHEET`)."""
    from .plant import valve
    return {p.name: Quantity(p.range.sign, p.range.low, p.range.high, p.unit, f"declared in {valve.__name__}")
            for p in valve.DATASHEET}


#: A datasheet valve's keys (the description's ``valve`` table): their ranges, from the valve block.
VALVE_RANGES = _valve_ranges()


def _datasheet_valve(r: _Reader, w: str, cy: dict, defaults: dict, kind: str):
    """Actuator ``w``'s datasheet valve (its own ``valve`` table, else [hydraulics]'): (the spool
    response for the plant, ``{name: value}`` of :data:`hydrogen.plant.valve.PARAMETERS`, and the
    kind's constants it sets: ``flow_gain``, ``underlap``), or (None, {}) without one. The flow gain
    follows from the kind's own orifice law: full opening with rated_drop across the edge passes
    rated_flow. An overlap > 0 is the plant's dead band (the controllers keep the ideal valve); < 0 the
    kind's underlap, which the controllers see as today."""
    from .actuators import actuator
    from .actuators.orifices import orifice_terms_np
    from .plant import valve
    from .plant.valve import Numeric as ValveLaw
    if "valve" in cy:
        table, wv, level = cy["valve"], f"{w} valve", cy
    elif "valve" in defaults:
        table, wv, level = defaults["valve"], "[hydraulics] valve", defaults
    else:
        return None, {}
    names = {p.name for p in actuator(kind).PARAMETERS}
    if "flow_gain" not in names:
        raise r.error(wv, f"actuator kind {kind} has no orifice valve (no flow_gain) for a datasheet valve to rate")
    for key in ("flow_gain", "underlap"):  # the valve sets them: one source each
        for given, where in ((cy, w), (defaults, "[hydraulics]")):
            if key in given and (given is level or given is cy):
                raise r.error(wv, f"and {where} {key} both given: the valve's rating sets {key}; give one, not both")
    if not isinstance(table, dict):
        raise r.error(wv, "expected a table { rated_flow, rated_drop, spool_travel, bandwidth_hz, damping, overlap }, "
                          f"got {_quote(table)}")
    r.known(table, _keys("[[cylinders]] valve"), wv)
    v = {k: r.number(f"{wv}.{k}", table[k], VALVE_RANGES[k]) for k in VALVE_RANGES if k in table}
    for k in valve.DATASHEET_REQUIRED:
        if k not in v:
            raise r.error(wv, f"missing key '{k}' ({VALVE_RANGES[k].unit})")
    overlap = v.get("overlap", 0.0)
    if overlap >= 1.0 or overlap <= -1.0:
        raise r.error(f"{wv}.overlap", f"must be in (-1, 1) (a fraction of spool_travel), got {overlap!r}")
    travel, omega = v["spool_travel"], 2 * np.pi * v["bandwidth_hz"]
    second = "damping" in v
    spool = {"lag": 0.0 if second else 1.0 / omega, "omega": omega if second else 0.0,
             "zeta": v.get("damping", 1.0),  # unused by the first order
             "overlap": max(overlap, 0.0) * travel, "full_opening": travel}
    underlap = max(-overlap, 0.0) * travel
    # full opening as the chambers see it (the valve block: saturation, dead band), through the kind's law
    row = [spool[k] for k in ("lag", "omega", "zeta", "overlap", "full_opening")]
    opening = float(ValveLaw.effective([travel], [travel], row)[0])
    root = np.sqrt(v["rated_drop"])
    per_gain = float(orifice_terms_np(opening, underlap, root, root))
    flow_gain = r.number(f"{wv}.rated_flow (the flow gain it gives)", v["rated_flow"] / per_gain,
                         declared_range(kind, "flow_gain"))
    derived = {"flow_gain": flow_gain, "underlap": r.number(f"{wv}.overlap", underlap, declared_range(kind, "underlap"))}
    return spool, {k: val for k, val in derived.items() if k in names}


def _seal_friction(r: _Reader, w: str, cy: dict, defaults: dict):
    """Actuator ``w``'s seal friction table (its own ``friction``, else [hydraulics]': every actuator's
    without its own, in each one's own unit), checked as a rig's is
    (:func:`hydrogen.plant.friction.table_problem`), or None without one. A stribeck_speed or
    pressure_coefficient that declares no term (no breakaway above coulomb, a 0) is kept: a number."""
    from .plant.friction import table_problem
    if "friction" in cy:
        table, wf = cy["friction"], f"{w} friction"
    elif "friction" in defaults:
        table, wf = defaults["friction"], "[hydraulics] friction"
    else:
        return None
    if not isinstance(table, dict) or not table:
        raise r.error(wf, "expected a table { coulomb, breakaway, stribeck_speed, viscous, pressure_coefficient, "
                          f"smooth_speed }} (the actuator's own unit), got {_quote(table)}")
    problem = table_problem(table)
    if problem is not None:
        key, what = problem
        raise r.error(wf if key is None else f"{wf}.{key}", what)
    return {k: float(v) for k, v in table.items()}


def order_broken(values: dict):
    """The first rule of CYLINDER_ORDER that a cylinder's constants ``values`` (by key) break, or None."""
    for a, b, strict, why in CYLINDER_ORDER:
        if a in values and b in values and not (values[a] < values[b] if strict else values[a] <= values[b]):
            return a, b, strict, why
    return None


def _check_order(r: _Reader, w: str, vals: dict, kind: str):
    """The cross-checks of a cylinder's constants (each in range already): CYLINDER_ORDER."""
    broken = order_broken(vals)
    if broken:
        a, b, strict, why = broken
        q = declared_range(kind, b)
        raise r.error(f"{w} {a}", f"must be {'<' if strict else '<='} {b} {vals[b]}{' ' + q.unit if q else ''} "
                                  f"({why})")


def _controllers(r, listed) -> tuple:
    """The description's ``controllers`` (None: all), checked, in the registry's order."""
    from .controllers import CONTROLLERS

    if listed is None:
        return tuple(CONTROLLERS)
    if not isinstance(listed, list) or not listed or not all(isinstance(c, str) for c in listed):
        raise r.error("controllers", f"expected a non-empty list of controller names, got {_quote(listed)}")
    unknown = [c for c in listed if c not in CONTROLLERS]
    if unknown:
        raise r.error("controllers", f"unknown controller {unknown[0]!r}; hydrogen's controllers: {', '.join(CONTROLLERS)}")
    if len(set(listed)) != len(listed):
        raise r.error("controllers", f"a controller is listed twice: {_quote(listed)}")
    return tuple(c for c in CONTROLLERS if c in listed)


def model_from_dict(data: dict, source: str = "<memory>", base_dir: Path | None = None) -> Model:
    """Validate parsed TOML data and build a :class:`Model`; errors name the source and the key."""
    r = _Reader(source)
    if not isinstance(data, dict):
        raise r.error("top level", f"a description is a table of keys (a dict), got {type(data).__name__} "
                                   f"{_quote(data)}")
    r.known(data, _keys("top level"), "top level")
    name = check_model_name(source, r.require(data, "name", "top level"))
    gravity = r.number("gravity", r.require(data, "gravity", "top level"), "gravity")
    form = data.get("rigid_body_form", _default("top level", "rigid_body_form"))
    if form not in RIGID_BODY_FORMS:
        raise r.error("rigid_body_form", f"expected one of {', '.join(map(repr, RIGID_BODY_FORMS))}, got {_quote(form)}")
    listed = _controllers(r, data.get("controllers"))
    urdf = None
    tree = r.table(data, "tree", required=False)
    if "urdf" in data:
        if "links" in data or "joints" in data:
            raise r.error("urdf", "give the tree either as a URDF file or as [[links]]/[[joints]], not both")
        rel = r.name("urdf", data["urdf"])
        urdf = (Path(base_dir) if base_dir else Path.cwd()) / rel
        try:
            text = read_description(urdf, "URDF")
        except ModelError as exc:
            raise r.error("urdf", str(exc)) from None
        # [tree] selects while the file is read: what it leaves out is not checked
        links, joints = _tree_from_urdf(urdf, text, lambda names, js: _kept_links(r, tree, names, js))
        kept = {lk.name for lk in links} | {j.parent for j in joints}
    else:
        links, joints = _tree_from_toml(r, data)
        kept = None
    links, joints = _select_tree(r, links, joints, tree, kept)
    root, joints, links = _order_tree(r, links, joints, "tree" if urdf is None else f"URDF {urdf}")
    floating = [j.name for j in joints if j.type == "floating"]
    if form == "staged" and floating:
        raise r.error("rigid_body_form", f"'staged' takes revolute, prismatic and fixed joints only; joint "
                                         f"'{floating[0]}' is floating (use 'closed' or 'auto')")
    _check_moving_mass(r, root, links, joints)
    link_names = {root} | {lk.name for lk in links}
    # coordinates
    coords = r.table(data, "coordinates")
    r.known(coords, _keys("[coordinates]"), "[coordinates]")
    default_names = []
    for j in joints:
        default_names += [f"{j.name}_{c}" for c in FLOATING_COORDINATES] if j.type == "floating" else \
            ([j.name] if j.dof else [])
    n = len(default_names)
    if n == 0:
        raise r.error("tree", "no joint moves: the robot needs at least one revolute, prismatic or floating joint")
    names = coords.get("names", default_names)
    if not isinstance(names, list) or len(names) != n or not all(isinstance(x, str) and x for x in names) \
            or len(set(names)) != n:
        raise r.error("[coordinates] names", f"expected {n} distinct names (one per coordinate), got {_quote(names)}")
    for c in names:
        r.label("[coordinates] names" if "names" in coords else f"coordinate {c!r} (from its joint's name)", c)
    # a TOML tree's root is named only as a parent: a misspelt one shows as a cylinder's unknown link
    root_note = "" if urdf is not None else \
        f"; the root '{root}' is the parent named by joint(s) {[j.name for j in joints if j.parent == root]}"
    # the actuators before the neutral pose: one on a fixed joint is the cause of a neutral pose
    # written for the joint moving, one number too many
    cylinders = _cylinders(r, data, link_names, root_note, joints)
    neutral = r.vector("[coordinates] neutral", r.require(coords, "neutral", "[coordinates]"), n)
    if len(cylinders) != n:
        raise r.error("[[cylinders]]", f"{len(cylinders)} cylinders for {n} coordinates: the method needs one "
                                       "cylinder per coordinate (a square JL)")
    # adaptation
    ad = r.table(data, "adaptation")
    r.known(ad, _keys("[adaptation]"), "[adaptation]")
    params = r.require(ad, "parameters", "[adaptation]")
    if not isinstance(params, list) or not params or not all(isinstance(p, str) for p in params) \
            or len(set(params)) != len(params):
        raise r.error("[adaptation] parameters", f"expected distinct names 'link.parameter', got {_quote(params)}")
    by_child = {j.child: j for j in joints}
    # the base and the links fixed to it: their inertia never enters the dynamics
    static = {root} | {lk.name for lk in links if (path := fixed_path(by_child, lk.name)) and path[-1].parent == root}
    for p in params:
        lk, _, key = p.partition(".")
        if lk not in {x.name for x in links} or key not in INERTIAL_PARAMETERS:
            raise r.error("[adaptation] parameters", f"'{p}' is not '<moving link>.<{'|'.join(INERTIAL_PARAMETERS)}>'")
        if lk in static:
            raise r.error("[adaptation] parameters", f"'{p}' is not '<moving link>.<{'|'.join(INERTIAL_PARAMETERS)}>': "
                                                     f"link '{lk}' is fixed to the base, its inertia never enters the "
                                                     "dynamics (nothing to adapt)")
    p_count = len(params)
    tmin = r.vector("[adaptation] theta_min", r.require(ad, "theta_min", "[adaptation]"), p_count)
    tmax = r.vector("[adaptation] theta_max", r.require(ad, "theta_max", "[adaptation]"), p_count)
    if np.any(tmin >= tmax):
        raise r.error("[adaptation] theta_min", "each lower bound must be < the upper bound theta_max")
    gb = {k: r.number(f"[adaptation] {k}", r.require(ad, k, "[adaptation]"), "positive")
          for k in ("gamma1_min", "gamma1_max", "gamma2_min", "gamma2_max")}
    for g in ("gamma1", "gamma2"):
        if gb[f"{g}_min"] >= gb[f"{g}_max"]:
            raise r.error(f"[adaptation] {g}_min", f"must be < {g}_max")
    sensors = r.table(data, "sensors", required=False)
    r.known(sensors, _keys("[sensors]"), "[sensors]")
    enc = sensors.get("joint_encoders", _default("[sensors]", "joint_encoders"))
    if not isinstance(enc, bool):
        raise r.error("[sensors] joint_encoders", f"expected true or false, got {_quote(enc)}")
    control = r.table(data, "control", required=False)
    r.known(control, _keys("[control]"), "[control]")
    scale = r.vector("[control] scale", control["scale"], n, "positive") if "scale" in control else None
    fcomp = control.get("friction_compensation", _default("[control]", "friction_compensation"))
    if not isinstance(fcomp, bool):
        raise r.error("[control] friction_compensation", f"expected true or false, got {_quote(fcomp)}")
    figs = r.table(data, "figures", required=False)
    r.known(figs, _keys("[figures]"), "[figures]")
    nonlinear = r.label("[figures] nonlinear", figs["nonlinear"]) if "nonlinear" in figs \
        else _default("[figures]", "nonlinear")
    gains = r.table(data, "gains", required=False)
    scen = r.table(data, "scenarios", required=False)
    for sname in scen:  # written into exported Makefiles, headers and FMUs
        from .names import check_label
        from .scenario_settings import VARIANT_SEPARATOR
        check_label(sname, f"{source}: [scenarios.{sname}]")
        if VARIANT_SEPARATOR in sname:  # '<scenario>.<variant>' would name a variant, never this table
            raise r.error(f'[scenarios."{sname}"]', f"a scenario name may not contain '{VARIANT_SEPARATOR}', which "
                          "joins a scenario to a variant (<scenario>.<variant>); rename it")
    if "rig" in scen:
        raise r.error("[scenarios.rig]", "'rig' is the name of the shared [rig] table: give the scenario another name")
    rig = r.table(data, "rig", required=False)
    variants = r.table(data, "variants", required=False)
    for vname in variants:  # joined to a scenario's name with '.', so no '.' of its own
        r.label(f"[variants.{vname}]", vname)
    _check_formerly(r, variants)
    supply = _supply(r, data, cylinders)
    model = Model(name=name, gravity=gravity, root=root, links=links, joints=joints, cylinders=cylinders,
                  coordinate_names=tuple(names), neutral_pose=neutral, theta_names=tuple(params),
                  theta_min=tmin, theta_max=tmax, joint_encoders=enc, scale=scale, friction_compensation=fcomp, figures_nonlinear=nonlinear, gains=gains,
                  scenarios={"rig": rig, **scen}, variants=variants, rigid_body_form=form, controllers=listed, source=source, urdf=urdf,
                  raw=data, supply=supply, **gb)
    _check_tables(r, model)
    _check_bounds(r, model)
    _check_neutral(r, model)
    return model


def _check_tables(r: _Reader, m: Model):
    """Every gain and scenario table and key known, at load time (they are read only when a run
    starts); the known ones come from their definitions: the controllers' gains, the Scenario fields."""
    from .controllers import COMMON_GAINS, CONTROLLERS, gain_names
    from .scenario_settings import RENAMED, table_keys
    names = {c: gain_names(c, m) for c in CONTROLLERS}
    _check_gains(r, m.gains, "[gains]", {**names, COMMON_GAINS: frozenset().union(*names.values())})
    r.known(m.scenarios["rig"], table_keys(rig=True), "[rig]", RENAMED)
    _check_setting_values(r, m.scenarios["rig"], "[rig]")
    for name, table in m.scenarios.items():
        if name == "rig":
            continue
        w = f"[scenarios.{name}]"
        if not isinstance(table, dict):
            raise r.error(w, f"expected a table, got {_quote(table)}")
        r.known(table, table_keys(), w, RENAMED)
        _check_setting_values(r, table, w)
        for flag in ("rig", "tuned"):
            if flag in table and not isinstance(table[flag], bool):
                raise r.error(f"{w} {flag}", f"expected true or false, got {_quote(table[flag])}")
        gains = table.get("gains", {})
        if not isinstance(gains, dict):
            raise r.error(f"{w} gains", f"expected a table of controllers, got {_quote(gains)}")
        _check_gains(r, gains, f"{w} gains", names)
    for name, table in m.variants.items():
        w = f"[variants.{name}]"
        if not isinstance(table, dict):
            raise r.error(w, f"expected a table, got {_quote(table)}")
        r.known(table, table_keys(rig=True) | _keys("[variants.<name>]"), w, RENAMED)
        _check_setting_values(r, table, w)
        gains = table.get("gains", {})
        if not isinstance(gains, dict):
            raise r.error(f"{w} gains", f"expected a table of controllers, got {_quote(gains)}")
        _check_gains(r, gains, f"{w} gains", names)


def _check_setting_values(r: _Reader, table: dict, where: str) -> None:
    """Each scenario setting of ``table`` that declares a check (hydrogen.setting: ``"number"``, a
    finite number; ``">=0"``, one not negative; ``">0"``, one above 0) holds it, at load time; the checks across settings
    (a valve's bandwidth against the sub-steps, a reference below Nyquist) wait for the scenario."""
    from .scenario_settings import settings
    from .setting import failed_check, words
    for f in settings():
        failed = failed_check(f, table[f.name]) if f.name in table else None
        if failed:
            what = words(f, failed)
            raise r.error(f"{where} {f.name}", f"must be {what} ({f.metadata['unit'] or 'no unit'}), "
                                               f"got {_quote(table[f.name])}")


def _check_formerly(r: _Reader, variants: dict):
    """Each variant's ``formerly`` (the names it was known by, which still run it): a list of names,
    none another variant's current or former name, so an old name runs exactly one variant."""
    owner = {}
    for vname, table in variants.items():
        old = table.get("formerly", []) if isinstance(table, dict) else []
        w = f"[variants.{vname}] formerly"
        if not isinstance(old, list) or not all(isinstance(o, str) for o in old):
            raise r.error(w, f"expected a list of the variant's former names, got {_quote(old)}")
        for o in old:
            r.label(w, o)
            if o in variants or o in owner:
                taken = f"[variants.{o}]" if o in variants else f"[variants.{owner[o]}] formerly"
                raise r.error(w, f"'{o}' is already {taken}: a former name runs one variant only")
            owner[o] = vname


def _check_gains(r: _Reader, gains: dict, where: str, names: dict):
    """``gains``: controller table -> {gain: value}; ``names``: table -> its known gains."""
    for table, values in gains.items():
        if table not in names:
            raise r.error(where, f"unknown controller table '{table}' (known: {', '.join(sorted(names))})")
        w = f"[gains.{table}]" if where == "[gains]" else f"{where}.{table}"
        if not isinstance(values, dict):
            raise r.error(w, f"expected a table of gains, got {_quote(values)}")
        r.known(values, names[table], w)


def _check_bounds(r: _Reader, m: Model):
    # Lemma 1 assumes a ≤ θ ≤ b: the true parameters must lie inside their projection bounds.
    theta = m.theta
    if np.any(theta < m.theta_min) or np.any(theta > m.theta_max):
        bad = [n for n, t, a, b in zip(m.theta_names, theta, m.theta_min, m.theta_max) if not a <= t <= b]
        raise r.error("[adaptation] theta_min/theta_max",
                      "must contain the true values (Lemma 1 assumes a <= theta <= b); outside: "
                      + ", ".join(f"{n} = {v:.6g}" for n, v in zip(m.theta_names, theta) if n in bad))
    for g, true in (("gamma1", m.gamma[0]), ("gamma2", m.gamma[1])):
        lo, hi = getattr(m, f"{g}_min"), getattr(m, f"{g}_max")
        if np.any(true < lo) or np.any(true > hi):
            raise r.error(f"[adaptation] {g}_min/{g}_max", f"must contain the true values {true.tolist()}")


def _check_neutral(r: _Reader, m: Model):
    """The neutral pose within the joints' limits, the actuators inside their travel's range there
    and JL well conditioned. The joints first: a pose past a joint's limit is the pose's fault, not
    the stroke's that it also leaves."""
    from .tree import cylinder_jacobian, cylinder_lengths
    q0 = m.neutral_pose
    lim, units = m.coordinate_limits(), m.coordinate_units
    for i, (q, lo, hi) in enumerate(zip(q0, lim["lower"], lim["upper"])):
        if not lo <= q <= hi:
            side = "lower" if q < lo else "upper"
            raise r.error("[coordinates] neutral", f"{m.coordinate_names[i]} = {q:.6g} {units[i]} is past joint "
                                                   f"'{m.coordinate_joint(i)}''s {side} limit (limits [{lo:g}, "
                                                   f"{hi:g}] {units[i]})")
    lengths = cylinder_lengths(m, q0)
    for c, l in zip(m.cylinders, lengths):
        if not c.stroke_min <= l <= c.stroke_max:
            t = c.travel  # its own travel: a cylinder's length (m), a vane's angle (rad)
            raise r.error(f"[[cylinders]] '{c.name}'", f"{t.value(l)} at the neutral pose is outside its "
                                                       f"{t.span(c.stroke_min, c.stroke_max)}")
    J = cylinder_jacobian(m, q0)
    cond = np.linalg.cond(J)
    if not np.isfinite(cond) or cond > 1e8:
        raise r.error("[[cylinders]]", f"JL = dl/dq is singular at the neutral pose (condition number {cond:.3g}): "
                                       "the cylinders cannot move every coordinate (check the pin points)")


def read_description(path: Path, what: str) -> bytes:
    """The bytes of description file ``path`` (``what``: "model", "URDF"): a regular file of at most
    MAX_DESCRIPTION_BYTES, else a ModelError naming the path and why (a FIFO would block the read, a
    device never end)."""
    def refuse(why):
        return ModelError(f"{path}: {why}")

    def check(st):
        if stat.S_ISDIR(st.st_mode):
            raise refuse(f"is a folder, not a {what} file")
        if not stat.S_ISREG(st.st_mode):
            raise refuse(f"is not a regular file ({_file_kind(st.st_mode)}), not a {what} file")
        if st.st_size > MAX_DESCRIPTION_BYTES:
            raise refuse(f"is {st.st_size} bytes, larger than the {MAX_DESCRIPTION_BYTES} bytes a {what} "
                         "file may have (hydrogen.model.MAX_DESCRIPTION_BYTES)")

    try:
        check(os.stat(path))  # before opening: opening a FIFO waits for a writer, a device may act
        # O_NONBLOCK: should it have become a FIFO since, the open returns at once and fstat refuses it
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise ModelError(f"{path}: {what} file not found") from None
    except OSError as exc:
        raise ModelError(f"{path}: cannot read {what} file: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as fh:
        check(os.fstat(fd))
        try:
            data = fh.read(MAX_DESCRIPTION_BYTES + 1)  # it may have grown since the check
        except OSError as exc:
            raise ModelError(f"{path}: cannot read {what} file: {exc.strerror or exc}") from None
    if len(data) > MAX_DESCRIPTION_BYTES:
        raise refuse(f"is larger than the {MAX_DESCRIPTION_BYTES} bytes a {what} file may have "
                     "(hydrogen.model.MAX_DESCRIPTION_BYTES)")
    return data


def _file_kind(mode) -> str:
    for test, kind in ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return "not a plain file"


def is_shipped(model) -> bool:
    """Whether ``model`` was loaded from one of the shipped descriptions (:func:`models`), not a user's
    file of the same name: its ``source`` is that description's path."""
    try:
        return model.name in models() and Path(model.source).resolve() == model_path(model.name).resolve()
    except (OSError, TypeError, ValueError):
        return False


def load_model(path: str | Path | None = None) -> Model:
    """Load a model: a built-in name (``hydrogen.models()``), a TOML file, or the default when None.

    Raises
    ------
    ModelError
        The file (or the URDF it names) is missing, not a regular file or larger than
        MAX_DESCRIPTION_BYTES, is not valid TOML (URDF), or a key, table or element is unknown,
        missing, of the wrong type, or out of range (QUANTITIES); the message names the file and
        the key, link, joint or cylinder.
    """
    if isinstance(path, Model):
        return path
    if path is not None and not isinstance(path, (str, Path)):
        raise ModelError(f"model must be a built-in name ({', '.join(models())}), a path or a Model, "
                         f"got {type(path).__name__} {_quote(path)}")
    path = default_model_path() if path is None else model_path(path)
    if not os.path.lexists(path):
        raise ModelError(f"{path}: model file not found (built-in models: {', '.join(models())})")
    try:
        text = read_description(path, "model").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ModelError(f"{path}: cannot read model file: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        if Path(path).suffix.lower() in (".urdf", ".xml") or text.lstrip().startswith(("<?xml", "<robot")):
            raise ModelError(f"{path}: a URDF, not a robot description: write a description TOML that loads it "
                             f"(urdf = \"{Path(path).name}\") and adds its actuators and hydraulics, and pass "
                             "that (docs/guide/robot.md)") from None
        raise ModelError(f"{path}: malformed TOML: {exc}") from None
    return model_from_dict(data, source=str(path), base_dir=path.parent)
