"""Independent numeric references (numpy only): rotation, T, Newton-Euler for one rigid body."""
import numpy as np


def rotation(psi, th, ph):
    cx, sx, cy, sy, cz, sz = np.cos(psi), np.sin(psi), np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def T_matrix(th, ph):
    """Eq. (62) as printed in the paper."""
    return np.array([[np.cos(th) * np.cos(ph), -np.sin(ph), 0],
                     [np.cos(th) * np.sin(ph), np.cos(ph), 0],
                     [-np.sin(th), 0, 1]])


def vee(S):
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


def leg_lengths(model, q):
    """Stewart platform: base point to platform point, with the paper's rotation (numpy)."""
    R = rotation(*q[3:])
    base = np.array([c.point_from for c in model.cylinders])
    plat = np.array([c.point_to for c in model.cylinders])
    return np.linalg.norm(q[:3] + plat @ R.T - base, axis=1)


def newton_euler(model, theta, q, qd, qdd, h=1e-5):
    """Generalised force L^T [f; n] for one rigid body moving along q(t) = q + qd t + qdd t²/2.

    ω and ω̇ come from finite differences of R(t) (S(ω) = Ṙ Rᵀ), not from T: an
    independent check of both T and the symbolic dynamics.
    """
    Mp, Ix, Iy, Iz = theta

    def R_at(t):
        qt = q + qd * t + 0.5 * qdd * t * t
        return rotation(*qt[3:])

    def omega_at(t):
        Rd = (R_at(t + h) - R_at(t - h)) / (2 * h)
        return vee(Rd @ R_at(t).T)

    w = omega_at(0.0)
    wd = (omega_at(h) - omega_at(-h)) / (2 * h)
    R = R_at(0.0)
    Ib = R @ np.diag([Ix, Iy, Iz]) @ R.T
    f = Mp * (qdd[:3] + np.array([0, 0, model.gravity]))
    n = Ib @ wd + np.cross(w, Ib @ w)
    T = T_matrix(q[4], q[5])
    return np.concatenate([f, T.T @ n])
