"""ctypes binding of the rendered C loop driver (templates/loop.c.j2).

:class:`LoopRunner` owns every buffer the C loop touches (configuration,
state, the controller's argument tables, the logs); they are made once and the
C code advances any number of control periods per call.
"""
from __future__ import annotations

import ctypes as C

import numpy as np

__all__ = ["LoopRunner", "SLOTS", "LOOP_OK", "LOOP_NONFINITE", "LOOP_FK_FAILED", "LOOP_CTRL_FAILED"]

SLOTS = ("q", "qdot", "pc", "l", "qd0", "qd1", "qd2", "qd3", "xc", "adapt")
LOOP_OK, LOOP_NONFINITE, LOOP_FK_FAILED, LOOP_CTRL_FAILED = 0, 1, 2, 3
_D = C.POINTER(C.c_double)
_LL = C.c_longlong


class _Config(C.Structure):
    _fields_ = [
        ("h", C.c_double), ("substeps", _LL), ("t_adapt", C.c_double),
        ("theta", _D), ("gamma", _D), ("friction", _D), ("tau_valve", _D), ("supply_pressure", C.c_double),
        ("use_kalman", _LL), ("kf_gain", C.c_double * 2),
        ("bias", _D), ("n_terms", _LL), ("terms", _D), ("step_axis", _LL), ("step_height", C.c_double),
        ("t_step", C.c_double),
        ("ctrl", C.c_void_p), ("ctrl_arg", C.c_void_p), ("ctrl_res", C.c_void_p), ("ctrl_iw", C.c_void_p),
        ("ctrl_w", C.c_void_p), ("slot", _LL * len(SLOTS)), ("n_xc", _LL), ("xc_lo", _D), ("xc_hi", _D),
        ("fk_tol", C.c_double), ("fk_max_iter", _LL),
    ]


class _State(C.Structure):
    _fields_ = [("t", C.c_double), ("k", _LL), ("x", C.c_double * 24), ("q_meas", C.c_double * 6),
                ("kf", C.c_double * 12), ("xc", _D)]


class _Log(C.Structure):
    _fields_ = [(n, _D) for n in ("t", "q", "q_d", "l", "f", "pc", "u", "xc")]


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_D)


def _check_reference_indices(ref, n):
    """Refuse, before any C runs, a reference whose bias or axes would index the C arrays out of range."""
    if np.shape(ref.bias) != (n,):
        raise ValueError(f"reference bias must hold {n} numbers, got shape {np.shape(ref.bias)}")
    axes = [t[0] for t in getattr(ref, "terms", ())]
    if hasattr(ref, "axis"):
        axes.append(ref.axis)
    for a in axes:
        if isinstance(a, bool) or not float(a).is_integer() or not 0 <= int(a) < n:
            raise ValueError(f"reference axis {a!r} is outside 0..{n - 1}; the C loop would index out of range")


class LoopRunner:
    """One configured closed loop: plant parameters, reference, sensors and a controller runtime.

    Parameters
    ----------
    dyn : Dynamics
        Compiled dynamics whose library holds the loop driver.
    ctrl : controller runtime from :func:`hydrogen.simulation.control.make_controller`
        Its static inputs (gains, bounds, θ for backstepping) are copied in once.
    """

    def __init__(self, dyn, ctrl, *, h, substeps, t_adapt, theta, gamma, friction, valve_lag,
                 reference, kalman_gain=None, fk_tol=1e-12, fk_max_iter=50):
        lib = dyn.library._lib
        name = dyn.model.name
        self._run = getattr(lib, f"{name}_loop_run")
        self._run.restype = C.c_int
        self._run.argtypes = [C.c_void_p, C.c_void_p, _LL, C.c_void_p, C.c_void_p]
        self._keep = []  # every array the C side points at stays alive with this object

        def arr(x):
            a = np.ascontiguousarray(x, dtype=float).copy()
            self._keep.append(a)
            return a

        fn = ctrl.fn
        self.ctrl, self.fn = ctrl, fn
        # Static inputs: write every input once through the function's own buffers.
        values = dict(ctrl.values)
        for nme, view in zip(fn.in_names, fn._in_views):
            if nme in values:
                view[...] = np.reshape(values[nme], view.shape)
        cfg = _Config()
        cfg.h, cfg.substeps, cfg.t_adapt = h, int(substeps), float(t_adapt)
        cfg.theta, cfg.gamma = _ptr(arr(theta)), _ptr(arr(gamma))
        cfg.friction, cfg.tau_valve = _ptr(arr(friction)), _ptr(arr([valve_lag]))
        cfg.supply_pressure = dyn.model.supply_pressure
        cfg.use_kalman = 1 if kalman_gain is not None else 0
        if kalman_gain is not None:
            cfg.kf_gain[0], cfg.kf_gain[1] = kalman_gain
        ref = reference
        _check_reference_indices(ref, len(dyn.model.neutral_pose))  # the C loop indexes qd[] with them
        cfg.bias = _ptr(arr(ref.bias))
        terms = getattr(ref, "terms", ())
        cfg.n_terms = len(terms)
        cfg.terms = _ptr(arr(np.array(terms, float).reshape(-1) if terms else np.zeros(1)))
        cfg.step_axis = getattr(ref, "axis", -1)
        cfg.step_height = getattr(ref, "height", 0.0)
        cfg.t_step = getattr(ref, "t_step", 0.0)
        cfg.ctrl = C.cast(getattr(lib, fn.c_name), C.c_void_p)
        cfg.ctrl_arg = C.cast(fn._arg, C.c_void_p)
        cfg.ctrl_res = C.cast(fn._res, C.c_void_p)
        cfg.ctrl_iw = C.cast(fn._iw, C.c_void_p)
        cfg.ctrl_w = C.cast(fn._w, C.c_void_p)
        for i, s in enumerate(SLOTS):
            cfg.slot[i] = fn.in_names.index(s) if s in fn.in_names else -1
        n_xc = ctrl.xc.size
        cfg.n_xc = n_xc
        cfg.xc_lo, cfg.xc_hi = _ptr(arr(np.where(np.isfinite(ctrl._lo), ctrl._lo, -1e300))), \
            _ptr(arr(np.where(np.isfinite(ctrl._hi), ctrl._hi, 1e300)))
        cfg.fk_tol, cfg.fk_max_iter = fk_tol, fk_max_iter
        self.cfg = cfg
        self.state = _State()
        self.xc = np.zeros(max(n_xc, 1))
        self.state.xc = _ptr(self.xc)
        self._cfg_ref, self._st_ref = C.byref(cfg), C.byref(self.state)

    def reset(self, x0, q_meas0, l0, xc0):
        """Initial plant state (24), measured pose, Kalman leg lengths and controller state."""
        st = self.state
        st.t, st.k = 0.0, 0
        st.x[:] = list(np.asarray(x0, float))
        st.q_meas[:] = list(np.asarray(q_meas0, float))
        st.kf[:] = list(np.concatenate([l0, np.zeros(6)]))
        self.xc[: xc0.size] = xc0

    _LOG_WIDTH = {"t": 1, "q": 6, "q_d": 6, "l": 6, "f": 6, "pc": 6, "u": 6}

    def run(self, n: int, noise=None, logs: dict | None = None) -> int:
        """Advance ``n`` periods; ``noise`` (≥ n, 12) or None; ``logs`` maps names to arrays with a row
        per period of the whole run (rows st.k … st.k + n − 1 are written).

        Shapes, dtype and layout are checked here, so the C code never writes or reads past an array.
        """
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if noise is not None:
            if (noise.dtype != np.float64 or not noise.flags.c_contiguous or noise.ndim != 2
                    or noise.shape[1] != 12 or noise.shape[0] < n):
                raise ValueError(f"noise must be a C-contiguous float64 array of shape (>= {n}, 12), "
                                 f"got {noise.dtype} {noise.shape}")
        log = None
        if logs:
            log = _Log()
            end = self.state.k + n
            for k, v in logs.items():
                width = self.xc.size if k == "xc" else self._LOG_WIDTH.get(k)
                if width is None:
                    raise KeyError(f"unknown log '{k}'; logs are {sorted(self._LOG_WIDTH)} and 'xc'")
                if (v.dtype != np.float64 or not v.flags.c_contiguous or v.size < end * width
                        or (v.ndim == 2 and v.shape[1] != width)):
                    raise ValueError(f"log '{k}' must be a C-contiguous float64 array with >= {end} rows "
                                     f"of {width}, got {v.dtype} {v.shape}")
                setattr(log, k, _ptr(v))
        nz = None if noise is None else noise.ctypes.data_as(C.c_void_p)
        return self._run(self._cfg_ref, self._st_ref, int(n), nz, None if log is None else C.byref(log))

    @property
    def plant_state(self) -> np.ndarray:
        return np.array(self.state.x[:])
