"""ctypes binding of the rendered C loop driver (templates/loop.c.j2).

:class:`LoopRunner` owns every buffer the C loop touches (configuration,
state, the controller's argument tables, the logs); they are made once and the
C code advances any number of control periods per call.
"""
from __future__ import annotations

import ctypes as C
import weakref

import numpy as np

__all__ = ["LoopRunner", "LOOP_OK", "LOOP_NONFINITE", "LOOP_FK_FAILED", "LOOP_CTRL_FAILED"]

from .. import references
from ..errors import InputError
from ..estimators import ESTIMATORS, estimator  # each estimator's state, started at the lengths
from ..layout import log_rows, loop_context

LOOP_OK, LOOP_NONFINITE, LOOP_FK_FAILED, LOOP_CTRL_FAILED = 0, 1, 2, 3
_D = C.POINTER(C.c_double)
_LL = C.c_longlong
_STRUCTS = {}
#: The loop context of each loaded library (its manifest does not change): a runner per gain set of a
#: sweep would otherwise render it again.
_CONTEXTS = weakref.WeakKeyDictionary()


def _context(library) -> dict:
    """:func:`hydrogen.layout.loop_context` of ``library``'s manifest, worked out once per library
    (shared by its runners: read only)."""
    ctx = _CONTEXTS.get(library)
    if ctx is None:
        ctx = _CONTEXTS[library] = loop_context(library.manifest)
    return ctx


def _structs(ctx: dict):
    """ctypes mirrors of the loop's config, state and log structs, sized from the template context
    (the same context the C was rendered from)."""
    # every field of every struct mirrored, with its type and length: two robots share the mirrors only
    # where their structs are the same (a robot's encoders, sensors or inputs change its structs' layout)
    key = (tuple((f["name"], f["type"]) for g in ctx["config"] for f in g["fields"]), len(ctx["slots"]),
           *(tuple((f["name"], f["type"], f["length"]) for f in ctx[part]) for part in ("state", "signals")),
           tuple(n for n, _, _ in ctx["logs"]))
    if key in _STRUCTS:
        return _STRUCTS[key]

    ctypes_of = {"double": C.c_double, "long long": _LL, "const double*": _D,
                 "fn": C.c_void_p, "double**": C.c_void_p, "long long int*": C.c_void_p, "double*": C.c_void_p,
                 "slots": _LL * len(ctx["slots"])}

    def config_type(ctype):  # double[<n>]: an array of the struct's own (an estimator's numbers)
        return C.c_double * _array_size(ctype) if ctype.startswith("double[") else ctypes_of[ctype]

    class Config(C.Structure):  # the loop header's struct, from the one description (hydrogen.layout.LOOP_CONFIG)
        _fields_ = [(f["name"], config_type(f["type"])) for g in ctx["config"] for f in g["fields"]]

    def mirror(fields):  # a struct of the loop header rendered from a description (hydrogen.layout)
        scalar = {"double": C.c_double, "long long": _LL, "double*": _D}
        return [(f["name"], scalar[f["type"]] if f["length"] is None else scalar[f["type"]] * f["length"])
                for f in fields]

    class State(C.Structure):  # hydrogen.layout.LOOP_STATE
        _fields_ = mirror(ctx["state"])

    class Signals(C.Structure):  # hydrogen.layout.LOOP_SIGNALS
        _fields_ = mirror(ctx["signals"])

    class Log(C.Structure):
        _fields_ = [(name, _D) for name, _, _ in ctx["logs"]]

    _STRUCTS[key] = (Config, State, Log, Signals)
    return _STRUCTS[key]


def _array_size(ctype: str) -> int:
    """Entries of a configuration field of C type ``double[<n>]``."""
    return int(ctype.removeprefix("double[").removesuffix("]"))


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_D)


def _check_values(values, ctx, ctrl, dyn) -> None:
    """Refuse, before any C runs, configuration values the C loop would read past or misread: a missing
    field, arrays of the wrong size, a reference axis outside the coordinates, a delay beyond the ring."""
    numbers = () if dyn.numbers is None else dyn.numbers
    missing = [f["name"] for g in ctx["config"] for f in g["fields"] if f["source"] and f["name"] not in values]
    if missing:
        raise InputError(f"loop configuration: no value for {missing} (hydrogen.layout.LOOP_CONFIG)")
    model = dyn.model
    n, m, n_xc = len(model.neutral_pose), ctx["m"], int(ctrl.xc.size)
    sizes = {"theta": len(model.theta), "gamma1": m, "gamma2": m,
             **{i["name"]: i["width"] * m for i in ctx["plant_inputs"]},  # each plant input's numbers per actuator
             "quant_l": m, "sensor_res": max(ctx["n_sensed"], 1), "sensor_bias": max(ctx["n_sensed"], 1), "bias": n,
             **references.config_sizes(values),
             "xc_lo": max(n_xc, 1), "xc_hi": max(n_xc, 1), "slot": len(ctx["slots"]),
             # the arrays of the struct's own (each estimator's numbers), of their declared sizes
             **{f["name"]: _array_size(f["type"]) for g in ctx["config"] for f in g["fields"]
                if f["type"].startswith("double[")},
             "pred_theta": len(model.theta), "pred_gamma1": m, "pred_gamma2": m,
             "p_low": ctx["n_pressures"], "p_high": ctx["n_pressures"], "numbers": max(len(numbers), 1),
             "pred_x0": ctx["nx"]}
    for name, size in sizes.items():
        if np.size(values[name]) != size:
            raise InputError(f"loop configuration: {name} must hold {size} numbers, got {np.size(values[name])}")
    for name, size in (("pred_theta_at", len(model.theta)), ("pred_gamma1_at", m), ("pred_gamma2_at", m)):
        at = int(values[name])
        if at != -1 and not 0 <= at <= n_xc - size:
            raise InputError(f"loop configuration: {name} = {at} is outside the controller's state ({n_xc})")
    if int(values["n_xc"]) != n_xc:
        raise InputError(f"loop configuration: n_xc is {values['n_xc']}, the controller's state holds {n_xc}")
    for a in references.config_axes(values):
        if not float(a).is_integer() or not 0 <= int(a) < n:
            raise InputError(f"reference axis {a!r} is outside 0..{n - 1}; the C loop would index out of range")
    delay, frac = values["delay"], values["delay_frac"]
    if not (np.isfinite(frac) and 0 <= frac < 1 and 0 <= delay and delay + frac <= ctx["max_delay"]):
        raise InputError(f"delay must be 0..{ctx['max_delay']} control periods, got {delay} + {frac!r} periods")


class LoopRunner:
    """One configured closed loop: plant parameters, reference, sensors and a controller runtime.

    Parameters
    ----------
    dyn : Dynamics
        Compiled dynamics whose library holds the loop driver.
    ctrl : controller runtime from :func:`hydrogen.simulation.control.make_controller`
        Its static inputs (gains, bounds, θ for backstepping) are copied in once.
    values : dict
        A value for every field of :data:`hydrogen.layout.LOOP_CONFIG` that has a source, by field name
        (:func:`hydrogen.simulation.loop_config.config_values`); the controller's tables are this
        runner's. Each value is checked against its field's C type, and arrays the C loop indexes by the
        model's sizes against them, before any C runs.
    """

    def __init__(self, dyn, ctrl, values: dict):
        manifest = dyn.library.manifest
        self.context = ctx = _context(dyn.library)
        # each log's columns (None: the controller state's, its size)
        self._log_width = {r["name"]: r["width"] for r in log_rows(manifest["model"])}
        self.n_noise = ctx["n_noise"]
        Config, State, self._Log, self._Signals = _structs(ctx)
        name = ctx["model"]
        self._library = dyn.library
        self._run = dyn.library.symbol(f"{name}_loop_run")
        self._run.restype = C.c_int
        self._run.argtypes = [C.c_void_p, C.c_void_p, _LL, C.c_void_p, C.c_void_p]
        self._keep = []  # every array the C side points at stays alive with this object

        fn = ctrl.fn
        self.ctrl, self.fn = ctrl, fn
        # Static inputs: written once into the function's own buffers.
        fn.set_inputs({k: v for k, v in ctrl.values.items() if k in fn.in_names})
        _check_values(values, ctx, ctrl, dyn)
        cfg = Config()
        arrays = self._fill(cfg, ctx, values)
        tables = fn.c_tables()
        cfg.ctrl, cfg.ctrl_arg, cfg.ctrl_res = tables["fn"], tables["arg"], tables["res"]
        cfg.ctrl_iw, cfg.ctrl_w = tables["iw"], tables["w"]
        n_xc = ctrl.xc.size
        if n_xc:
            h = np.array([values["h"]])
            self._keep.append(h)
            self._step_tables(cfg, ctrl, tables, [h, arrays["xc_lo"], arrays["xc_hi"]])
        self.cfg = cfg
        self.state = State()
        self.xc = np.zeros(max(n_xc, 1))
        self.state.xc = _ptr(self.xc)
        self._cfg_ref, self._st_ref = C.byref(cfg), C.byref(self.state)

    def _fill(self, cfg, ctx, values) -> dict:
        """Every field with a source from ``values``, by its C type; returns the arrays the C side reads."""
        arrays = {}
        for g in ctx["config"]:
            for f in g["fields"]:
                if f["source"] is None:
                    continue
                name, ctype, v = f["name"], f["type"], values[f["name"]]
                if ctype == "double":
                    setattr(cfg, name, float(v))
                elif ctype == "long long":
                    setattr(cfg, name, int(v))
                elif ctype == "const double*":
                    arrays[name] = a = np.ascontiguousarray(v, dtype=float).copy()
                    self._keep.append(a)
                    setattr(cfg, name, _ptr(a))
                else:  # fixed-size arrays of the struct itself (double[<n>], slots)
                    getattr(cfg, name)[:] = [float(x) if ctype != "slots" else int(x) for x in np.ravel(v)]
        return arrays

    def _step_tables(self, cfg, ctrl, tables, extra):
        """The semi-implicit step's tables: its arguments are the controller's (the same buffers, which
        the loop writes) then h, xc_lo, xc_hi; its command result is the controller's u buffer."""
        if ctrl.step_fn is None:
            raise InputError(f"{ctrl.fn.name} has no generated semi-implicit step (dynamics of derived "
                             "functions alone); the C loop needs the compiled library's")
        step, fn = ctrl.step_fn.clone(), ctrl.fn  # a clone: its result table is redirected below
        n_in = len(fn.in_names)
        if step.in_names[:n_in] != fn.in_names or step.in_names[n_in:] != ["h", "xc_lo", "xc_hi"]:
            raise InputError(f"{step.name} does not take {fn.name}'s inputs then h, xc_lo, xc_hi; regenerate")
        # by the C tables' names: the controller's buffers (the description's numbers too), then h, xc_lo, xc_hi
        ctrl_arg = C.cast(tables["arg"], C.POINTER(C.c_void_p))
        own = dict(zip(("h", "xc_lo", "xc_hi"), (a.ctypes.data for a in extra)))
        step_arg = (C.c_void_p * len(step.arg_names))(
            *[own[a] if a in own else ctrl_arg[fn.arg_names.index(a)] for a in step.arg_names])
        st = step.c_tables()
        step_res = C.cast(st["res"], C.POINTER(C.c_void_p))
        step_res[0] = C.cast(tables["res"], C.POINTER(C.c_void_p))[0]  # u lands where the controller writes it
        self._keep += [step_arg, step]
        cfg.step, cfg.step_arg, cfg.step_res = st["fn"], C.cast(step_arg, C.c_void_p), st["res"]
        cfg.step_iw, cfg.step_w = st["iw"], st["w"]

    def reset(self, x0, q_meas0, l0, xc0):
        """Initial plant state, measured pose, each estimator's state at the lengths ``l0`` (m; its
        ``start``) and controller state."""
        st = self.state
        st.t, st.k = 0.0, 0
        st.x[:] = list(np.asarray(x0, float))
        st.q_meas[:] = list(np.asarray(q_meas0, float))
        for name in ESTIMATORS:  # each one's state, row after row as the C struct holds it
            mod = estimator(name)
            getattr(st, mod.STATE.name)[:] = list(np.ravel(mod.start(np.asarray(l0, float))))
        C.memset(st.u_hist, 0, C.sizeof(st.u_hist))
        C.memset(st.u_app, 0, C.sizeof(st.u_app))
        self.xc[: xc0.size] = xc0

    def run(self, n: int, noise=None, logs: dict | None = None) -> int:
        """Advance ``n`` periods; ``noise`` (≥ n, n_noise) or None; ``logs`` maps names to arrays with a row
        per period of the whole run (rows st.k … st.k + n − 1 are written).

        Shapes, dtype and layout are checked here, so the C code never writes or reads past an array.
        """
        n = int(n)
        if n < 0:
            raise InputError(f"n must be >= 0, got {n}")
        if noise is not None:
            if (noise.dtype != np.float64 or not noise.flags.c_contiguous or noise.ndim != 2
                    or noise.shape[1] != self.n_noise or noise.shape[0] < n):
                raise InputError(f"noise must be a C-contiguous float64 array of shape (>= {n}, {self.n_noise}), "
                                 f"got {noise.dtype} {noise.shape}")
        log = None
        if logs:
            log = self._Log()
            end = self.state.k + n
            for k, v in logs.items():
                if k not in self._log_width:
                    raise KeyError(f"unknown log '{k}'; logs are {', '.join(self._log_width)}")
                width = self._log_width[k] or self.xc.size
                if (v.dtype != np.float64 or not v.flags.c_contiguous or v.size < end * width
                        or (v.ndim == 2 and v.shape[1] != width)):
                    raise InputError(f"log '{k}' must be a C-contiguous float64 array with >= {end} rows "
                                     f"of {width}, got {v.dtype} {v.shape}")
                setattr(log, k, _ptr(v))
        nz = None if noise is None else noise.ctypes.data_as(C.c_void_p)
        return self._run(self._cfg_ref, self._st_ref, int(n), nz, None if log is None else C.byref(log))

    def stepper(self, noise):
        """A function ``step(k)`` advancing one period with noise row ``k`` of ``noise`` (checked once
        here; its rows must outlive the stepper): the cheapest call per period from Python."""
        if (noise.dtype != np.float64 or not noise.flags.c_contiguous or noise.ndim != 2
                or noise.shape[1] != self.n_noise):
            raise InputError(f"noise must be a C-contiguous float64 array of shape (k, {self.n_noise})")
        run, cfg, st, addr, row, rows = self._run, self._cfg_ref, self._st_ref, noise.ctypes.data, \
            noise.strides[0], noise.shape[0]
        self._keep.append(noise)

        def step(k):
            if not 0 <= k < rows:
                raise IndexError(f"noise row {k} outside the table's {rows} rows")
            return run(cfg, st, 1, addr + k * row, None)
        return step

    def stages(self):
        """The loop's stages as ctypes functions on this runner's configuration and state, for a program
        that composes its own period (``measure(nz)``, ``estimate()``, ``reference()``, ``control()``,
        ``plant_step()``, ``control_advance()``, each returning the C code; ``nz`` a noise row of
        ``n_noise`` numbers or None), and the :class:`Signals` structure they hand on
        (``signals``). One period of :meth:`run` is these calls in this order, then ``state.k += 1``."""
        lib, name = self._library, self.context["model"]
        sig = self._Signals()
        cfg, st, s = self._cfg_ref, self._st_ref, C.byref(sig)

        def fn(stage, *argtypes):
            f = lib.symbol(f"{name}_{stage}")
            f.restype, f.argtypes = (None if stage == "reference" else C.c_int), list(argtypes)
            return f

        vp = C.c_void_p
        measure, estimate = fn("measure", vp, vp, vp, vp), fn("estimate", vp, vp, vp)
        reference, control = fn("reference", vp, C.c_double, vp), fn("control", vp, vp, vp)
        plant_step, advance = fn("plant_step", vp, vp, vp, vp), fn("control_advance", vp, vp)

        def noise_row(nz):
            if nz is None:
                return None
            row = np.ascontiguousarray(nz, dtype=float)
            if row.shape != (self.n_noise,):
                raise InputError(f"a noise row holds {self.n_noise} numbers, got shape {row.shape}")
            Stages.row = row  # alive while the call reads it (only the current row is kept)
            return row.ctypes.data_as(vp)

        class Stages:
            signals, row = sig, None

            @staticmethod
            def measure(nz=None):
                return measure(cfg, st, noise_row(nz), s)

            @staticmethod
            def estimate():
                return estimate(cfg, st, s)

            @staticmethod
            def reference():
                reference(cfg, sig.t, C.cast(sig.qd, vp))

            @staticmethod
            def control():
                return control(cfg, st, s)

            @staticmethod
            def plant_step():
                return plant_step(cfg, st, C.cast(sig.u_held, vp), C.cast(sig.u_app, vp))

            @staticmethod
            def control_advance():
                return advance(cfg, st)
        return Stages

    @property
    def plant_state(self) -> np.ndarray:
        return np.array(self.state.x[:])
