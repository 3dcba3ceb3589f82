"""Numeric kinematics of a description's kinematic tree (numpy only).

Used to check a description when it is loaded (cylinder lengths and JL at the
neutral pose) and by tests as an implementation independent of the SymPy
derivation. Frames: base frame z up; a link frame sits at its parent joint.
Floating joints use [x, y, z, ψ, θ, φ] with R = Rz(φ) Ry(θ) Rx(ψ).
"""
from __future__ import annotations

import numpy as np

__all__ = ["rpy_matrix", "axis_rotation", "euler_zyx", "link_poses", "cylinder_lengths",
           "cylinder_jacobian", "fixed_path"]


def fixed_path(parent_joint: dict, link: str) -> list:
    """The fixed joints from ``link`` up to the link it moves with, child first: empty where its own
    joint moves or it has none (the root). ``parent_joint``: by child link name, the joint from its
    parent (anything with ``type``, ``parent``, ``child``: a description's joints or a URDF's).

    The link it moves with is the last joint's parent (``link`` itself where the path is empty);
    where that is the root, ``link`` is fixed to the base and never moves. The one walk of the tree
    through fixed joints, for the description's checks, the URDF reader and the derivation's merged
    bodies. A cycle (a tree not checked yet) ends the walk."""
    out, seen = [], set()
    while link in parent_joint and parent_joint[link].type == "fixed" and link not in seen:
        seen.add(link)
        out.append(parent_joint[link])
        link = parent_joint[link].parent
    return out


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rpy_matrix(rpy) -> np.ndarray:
    """URDF origin rotation: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (float(v) for v in rpy)
    return _rz(y) @ _ry(p) @ _rx(r)


def euler_zyx(psi, theta, phi) -> np.ndarray:
    """R = Rz(φ) Ry(θ) Rx(ψ) of a floating joint."""
    return _rz(phi) @ _ry(theta) @ _rx(psi)


def axis_rotation(axis, angle) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the unit vector ``axis`` (Rodrigues)."""
    k = np.asarray(axis, float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def link_poses(model, q) -> dict:
    """World pose (R 3×3, p 3) of every link at coordinates ``q`` (n,), keyed by link name."""
    q = np.asarray(q, float)
    poses = {model.root: (np.eye(3), np.zeros(3))}
    i = 0
    for j in model.joints:
        R_p, p_p = poses[j.parent]
        R_o = rpy_matrix(j.origin_rpy)
        xyz = np.asarray(j.origin_xyz, float)
        if j.type == "revolute":
            R = R_p @ R_o @ axis_rotation(j.axis, q[i])
            p = p_p + R_p @ xyz
        elif j.type == "prismatic":
            R = R_p @ R_o
            p = p_p + R_p @ (xyz + R_o @ np.asarray(j.axis, float) * q[i])
        elif j.type == "floating":
            R = R_p @ R_o @ euler_zyx(*q[i + 3:i + 6])
            p = p_p + R_p @ (xyz + q[i:i + 3])
        else:  # fixed
            R, p = R_p @ R_o, p_p + R_p @ xyz
        i += j.dof
        poses[j.child] = (R, p)
    return poses


def cylinder_lengths(model, q) -> np.ndarray:
    """Pin-to-pin length of every cylinder (m,) at ``q``."""
    poses = link_poses(model, q)
    q = np.asarray(q, float)
    columns, i = {}, 0
    for j in model.joints:
        columns[j.name] = i
        i += j.dof
    out = []
    for c in model.cylinders:
        if getattr(c, "joint", None) is not None:  # a joint actuator (rotary): the joint's angle
            out.append(q[columns[c.joint]])
            continue
        if getattr(c, "linkage", None) is not None:  # through a four-bar linkage on its joint
            out.append(float(c.linkage.lengths(q[columns[c.linkage_joint]])))
            continue
        Ra, pa = poses[c.link_from]
        Rb, pb = poses[c.link_to]
        out.append(np.linalg.norm(pb + Rb @ c.point_to - pa - Ra @ c.point_from))
    return np.array(out)


def cylinder_jacobian(model, q, h: float = 1e-7) -> np.ndarray:
    """JL = ∂l/∂q (m × n) by central differences (a check, not a hot path)."""
    q = np.asarray(q, float)
    cols = []
    for k in range(q.size):
        dq = np.zeros_like(q)
        dq[k] = h
        cols.append((cylinder_lengths(model, q + dq) - cylinder_lengths(model, q - dq)) / (2 * h))
    return np.array(cols).T
