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


def controller_rate_map(model, syms, X, idx):
    """Each symbol's rate along the controllers' assumptions (q → q̇, q̇ → acc, q_d,k → q_d,k+1,
    z → ż, θ̂ → θ̂̇, q̂ → z + Λ2 (q − q̂)), as a CasADi SX vector over ``X`` (``idx``: name → index)."""
    import casadi as ca

    rate = ca.SX.zeros(len(syms))

    def get(name):
        return X[idx[name]] if name in idx else 0

    for s in syms:
        n = str(s)
        base, _, k = n.rpartition("_")
        if n.startswith("q_") and not n.startswith("q_hat"):
            rate[idx[n]] = get(f"qdot_{model.coordinate_names.index(n[2:])}")
        elif base == "qdot":
            rate[idx[n]] = get(f"acc_{k}")
        elif base in ("qd0", "qd1", "qd2"):
            rate[idx[n]] = get(f"qd{int(base[2]) + 1}_{k}")
        elif base == "z":
            rate[idx[n]] = get(f"zdot_{k}")
        elif base == "theta_hat":
            rate[idx[n]] = get(f"thetadot_{k}")
        elif base == "q_hat":
            i = int(k)
            rate[idx[n]] = get(f"z_{i}") + get(f"Lambda2_{i}") * (get(f"q_{model.coordinate_names[i]}") - X[idx[n]])
    return rate


def rk4(f, y, h, steps):
    """``steps`` classical Runge-Kutta steps of ``h`` of y' = f(y) from ``y`` (an independent integrator for
    the plant blocks' closed-form checks)."""
    for _ in range(steps):
        k1 = f(y)
        k2 = f(y + h / 2 * k1)
        k3 = f(y + h / 2 * k2)
        k4 = f(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y


def singular_pose(dyn) -> np.ndarray:
    """A pose of ``dyn``'s robot where JL loses rank: the neutral pose with the first coordinate whose
    sweep down by up to pi changes det(JL)'s sign moved to that root, by bisection (a pivot ~1e-16)."""
    q0 = dyn.model.neutral_pose.copy()

    def det(j, x):
        q = q0.copy()
        q[j] = x
        return np.linalg.det(dyn.leg_jacobian(q)), q

    for j in range(dyn.model.n):
        xs = np.linspace(q0[j], q0[j] - np.pi, 181)
        signs = [np.sign(det(j, x)[0]) for x in xs]
        for a, b, sa, sb in zip(xs, xs[1:], signs, signs[1:]):
            if sa and sb and sa != sb:
                for _ in range(200):
                    mid = 0.5 * (a + b)
                    a, b = (mid, b) if np.sign(det(j, mid)[0]) == sa else (a, mid)
                return det(j, a)[1]
    raise AssertionError("no pose where JL is singular")
