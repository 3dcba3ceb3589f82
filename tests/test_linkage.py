"""The four-bar linkage's cylinder length l(q) against a geometric construction, dl/dq against
finite differences, and its checks; then a linkage in a description: the compiled length and JL
against a construction in the base frame and finite differences, and bad linkages refused at load."""
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq

import hydrogen

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib
from hydrogen.model import model_from_dict
from hydrogen.symbolic.linkage import FourBar
from hydrogen.tree import cylinder_lengths, link_poses

GEOMETRY = dict(crank=0.35, crank_offset=0.4, coupler=0.55, rocker=0.5, rocker_pivot=(-0.45, 0.1),
                cylinder_base=(-2.0, 0.4))
ANGLES = np.linspace(-1.2, 1.2, 25)


def _constructed_length(g: FourBar, q):
    """l(q) built another way: the rocker angle ψ with |O4 + r4 (cos ψ, sin ψ) − B| = r3 found by
    root bracketing, the assembly picked by the side of B→O4 the pin C lies on."""
    B = g.crank * np.array([np.cos(q + g.crank_offset), np.sin(q + g.crank_offset)])
    O4, P = np.asarray(g.rocker_pivot), np.asarray(g.cylinder_base)
    pin = lambda psi: O4 + g.rocker * np.array([np.cos(psi), np.sin(psi)])  # noqa: E731
    gap = lambda psi: np.linalg.norm(pin(psi) - B) - g.coupler  # noqa: E731
    grid = np.linspace(-np.pi, np.pi, 721)
    vals = [gap(s) for s in grid]
    roots = [brentq(gap, a, b, xtol=1e-15) for a, b, va, vb in zip(grid, grid[1:], vals, vals[1:]) if va * vb < 0]
    assert len(roots) == 2
    d = O4 - B
    for psi in roots:
        C = pin(psi)
        side = np.sign(d[0] * (C - B)[1] - d[1] * (C - B)[0])
        if side == g.branch:
            return np.linalg.norm(C - P)
    raise AssertionError("no assembly on the branch")


@pytest.mark.parametrize("branch", [1, -1])
def test_length_matches_a_geometric_construction(branch):
    g = FourBar(**GEOMETRY, branch=branch)
    q = sp.Symbol("q", real=True)
    l, _, _ = g.symbolic(q)
    fn = sp.lambdify(q, l, "numpy")
    for qk in ANGLES:
        np.testing.assert_allclose(fn(qk), _constructed_length(g, qk), rtol=1e-11)


@pytest.mark.parametrize("branch", [1, -1])
def test_jacobian_matches_finite_differences(branch):
    g = FourBar(**GEOMETRY, branch=branch)
    q = sp.Symbol("q", real=True)
    l, dl, C = g.symbolic(q)
    fl, fdl = sp.lambdify(q, l, "numpy"), sp.lambdify(q, dl, "numpy")
    h = 1e-6
    fd = (fl(ANGLES + h) - fl(ANGLES - h)) / (2 * h)
    np.testing.assert_allclose(fdl(ANGLES), fd, rtol=1e-7, atol=1e-9)
    assert np.ptp(fdl(ANGLES)) > 1e-2  # the lever arm varies with q: a real linkage, not a constant
    # the pin C keeps the coupler and rocker lengths
    fC = sp.lambdify(q, C, "numpy")
    for qk in ANGLES[::6]:
        Ck = np.asarray(fC(qk), float).ravel()
        B = g.crank * np.array([np.cos(qk + g.crank_offset), np.sin(qk + g.crank_offset)])
        np.testing.assert_allclose(np.linalg.norm(Ck - B), g.coupler, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(Ck - np.asarray(g.rocker_pivot)), g.rocker, rtol=1e-12)


def test_a_linkage_that_cannot_assemble_names_the_angle():
    g = FourBar(**{**GEOMETRY, "rocker_pivot": (-1.2, 0.0)})
    with pytest.raises(ValueError, match=r"does not assemble at q = .* rad: \|B O4\| = .* is outside"):
        g.check_assembles(np.linspace(-3, 3, 61))
    FourBar(**GEOMETRY).check_assembles(np.linspace(-3, 3, 61))  # the example closes everywhere


@pytest.mark.parametrize("field,value,message", [
    ("coupler", -0.1, "coupler must be a positive length"),
    ("branch", 0, "branch must be"),
    ("rocker_pivot", (1.0,), "rocker_pivot must be a point"),
])
def test_bad_geometry_is_named(field, value, message):
    with pytest.raises(ValueError, match=message):
        FourBar(**{**GEOMETRY, field: value})


# --- through a description ------------------------------------------------------------------------

ARM = Path(__file__).parent / "data" / "four_way_arm.toml"
# the four-way arm's elbow cylinder through a four-bar linkage on the elbow (points in the upper
# link's frame, the crank pin in the forearm's, m)
ELBOW_LINKAGE = {"joint": "elbow", "rocker_pivot": [0.937, 0.0, -0.047], "rocker": 0.189, "coupler": 0.115,
                 "crank_pin": [0.074, 0.0, 0.072], "branch": -1}
ELBOW_RANGE = {"lower": -1.8, "upper": -0.2}


def _linkage_arm(**changes):
    """The four-way arm's description with its elbow cylinder on ELBOW_LINKAGE; ``changes`` update
    the linkage table (None removes a key)."""
    data = tomllib.loads(ARM.read_text())
    data["joints"][1]["limit"] = dict(ELBOW_RANGE)
    cyl = data["cylinders"][1]
    del cyl["to"]
    cyl["from"] = {"link": "upper", "point": [0.695, 0.0, 0.146]}
    cyl["stroke"] = [0.30, 0.45]
    link = {**ELBOW_LINKAGE, **changes}
    cyl["linkage"] = {k: v for k, v in link.items() if v is not None}
    return data


def _world_length(model, q):
    """The elbow cylinder's length built in the base frame from the link poses: the rocker's pin C
    on the circle about the rocker pivot at the rocker's length from the crank pin, found by root
    bracketing on the rocker angle, on the side of crank pin → pivot the branch names."""
    poses = link_poses(model, q)
    (Ru, pu), (Rf, pf) = poses["upper"], poses["fore"]
    to_plane = lambda x: np.array([x[0], x[2]])  # noqa: E731  the x-z plane; the axes are -y
    B = to_plane(pf + Rf @ np.array(ELBOW_LINKAGE["crank_pin"]))
    O4 = to_plane(pu + Ru @ np.array(ELBOW_LINKAGE["rocker_pivot"]))
    P = to_plane(pu + Ru @ np.array([0.695, 0.0, 0.146]))
    r3, r4 = ELBOW_LINKAGE["coupler"], ELBOW_LINKAGE["rocker"]
    pin = lambda psi: O4 + r4 * np.array([np.cos(psi), np.sin(psi)])  # noqa: E731
    gap = lambda psi: np.linalg.norm(pin(psi) - B) - r3  # noqa: E731
    grid = np.linspace(-np.pi, np.pi, 721)
    vals = [gap(s) for s in grid]
    roots = [brentq(gap, a, b, xtol=1e-15) for a, b, va, vb in zip(grid, grid[1:], vals, vals[1:]) if va * vb < 0]
    # x right and z up is the plane seen with the joint axis -y towards the viewer (x × z = -y)
    d = O4 - B
    side = [np.sign(d[0] * (pin(s) - B)[1] - d[1] * (pin(s) - B)[0]) for s in roots]
    return np.linalg.norm(pin(roots[side.index(ELBOW_LINKAGE["branch"])]) - P)


@pytest.fixture(scope="module")
def linkage_arm():
    return model_from_dict(_linkage_arm(), "linkage_arm.toml")


def test_a_described_linkage_gives_the_length_and_JL(linkage_arm, cache):
    m = linkage_arm
    c = m.cylinders[1]
    assert c.linkage_joint == "elbow" and c.linkage is not None
    dyn = hydrogen.build(m, cache=cache)
    rng = np.random.default_rng(3)
    qs = np.column_stack([rng.uniform(-0.2, 0.8, 12), rng.uniform(-1.8, -0.2, 12)])
    h = 1e-6
    for q in qs:
        l = dyn.leg_lengths(q)
        np.testing.assert_allclose(l[1], _world_length(m, q), rtol=1e-10)
        np.testing.assert_allclose(l, cylinder_lengths(m, q), rtol=1e-12)
        J = dyn.leg_jacobian(q)
        fd = np.column_stack([(dyn.leg_lengths(q + h * e) - dyn.leg_lengths(q - h * e)) / (2 * h) for e in np.eye(2)])
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-9)
        assert J[1, 0] == 0.0 and abs(J[1, 1]) > 0.05  # the linkage's joint alone moves it
    levers = [dyn.leg_jacobian(q)[1, 1] for q in qs]
    assert np.ptp(levers) > 0.01  # the lever varies along the range: the linkage, not a pin


def test_a_linkage_key_changes_the_model_hash(linkage_arm):
    other = model_from_dict(_linkage_arm(rocker=0.19), "linkage_arm.toml")
    assert other.baked_hash() != linkage_arm.baked_hash()


@pytest.mark.parametrize("changes,where,message", [
    # the coupler too short to reach the rocker over the range
    (dict(coupler=0.03), "linkage", r"does not assemble at q = .* rad.*joint 'elbow''s range"),
    # assembles, but the cylinder's length leaves the stroke over the joint range
    (dict(rocker=0.17), "linkage", r"spans \[.*\] m, outside its stroke \[0.3, 0.45\] m.*cannot close over the stroke"),
    (dict(joint="shoulder"), "from.link", r"carries joint 'shoulder''s pivot, 'base'"),
    (dict(joint="wrist"), "linkage.joint", r"'wrist' is not a revolute joint"),
    (dict(branch=0), "linkage.branch", r"expected 1 or -1"),
    (dict(coupler=-0.1), "linkage.coupler", r"must be > 0"),
    (dict(rocker=None), "linkage", r"missing key 'rocker'"),
    (dict(crank_pin=[0.074, 0.02, 0.072]), "linkage", r"one plane normal to the axis"),
    (dict(crank_pin=[0.0, 0.0, 0.0]), "linkage", r"on joint 'elbow''s axis"),
    (dict(pin=1), "linkage", r"unknown key 'pin'"),
])
def test_a_bad_linkage_is_one_clear_error_at_load(changes, where, message):
    with pytest.raises(hydrogen.ModelError, match=rf"linkage_arm.toml: \[\[cylinders\]\] 'elbow_cylinder' {where}: .*{message}"):
        model_from_dict(_linkage_arm(**changes), "linkage_arm.toml")


def test_a_linkage_needs_its_joint_range_and_no_to():
    data = _linkage_arm()
    del data["joints"][1]["limit"]
    with pytest.raises(hydrogen.ModelError, match=r"linkage.joint: joint 'elbow' has no position limits"):
        model_from_dict(data, "linkage_arm.toml")
    data = _linkage_arm()
    data["cylinders"][1]["to"] = {"link": "fore", "point": [0.1, 0.0, 0.1]}
    with pytest.raises(hydrogen.ModelError, match=r"either 'to' .* or 'linkage'"):
        model_from_dict(data, "linkage_arm.toml")


def test_the_linkage_plane_follows_a_turned_and_offset_joint():
    """from_description on a joint with an origin offset, roll-pitch-yaw and a tilted axis: l(q)
    equals the length built in 3-D (the child's crank pin turned about the axis, the rocker's pin C
    found by bracketing on the circle about the pivot in the plane normal to the axis)."""
    from hydrogen.model import Joint
    from hydrogen.symbolic.linkage import from_description
    from hydrogen.tree import axis_rotation, rpy_matrix

    axis = np.array([0.3, -0.8, 0.52])
    axis /= np.linalg.norm(axis)
    joint = Joint("j", "revolute", "a", "b", np.array([0.4, -0.2, 1.1]), np.array([0.3, -0.5, 0.9]), axis)
    R_o, o = rpy_matrix(joint.origin_rpy), joint.origin_xyz
    e1 = np.cross(axis, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    w = 0.07  # every point 7 cm along the axis: one plane
    in_joint = lambda x, y: w * axis + x * e1 + y * e2  # noqa: E731  joint-frame point of plane coordinates
    to_parent = lambda x: o + R_o @ x  # noqa: E731
    pivot, base = to_parent(in_joint(-0.45, 0.1)), to_parent(in_joint(-2.0, 0.4))
    crank = in_joint(0.35 * np.cos(0.4), 0.35 * np.sin(0.4))  # child frame = joint frame at q = 0
    g, offsets = from_description(joint, base, pivot, crank, coupler=0.55, rocker=0.5, branch=1)
    np.testing.assert_allclose(list(offsets.values()), w, atol=1e-12)
    for q in np.linspace(-1.0, 1.0, 9):
        B = to_parent(axis_rotation(axis, q) @ crank)
        n = R_o @ axis  # the axis in the parent frame; C lies in the plane through the pivot normal to it
        u1 = R_o @ e1
        u2 = np.cross(n, u1)
        pin = lambda psi: pivot + 0.5 * (np.cos(psi) * u1 + np.sin(psi) * u2)  # noqa: E731
        gap = lambda psi: np.linalg.norm(pin(psi) - B) - 0.55  # noqa: E731
        grid = np.linspace(-np.pi, np.pi, 721)
        vals = [gap(s) for s in grid]
        roots = [brentq(gap, a, b, xtol=1e-15) for a, b, va, vb in zip(grid, grid[1:], vals, vals[1:]) if va * vb < 0]
        # branch +1: C to the left of B -> pivot seen with the axis towards the viewer
        C = next(pin(s) for s in roots if np.cross(pivot - B, pin(s) - B) @ n > 0)
        np.testing.assert_allclose(g.lengths(q), np.linalg.norm(C - base), rtol=1e-10)
