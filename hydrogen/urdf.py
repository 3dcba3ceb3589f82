"""A URDF reader for what hydrogen needs: links' inertials and joints' type, parent, child, origin,
axis, limit and mimic. Meshes, visuals, collisions, materials and transmissions are not read.

Read with lxml (strict: no recovery from malformed XML; a file with a <!DOCTYPE> or <!ENTITY>
declaration is refused, no DTD is loaded, no network: a description file is data). :func:`load_robot` returns the same shape of data yourdfpy's
``URDF.load(...).robot`` gives (origins as 4×4 homogeneous transforms in the parent frame, SI;
inertia tensors as 3×3 matrices about the link's centre of mass, in the inertial frame), so the
model reader can use either. A value that is missing where URDF requires it, or is not a number,
raises :class:`~hydrogen.errors.ModelError` naming the file, the element and the attribute.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ModelError

__all__ = ["load_robot", "Robot", "Link", "Inertial", "Joint", "Limit", "Mimic", "origin_matrix"]


@dataclass
class Inertial:
    mass: float | None
    origin: np.ndarray | None  # 4×4, the inertial frame in the link frame
    inertia: np.ndarray        # 3×3 about the centre of mass, in the inertial frame (kg m²)


@dataclass
class Link:
    name: str
    inertial: Inertial | None = None


@dataclass
class Limit:
    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None


@dataclass
class Mimic:
    joint: str
    multiplier: float | None = None
    offset: float | None = None


@dataclass
class Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray | None = None  # 4×4, the joint frame in the parent link's frame
    axis: np.ndarray | None = None    # in the joint frame (None: URDF's default, x)
    limit: Limit | None = None
    mimic: Mimic | None = None


@dataclass
class Robot:
    name: str
    links: list = field(default_factory=list)
    joints: list = field(default_factory=list)


def origin_matrix(xyz, rpy) -> np.ndarray:
    """4×4 transform of an <origin>: translation xyz (m), rotation Rz(yaw) Ry(pitch) Rx(roll) (rad)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    T = np.eye(4)
    T[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    T[:3, 3] = xyz
    return T + 0.0  # -sin(0) is -0.0: a signed zero would change the model's hash, not its numbers


class _Parser:
    def __init__(self, path: Path):
        self.path = path

    def error(self, where: str, what: str) -> ModelError:
        return ModelError(f"{self.path}: {where}: {what}")

    def number(self, el, attr: str, where: str, default=None):
        text = el.get(attr)
        if text is None:
            if default is None:
                raise self.error(where, f"needs the attribute {attr}")
            return default
        try:
            return float(text)
        except ValueError:
            raise self.error(where, f"{attr}={text!r} is not a number") from None

    def vector(self, el, attr: str, where: str, default):
        text = el.get(attr) if el is not None else None
        if text is None:
            return np.array(default, float)
        parts = text.split()
        try:
            values = [float(v) for v in parts]
        except ValueError:
            raise self.error(where, f"{attr}={text!r} is not three numbers") from None
        if len(values) != 3:
            raise self.error(where, f"{attr}={text!r} has {len(values)} numbers, expected 3")
        return np.array(values, float)

    def origin(self, el, where: str):
        o = el.find("origin")
        if o is None:
            return None
        return origin_matrix(self.vector(o, "xyz", f"{where} <origin>", (0, 0, 0)),
                             self.vector(o, "rpy", f"{where} <origin>", (0, 0, 0)))

    def name(self, el, where: str) -> str:
        n = el.get("name")
        if not n:
            raise self.error(where, "needs a name")
        return n


def parse_xml(path, data: bytes | None = None):
    """The root element of the URDF file at ``path`` (its bytes ``data`` when already read), parsed
    strictly, with no document type and no entity expansion."""
    from lxml import etree

    path = Path(path)
    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    if data is None:
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise ModelError(f"{path}: cannot read URDF file ({exc.strerror or exc})") from None
    # A description file is data: no document type, so no entity of any kind (libxml2 expands
    # internal entities in attributes even with resolve_entities=False).
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise ModelError(f"{path}: URDF has a <!DOCTYPE> or <!ENTITY> declaration; hydrogen reads URDF as plain "
                         "data and expands no entities: remove the declaration")
    try:
        return etree.fromstring(data, parser, base_url=str(path))
    except etree.XMLSyntaxError as exc:
        raise ModelError(f"{path}: URDF does not parse: {exc}") from None


def load_robot(path, data: bytes | None = None) -> Robot:
    """The links and joints of the URDF file at ``path`` (its bytes ``data`` when already read; see
    the module's docstring)."""
    path = Path(path)
    root = parse_xml(path, data)
    p = _Parser(path)
    if root.tag != "robot":
        raise p.error(f"<{root.tag}>", "the root element of a URDF file must be <robot>")
    robot = Robot(root.get("name") or "")
    for i, el in enumerate(root.findall("link")):
        w = f"<link> {i + 1}" if not el.get("name") else f"link '{el.get('name')}'"
        name = p.name(el, w)
        inertial = None
        ie = el.find("inertial")
        if ie is not None:
            m = ie.find("mass")
            mass = None if m is None else p.number(m, "value", f"{w} <mass>")
            I = np.zeros((3, 3))
            ii = ie.find("inertia")
            if ii is not None:
                v = {k: p.number(ii, k, f"{w} <inertia>") for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
                I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                              [v["ixz"], v["iyz"], v["izz"]]])
            inertial = Inertial(mass, p.origin(ie, w + " <inertial>"), I)
        robot.links.append(Link(name, inertial))
    for i, el in enumerate(root.findall("joint")):
        w = f"<joint> {i + 1}" if not el.get("name") else f"joint '{el.get('name')}'"
        name = p.name(el, w)
        jtype = el.get("type")
        if not jtype:
            raise p.error(w, "needs a type")
        links = {}
        for tag in ("parent", "child"):
            e = el.find(tag)
            if e is None or not e.get("link"):
                raise p.error(w, f"needs <{tag} link=\"...\"/>")
            links[tag] = e.get("link")
        ax = el.find("axis")
        axis = None if ax is None else p.vector(ax, "xyz", f"{w} <axis>", (1, 0, 0))
        limit = None
        le = el.find("limit")
        if le is not None:
            limit = Limit(*(p.number(le, k, f"{w} <limit>", default=float("nan")) for k in
                            ("lower", "upper", "effort", "velocity")))
            limit = Limit(*(None if v != v else v for v in
                            (limit.lower, limit.upper, limit.effort, limit.velocity)))
        mimic = None
        me = el.find("mimic")
        if me is not None:
            if not me.get("joint"):
                raise p.error(f"{w} <mimic>", "needs the attribute joint")
            mimic = Mimic(me.get("joint"), p.number(me, "multiplier", f"{w} <mimic>", default=1.0),
                          p.number(me, "offset", f"{w} <mimic>", default=0.0))
        robot.joints.append(Joint(name, jtype, links["parent"], links["child"], p.origin(el, w), axis, limit, mimic))
    return robot
