"""Compiled dynamics of a model: the user-facing numeric API (numpy in, numpy out).

q: the model's n generalized coordinates (m or rad; a floating joint's are [x, y, z, ψ, θ, φ] in
the base frame, z up). θ: the adapted inertial parameters (``model.theta_names``, SI). Cylinder
("leg") lengths in m, pressures in Pa, spool positions in m; one entry per cylinder.
"""
from __future__ import annotations

import ctypes

import numpy as np

from .errors import InputError, KinematicsError, ScenarioError
from .layout import FK_MAX_COND, FK_MAX_ITER, FK_STATUS, FK_TOL, LU_PIVOT_MIN
from .plant.supply import PRESSURE as SUPPLY_PRESSURE

__all__ = ["Dynamics", "fk_failure"]

_D = ctypes.c_double
_SOLVED, _SINGULAR, _NOT_CONVERGED, VELOCITY_SINGULAR = (
    FK_STATUS.index(s) for s in ("solved", "singular", "not_converged", "velocity_singular"))


def fk_failure(status: int, info, q, l, max_iter: int, max_cond: float = FK_MAX_COND) -> str:
    """Why forward kinematics failed, in words: the C outcome ``status`` (:data:`~hydrogen.layout.FK_STATUS`)
    with its ``info`` (residual in m, JL's 1-norm condition number, Newton steps), the last iterate ``q``
    and the cylinder lengths ``l`` (m) it was solved for. The one wording of the loop and of
    :meth:`Dynamics.forward_kinematics`. ``VELOCITY_SINGULAR`` is the loop's velocity solve at the
    measured pose ``q`` (encoders' or solved), not forward kinematics."""
    err, cond, steps = (float(v) for v in info)
    q, l = np.asarray(q, float), np.asarray(l, float)
    if status == VELOCITY_SINGULAR:
        return (f"velocity estimate: JL is singular at the measured pose q = {q} (a pivot not above "
                f"{LU_PIVOT_MIN:g}): no joint velocities from the cylinder rates (leg lengths {l})")
    if status == _SINGULAR:
        return (f"forward kinematics: JL is singular (condition number {cond:.3g}, 1-norm; at most {max_cond:.3g}) "
                f"at q = {q} (iteration {int(steps)}, leg lengths {l})")
    if status == _NOT_CONVERGED:
        return (f"forward kinematics did not converge in {max_iter} iterations for leg lengths {l}: "
                f"residual {err:.3g} m at q = {q}")
    return f"forward kinematics: the generated leg_kinematics function returned an error at q = {q}"


class Dynamics:
    """Thin wrapper over the compiled library of one model (see :func:`hydrogen.build`).

    Every function takes one state, or a batch: inputs stacked as (n, …) (an unstacked input
    is shared by all n states) give outputs of shape (n, …) from one call into C. ``out=``
    writes into given arrays (C-contiguous float64 of the output's shape) and returns them.
    ``backend`` tells how the compiled code is called: "extension" or "ctypes".
    """

    def __init__(self, model, library):
        self.model = model
        self.library = library
        # The compiled extension's functions when built (hydrogen.runtime.extension), else ctypes.
        fast = getattr(library, "extension_functions", None)
        #: "extension" (direct calls through the compiled CPython extension) or "ctypes"
        self.backend = "extension" if fast else "ctypes"
        f = fast or library.functions
        self._leg_lengths = f["leg_lengths"]
        self._leg_jacobian = f["leg_jacobian"]
        self._mass_matrix = f["mass_matrix"]
        self._coriolis = f["coriolis"]
        self._gravity = f["gravity"]
        self._regressor = f["regressor"]
        self._forward_dynamics = f.get("forward_dynamics")
        self._inverse_dynamics = f.get("inverse_dynamics")
        self.functions = f
        symbol = getattr(library, "symbol", None)  # absent for pure-Python stand-ins (benchmarks)
        #: the values of the generated functions' ``numbers`` input (a library generated with the
        #: description's numbers as inputs), or None (numbers folded)
        self.numbers = getattr(library, "numbers", None)
        self._many = symbol(f"{model.name}_leg_lengths_many") if symbol is not None else None
        self._fk = None  # the loop driver's forward kinematics, bound at first use (_fk_symbols)
        if self._many is not None:
            self._many.restype = ctypes.c_int
            self._many.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_longlong, ctypes.c_void_p]

    # --- kinematics -------------------------------------------------------------------
    def leg_lengths(self, q, out=None) -> np.ndarray:
        """(m,) cylinder lengths l(q), m."""
        return self._leg_lengths(q) if out is None else self._leg_lengths(q, out=out)

    def leg_lengths_many(self, qs) -> np.ndarray:
        """(k, m) cylinder lengths (m) of the k poses in the rows of ``qs`` (k, n): one call into the
        compiled loop driver for a whole trajectory."""
        n, m = self.model.n, self.model.n_cylinders
        qs = np.ascontiguousarray(qs, dtype=float)
        if qs.ndim != 2 or qs.shape[1] != n:
            raise InputError(f"leg_lengths_many: poses must have shape (k, {n}), got {qs.shape}")
        bad = np.nonzero(~np.isfinite(qs).all(axis=1))[0]
        if bad.size:  # as leg_lengths refuses a NaN pose, naming the rows
            rows = ", ".join(map(str, bad[:10].tolist())) + (" ..." if bad.size > 10 else "")
            raise InputError(f"leg_lengths_many: poses not finite in {bad.size} of {len(qs)} rows: [{rows}]")
        if self._many is None:
            return np.array([self._leg_lengths(q) for q in qs]).reshape(-1, m)
        out = np.empty((qs.shape[0], m))
        if self._many(self._numbers_pointer(), qs.ctypes.data, len(qs), out.ctypes.data):
            raise KinematicsError("leg_lengths_many: the generated leg_lengths function returned an error")
        return out

    def leg_jacobian(self, q, out=None) -> np.ndarray:
        """(m, n) JL = ∂l/∂q."""
        return self._leg_jacobian(q) if out is None else self._leg_jacobian(q, out=out)

    def _fk_symbols(self):
        """The loop driver's forward kinematics (templates/loop.c.j2): the single sample's and the batch's."""
        if self._fk is None:
            symbol = getattr(self.library, "symbol", None)
            if symbol is None:
                raise KinematicsError(f"forward kinematics of model '{self.model.name}': these dynamics have no "
                                      "compiled loop driver (it holds forward kinematics); build them with "
                                      "hydrogen.build")
            one, many = symbol(f"{self.model.name}_forward_kinematics"), \
                symbol(f"{self.model.name}_forward_kinematics_many")
            vp, ll = ctypes.c_void_p, ctypes.c_longlong
            one.restype, one.argtypes = ctypes.c_int, [vp, vp, vp, _D, ll, _D, vp]
            many.restype, many.argtypes = ll, [vp, vp, ll, vp, _D, ll, _D, vp, vp, vp]
            self._fk = one, many
        return self._fk

    def _fk_arguments(self, q0, tol, max_iter, max_cond):
        """The start pose (a fresh float64 copy; the neutral pose for None) and the solver settings, checked."""
        n = self.model.n
        q = np.array(self.model.neutral_pose if q0 is None else q0, dtype=float)
        if q.shape != (n,):
            raise KinematicsError(f"forward kinematics: q0 needs {n} coordinates, got shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise KinematicsError(f"forward kinematics: initial guess q0 is not finite: {q}")
        try:
            settings = float(tol), int(max_iter), float(max_cond)
            ok = 0 < settings[0] < np.inf and settings[1] == max_iter and settings[1] >= 0 and settings[2] > 0
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise KinematicsError(f"forward kinematics: needs tol > 0 (m), max_iter >= 0 (an integer) and "
                                  f"max_cond > 0, got tol = {tol!r}, max_iter = {max_iter!r}, max_cond = {max_cond!r}")
        return (q, *settings)

    def forward_kinematics(self, l, q0=None, tol: float = FK_TOL, max_iter: int = FK_MAX_ITER,
                           max_cond: float = FK_MAX_COND) -> np.ndarray:
        """Coordinates q (n,) whose cylinder lengths are ``l`` (m), by Newton's method from ``q0``.

        The C loop's own forward kinematics (``<model>_forward_kinematics`` of the compiled loop
        driver). ``q0`` defaults to the model's neutral pose. Raises
        :class:`~hydrogen.errors.KinematicsError` if JL becomes singular (condition number, 1-norm,
        above ``max_cond``) or the residual max |l(q) − l| does not fall below ``tol`` m within
        ``max_iter`` Newton steps.
        """
        m = self.model.n_cylinders
        l = np.asarray(l, dtype=float)
        if l.shape != (m,):
            raise KinematicsError(f"forward kinematics: needs {m} cylinder lengths, got shape {l.shape}")
        if not np.all(np.isfinite(l)):
            raise KinematicsError(f"forward kinematics: leg lengths are not finite: {l}")
        q, tol, max_iter, max_cond = self._fk_arguments(q0, tol, max_iter, max_cond)
        l = np.ascontiguousarray(l)
        info = np.empty(3)
        one = self._fk_symbols()[0]
        status = one(self._numbers_pointer(), l.ctypes.data, q.ctypes.data, tol, max_iter, max_cond, info.ctypes.data)
        if status != _SOLVED:
            raise KinematicsError(fk_failure(status, info, q, l, max_iter, max_cond))
        return q

    def forward_kinematics_many(self, L, q0=None, tol: float = FK_TOL, max_iter: int = FK_MAX_ITER,
                                max_cond: float = FK_MAX_COND) -> np.ndarray:
        """(k, n) poses of the k rows of cylinder lengths ``L`` (k, m), in m: :meth:`forward_kinematics`
        of each row started from the pose of the row before (the first from ``q0``), in one call into C.

        Raises :class:`~hydrogen.errors.KinematicsError` naming the first row that fails; the error's
        ``sample`` is that row and its ``reason`` the words :meth:`forward_kinematics` would raise."""
        m = self.model.n_cylinders
        L = np.ascontiguousarray(L, dtype=float)
        if L.ndim != 2 or L.shape[1] != m:
            raise KinematicsError(f"forward kinematics: needs rows of {m} cylinder lengths, shape (k, {m}); "
                                  f"got shape {L.shape}")
        bad = ~np.isfinite(L).all(axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            _raise_at(k, f"forward kinematics: leg lengths are not finite: {L[k]}")
        q0, tol, max_iter, max_cond = self._fk_arguments(q0, tol, max_iter, max_cond)
        Q = np.empty((len(L), self.model.n))
        status, info = ctypes.c_int(0), np.empty(3)
        many = self._fk_symbols()[1]
        k = many(self._numbers_pointer(), L.ctypes.data, len(L), q0.ctypes.data, tol, max_iter, max_cond,
                 Q.ctypes.data, ctypes.byref(status), info.ctypes.data)
        if k != len(L):
            _raise_at(k, fk_failure(status.value, info, Q[k], L[k], max_iter, max_cond))
        return Q

    def _numbers_pointer(self):
        return None if self.numbers is None else self.numbers.ctypes.data

    # --- rigid body -------------------------------------------------------------------
    def mass_matrix(self, q, theta, out=None) -> np.ndarray:
        """(n, n) D(q) for parameters θ."""
        return self._mass_matrix(q, theta) if out is None else self._mass_matrix(q, theta, out=out)

    def coriolis(self, q, qdot, theta, out=None) -> np.ndarray:
        """(n, n) Christoffel-form C(q, q̇)."""
        return self._coriolis(q, qdot, theta) if out is None else self._coriolis(q, qdot, theta, out=out)

    def gravity(self, q, theta, out=None) -> np.ndarray:
        """(n,) G, N or N m (generalised force; gravity along −z)."""
        return self._gravity(q, theta) if out is None else self._gravity(q, theta, out=out)

    def regressor(self, q, v, w, a, out=None) -> np.ndarray:
        """(n, p) Y(q, v, w, a): Y θ + y0 = D(q) a + C(q, v) w + G(q), where y0 (the share of the
        parameters that are not adapted; zero when θ holds them all) is :meth:`regressor_offset`."""
        return self._regressor(q, v, w, a) if out is None else self._regressor(q, v, w, a, out=out)

    def forward_dynamics(self, q, qdot, tau, theta, out=None) -> np.ndarray:
        """q̈ = D(q)⁻¹ (τ − C(q, q̇) q̇ − G) for generalised forces τ: one generated function.

        Like every method here it takes a batch too: q, q̇, τ of shape (n, …) (θ shared or
        stacked) give q̈ of shape (n, …) from one call into C.
        """
        f = self._forward_dynamics
        return f(q, qdot, tau, theta) if out is None else f(q, qdot, tau, theta, out=out)

    def inverse_dynamics(self, q, qdot, qddot, theta, out=None) -> np.ndarray:
        """τ = D(q) q̈ + C(q, q̇) q̇ + G (N or N m): one generated function (batches as everywhere)."""
        f = self._inverse_dynamics
        if f is None:
            raise KeyError("inverse_dynamics: these dynamics have no generated inverse dynamics; regenerate")
        return f(q, qdot, qddot, theta) if out is None else f(q, qdot, qddot, theta, out=out)

    def regressor_offset(self, q, v, w, a) -> np.ndarray:
        """(n,) y0 = D a + C(q, v) w + G − Y θ (zeros when every parameter that moves the robot is in θ)."""
        f = self.functions.get("regressor_offset")
        return np.zeros(self.model.n) if f is None else f(q, v, w, a)

    # --- hydraulics -------------------------------------------------------------------
    def valve_flow(self, u, pc, out=None) -> np.ndarray:
        """Valve flow per unit flow gain c into each pressure state's chamber (m·√Pa), for spool u (m,
        per actuator) and the pressure vector ``pc`` (Pa): each kind's law with its drops clipped at 0
        (a three-way cylinder's is q_l / c of (57), one per actuator)."""
        f = self.functions["valve_flow"]
        return f(u, pc) if out is None else f(u, pc, out=out)

    def valve_inverse(self, g0, pc, l=None, out=None) -> np.ndarray:
        """(m,) spool positions u (m) whose g0(l, p, u) is ``g0`` per actuator (the force loop's valve
        term, ḟ = β f0 + βc g0) at the pressure vector ``pc`` (Pa) and actuator coordinates ``l`` (m,
        m or rad), every branch in closed form; for a three-way cylinder (57) inverted at
        q_l / c = g0 (l − L)."""
        if l is None:
            raise InputError(f"model '{self.model.name}': valve_inverse(g0, pc, l=...) needs the actuator "
                             "coordinates l (g0 depends on them)")
        f = self.functions["valve_inverse"]
        return f(g0, l, pc) if out is None else f(g0, l, pc, out=out)

    def pressure_rate(self, l, ldot, pc, u, gamma, out=None) -> np.ndarray:
        """ṗ (Pa/s) of the pressure vector (ṗ_c of (56)-(57) per three-way cylinder) with γ = [β, βc] per
        cylinder, shape (2, m) (or (2,) for all; stacked as (k, 2, m) with the other inputs)."""
        m = self.model.n_cylinders
        g = np.asarray(gamma, float)
        if g.shape == (2,):
            g = np.broadcast_to(g[:, None], (2, m))
        elif g.ndim < 2 or g.shape[-2:] != (2, m):
            raise InputError(f"pressure_rate: gamma must be [beta, beta*c] of shape (2,), (2, {m}) or (k, 2, {m}) "
                             f"(rows beta and beta*c, a column per actuator), got shape {g.shape}")
        f = self.functions["pressure_rate"]
        g1, g2 = g[..., 0, :], g[..., 1, :]
        return f(l, ldot, pc, u, g1, g2) if out is None else f(l, ldot, pc, u, g1, g2, out=out)

    def leg_force(self, pc, ps=None, out=None) -> np.ndarray:
        """(m,) cylinder forces from the pressure vector (f = p_c A − p_s a for a three-way cylinder), N;
        ``ps`` (Pa, (1,)): the supply pressure of a robot whose supply is a plant state (required there,
        refused otherwise)."""
        fn = self.functions["leg_force"]
        takes = SUPPLY_PRESSURE in fn.in_names
        if takes != (ps is not None):
            raise ScenarioError(f"leg_force of '{self.model.name}': " + (
                "needs the supply pressure ps (its supply is a plant state)" if takes else
                "takes no supply pressure (its supply is constant)"))
        args = (pc, np.atleast_1d(np.asarray(ps, float))) if takes else (pc,)
        return fn(*args) if out is None else fn(*args, out=out)


def _raise_at(k: int, reason: str):
    """A KinematicsError for row ``k`` of a batch: ``sample`` and ``reason`` (the single sample's words) kept."""
    exc = KinematicsError(f"sample {k}: {reason}")
    exc.sample, exc.reason = k, reason
    raise exc
