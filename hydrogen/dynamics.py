"""Compiled dynamics of a model: the user-facing numeric API (numpy in, numpy out).

q: the model's n generalized coordinates (m or rad; a floating joint's are [x, y, z, ψ, θ, φ] in
the base frame, z up). θ: the adapted inertial parameters (``model.theta_names``, SI). Cylinder
("leg") lengths in m, pressures in Pa, spool positions in m; one entry per cylinder.
"""
from __future__ import annotations

import ctypes

import numpy as np

from .errors import KinematicsError

__all__ = ["Dynamics"]


class Dynamics:
    """Thin wrapper over the compiled library of one model (see :func:`hydrogen.build`)."""

    def __init__(self, model, library):
        self.model = model
        self.library = library
        f = library.functions
        self._leg_lengths = f["leg_lengths"]
        self._leg_jacobian = f["leg_jacobian"]
        self._mass_matrix = f["mass_matrix"]
        self._coriolis = f["coriolis"]
        self._gravity = f["gravity"]
        self._regressor = f["regressor"]
        self.functions = f
        symbol = getattr(library, "symbol", None)  # absent for pure-Python stand-ins (benchmarks)
        self._many = symbol(f"{model.name}_leg_lengths_many") if symbol is not None else None
        if self._many is not None:
            self._many.restype = ctypes.c_int
            self._many.argtypes = [ctypes.c_void_p, ctypes.c_longlong, ctypes.c_void_p]

    # --- kinematics -------------------------------------------------------------------
    def leg_lengths(self, q) -> np.ndarray:
        """(m,) cylinder lengths l(q), m."""
        return self._leg_lengths(q)

    def leg_lengths_many(self, qs) -> np.ndarray:
        """(k, m) cylinder lengths (m) of the k poses in the rows of ``qs`` (k, n): one call into the
        compiled loop driver for a whole trajectory."""
        n, m = self.model.n, self.model.n_cylinders
        qs = np.ascontiguousarray(qs, dtype=float)
        if qs.ndim != 2 or qs.shape[1] != n:
            raise ValueError(f"leg_lengths_many: poses must have shape (k, {n}), got {qs.shape}")
        if self._many is None:
            return np.array([self._leg_lengths(q) for q in qs]).reshape(-1, m)
        out = np.empty((qs.shape[0], m))
        if self._many(qs.ctypes.data, len(qs), out.ctypes.data):
            raise KinematicsError("leg_lengths_many: the generated leg_lengths function returned an error")
        return out

    def leg_jacobian(self, q) -> np.ndarray:
        """(m, n) JL = ∂l/∂q."""
        return self._leg_jacobian(q)

    def forward_kinematics(self, l, q0=None, tol: float = 1e-12, max_iter: int = 50,
                           max_cond: float = 1e8) -> np.ndarray:
        """Coordinates q (n,) whose cylinder lengths are ``l`` (m), by Newton's method from ``q0``.

        ``q0`` defaults to the model's neutral pose. Raises
        :class:`~hydrogen.errors.KinematicsError` if JL becomes singular (condition
        number above ``max_cond``) or the residual ‖l(q) − l‖ does not fall below
        ``tol`` m within ``max_iter`` iterations.
        """
        n, m = self.model.n, self.model.n_cylinders
        l = np.asarray(l, dtype=float)
        if l.shape != (m,):
            raise KinematicsError(f"forward kinematics: needs {m} cylinder lengths, got shape {l.shape}")
        if not np.all(np.isfinite(l)):
            raise KinematicsError(f"forward kinematics: leg lengths are not finite: {l}")
        q = np.array(self.model.neutral_pose if q0 is None else q0, dtype=float)
        if q.shape != (n,):
            raise KinematicsError(f"forward kinematics: q0 needs {n} coordinates, got shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise KinematicsError(f"forward kinematics: initial guess q0 is not finite: {q}")
        err = np.inf
        for it in range(max(int(max_iter), 1)):
            r = self._leg_lengths(q) - l
            err = float(np.max(np.abs(r)))
            if err < tol:
                return q
            J = self._leg_jacobian(q)
            cond = np.linalg.cond(J)
            if not np.isfinite(cond) or cond > max_cond:
                raise KinematicsError(
                    f"forward kinematics: JL is singular (cond {cond:.3g}) at q = {q} "
                    f"(iteration {it}, leg lengths {l})")
            q = q - np.linalg.solve(J, r)
        raise KinematicsError(
            f"forward kinematics did not converge in {max_iter} iterations for leg lengths {l}: "
            f"residual {err:.3g} m at q = {q}")

    # --- rigid body -------------------------------------------------------------------
    def mass_matrix(self, q, theta) -> np.ndarray:
        """(n, n) D(q) for parameters θ."""
        return self._mass_matrix(q, theta)

    def coriolis(self, q, qdot, theta) -> np.ndarray:
        """(n, n) Christoffel-form C(q, q̇)."""
        return self._coriolis(q, qdot, theta)

    def gravity(self, q, theta) -> np.ndarray:
        """(n,) G, N or N m (generalised force; gravity along −z)."""
        return self._gravity(q, theta)

    def regressor(self, q, v, w, a) -> np.ndarray:
        """(n, p) Y(q, v, w, a): Y θ + y0 = D(q) a + C(q, v) w + G(q), where y0 (the share of the
        parameters that are not adapted; zero when θ holds them all) is :meth:`regressor_offset`."""
        return self._regressor(q, v, w, a)

    def regressor_offset(self, q, v, w, a) -> np.ndarray:
        """(n,) y0 = D a + C(q, v) w + G − Y θ (zeros when every parameter that moves the robot is in θ)."""
        f = self.functions.get("regressor_offset")
        return np.zeros(self.model.n) if f is None else f(q, v, w, a)

    # --- hydraulics -------------------------------------------------------------------
    def valve_flow(self, u, pc) -> np.ndarray:
        """(m,) load flow per unit flow gain, q_l / c (eq. 57), for spool u (m) and p_c (Pa).

        This is (57) as printed: its roots need 0 ≤ p_c ≤ P_s, and a pressure outside
        that range gives NaN (the simulated plant uses its linearised, signed law instead).
        """
        return self.functions["valve_flow"](u, pc)

    def valve_inverse(self, ql_per_c, pc) -> np.ndarray:
        """(m,) spool positions u (m) giving q_l / c = ``ql_per_c`` at control pressures p_c."""
        return self.functions["valve_inverse"](ql_per_c, pc)

    def pressure_rate(self, l, ldot, pc, u, gamma) -> np.ndarray:
        """(m,) ṗ_c (Pa/s) of (56)-(57) with γ = [β, βc] per cylinder, shape (2, m) (or (2,) for all)."""
        g = np.broadcast_to(np.asarray(gamma, float).reshape(2, -1), (2, self.model.n_cylinders))
        return self.functions["pressure_rate"](l, ldot, pc, u, g[0], g[1])

    def leg_force(self, pc) -> np.ndarray:
        """(m,) cylinder forces f = p_c A − p_s a, N."""
        return self.functions["leg_force"](pc)
