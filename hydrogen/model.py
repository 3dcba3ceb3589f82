"""Model data: Table I of the paper plus the platform geometry, loaded from TOML.

A model is plain data. Everything under ``[geometry]`` and ``[hydraulics]`` is
baked into the generated C (changing it regenerates code); the rigid-body
parameters θ = [M_p, I_x, I_y, I_z] and the hydraulic parameters
γ = [β, βc] are runtime inputs of every generated function, so the adaptive
controllers can feed their estimates and a user can change masses without
regenerating. Units are SI; frames: base frame z up, platform frame at the
platform's centre of mass.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

import numpy as np

from .errors import ModelError

__all__ = ["Model", "load_model", "default_model_path"]

DEFAULT_MODEL = "ubc_stewart.toml"


def default_model_path() -> Path:
    """Path of the default model file shipped inside the package."""
    return Path(str(resources.files("hydrogen") / "data" / DEFAULT_MODEL))


@dataclass(frozen=True)
class Model:
    """A hydraulic Stewart platform. All values SI; see the module docstring."""

    name: str
    mass: float
    inertia: tuple
    gravity: float
    base_joints: np.ndarray      # (6, 3) base frame, m
    platform_joints: np.ndarray  # (6, 3) platform frame, m
    neutral_pose: np.ndarray     # (6,) [x y z ψ θ φ]
    leg_min: float
    leg_max: float
    piston_area: float
    rod_area: float
    chamber_length: float
    supply_pressure: float
    underlap: float
    flow_gain: float
    bulk_modulus: float
    orifice_linear_below: float
    theta_min: np.ndarray
    theta_max: np.ndarray
    gamma1_min: float
    gamma1_max: float
    gamma2_min: float
    gamma2_max: float
    source: str = "<memory>"
    raw: dict = field(default=None, repr=False, compare=False)

    @property
    def theta(self) -> np.ndarray:
        """True rigid-body parameters [M_p kg, I_x, I_y, I_z kg m²]."""
        return np.array([self.mass, *self.inertia], dtype=float)

    @property
    def gamma(self) -> np.ndarray:
        """True hydraulic parameters [γ1, γ2] = [β Pa, βc] (the same for every leg)."""
        return np.array([self.bulk_modulus, self.bulk_modulus * self.flow_gain])

    def baked(self) -> dict:
        """The part of the model compiled into C (geometry and actuator constants)."""
        return {
            "name": self.name,
            "gravity": self.gravity,
            "base_joints": np.asarray(self.base_joints).tolist(),
            "platform_joints": np.asarray(self.platform_joints).tolist(),
            "piston_area": self.piston_area,
            "rod_area": self.rod_area,
            "chamber_length": self.chamber_length,
            "supply_pressure": self.supply_pressure,
            "underlap": self.underlap,
            "orifice_linear_below": self.orifice_linear_below,
        }

    def baked_hash(self) -> str:
        """SHA-256 of the baked part, canonical JSON (floats by repr), so equal models hash equal."""
        text = json.dumps(self.baked(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


# key -> (section, kind, constraint); kinds: 'float', 'vec3', 'vec4', 'vec6', 'mat63', 'str'
_SCHEMA = {
    ("", "name"): ("str", None),
    ("rigid_body", "mass"): ("float", "positive"),
    ("rigid_body", "inertia"): ("vec3", "positive"),
    ("rigid_body", "gravity"): ("float", "nonnegative"),
    ("geometry", "base_joints"): ("mat63", None),
    ("geometry", "platform_joints"): ("mat63", None),
    ("geometry", "neutral_pose"): ("vec6", None),
    ("geometry", "leg_min"): ("float", "positive"),
    ("geometry", "leg_max"): ("float", "positive"),
    ("hydraulics", "piston_area"): ("float", "positive"),
    ("hydraulics", "rod_area"): ("float", "positive"),
    ("hydraulics", "chamber_length"): ("float", "nonnegative"),
    ("hydraulics", "supply_pressure"): ("float", "positive"),
    ("hydraulics", "underlap"): ("float", "nonnegative"),
    ("hydraulics", "flow_gain"): ("float", "positive"),
    ("hydraulics", "bulk_modulus"): ("float", "positive"),
    ("hydraulics", "orifice_linear_below"): ("float", "positive"),
    ("adaptation", "theta_min"): ("vec4", "positive"),
    ("adaptation", "theta_max"): ("vec4", "positive"),
    ("adaptation", "gamma1_min"): ("float", "positive"),
    ("adaptation", "gamma1_max"): ("float", "positive"),
    ("adaptation", "gamma2_min"): ("float", "positive"),
    ("adaptation", "gamma2_max"): ("float", "positive"),
}

_SHAPES = {"vec3": (3,), "vec4": (4,), "vec6": (6,), "mat63": (6, 3)}


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_value(where: str, kind: str, constraint, value):
    if kind == "str":
        if not isinstance(value, str) or not value.isidentifier():
            raise ModelError(f"{where}: expected a name (letters, digits, underscores), got {value!r}")
        from .names import check_identifier; return check_identifier(value, where)  # noqa: E702
    if kind == "float":
        if not _is_number(value):
            raise ModelError(f"{where}: expected a number, got {type(value).__name__} {value!r}")
        arr = np.array(float(value))
    else:
        shape = _SHAPES[kind]
        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise ModelError(f"{where}: expected numbers of shape {shape}, got {value!r}") from None
        flat = value if len(shape) == 1 else [x for row in value for x in (row if isinstance(row, list) else [row])]
        if arr.shape != shape or not all(_is_number(x) for x in flat):
            raise ModelError(f"{where}: expected numbers of shape {shape}, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{where}: must be finite, got {value!r}")
    if constraint == "positive" and not np.all(arr > 0):
        raise ModelError(f"{where}: must be > 0, got {value!r}")
    if constraint == "nonnegative" and not np.all(arr >= 0):
        raise ModelError(f"{where}: must be >= 0, got {value!r}")
    return float(arr) if kind == "float" else arr


def model_from_dict(data: dict, source: str = "<memory>") -> Model:
    """Validate parsed TOML data and build a :class:`Model`; errors name source and key."""
    values = {}
    for (section, key), (kind, constraint) in _SCHEMA.items():
        table = data if not section else data.get(section)
        dotted = f"{section}.{key}" if section else key
        where = f"{source}: [{section}] {key}" if section else f"{source}: {key}"
        if section and not isinstance(table, dict):
            raise ModelError(f"{source}: missing table [{section}] (needed for key '{dotted}')")
        if key not in table:
            raise ModelError(f"{where}: missing key '{dotted}'")
        values[key] = _check_value(where, kind, constraint, table[key])
    known = {s for s, _ in _SCHEMA if s} | {k for s, k in _SCHEMA if not s}
    for key in data:
        if key not in known:
            raise ModelError(f"{source}: unknown key or table '{key}'")
    for section in {s for s, _ in _SCHEMA if s}:
        for key in data[section]:
            if (section, key) not in _SCHEMA:
                raise ModelError(f"{source}: [{section}] unknown key '{key}'")

    def bad(key, msg):
        return ModelError(f"{source}: {key}: {msg}")

    if values["leg_min"] >= values["leg_max"]:
        raise bad("[geometry] leg_min", f"must be < leg_max ({values['leg_min']} >= {values['leg_max']})")
    if values["chamber_length"] >= values["leg_min"]:
        raise bad("[hydraulics] chamber_length",
                  "must be < [geometry] leg_min so the control chamber keeps a positive volume")
    if values["rod_area"] >= values["piston_area"]:
        raise bad("[hydraulics] rod_area", "must be < piston_area")
    if np.any(values["theta_min"] >= values["theta_max"]):
        raise bad("[adaptation] theta_min", "each lower bound must be < the upper bound theta_max")
    for g in ("gamma1", "gamma2"):
        if values[f"{g}_min"] >= values[f"{g}_max"]:
            raise bad(f"[adaptation] {g}_min", f"must be < {g}_max")
    # Lemma 1 assumes a ≤ θ ≤ b: the true parameters must lie inside their projection bounds.
    theta = np.array([values["mass"], *values["inertia"]])
    if np.any(theta < values["theta_min"]) or np.any(theta > values["theta_max"]):
        raise bad("[adaptation] theta_min/theta_max",
                  f"must contain the true [mass, inertia] {theta.tolist()} (Lemma 1 assumes a <= theta <= b)")
    for g, true in (("gamma1", values["bulk_modulus"]), ("gamma2", values["bulk_modulus"] * values["flow_gain"])):
        if not values[f"{g}_min"] <= true <= values[f"{g}_max"]:
            raise bad(f"[adaptation] {g}_min/{g}_max", f"must contain the true value {true:.6g}")
    inertia = tuple(float(x) for x in values.pop("inertia"))
    return Model(inertia=inertia, source=source, raw=data, **values)


def load_model(path: str | Path | None = None) -> Model:
    """Load a model from a TOML file (the packaged default when ``path`` is None).

    Raises
    ------
    ModelError
        The file is missing, is not valid TOML, or a key is missing, of the wrong
        type, or out of range; the message names the file and the key.
    """
    path = default_model_path() if path is None else Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ModelError(f"{path}: model file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: cannot read model file: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError(f"{path}: malformed TOML: {exc}") from None
    return model_from_dict(data, source=str(path))
