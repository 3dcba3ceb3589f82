"""Controller runtimes: bind gains and state to a generated controller and step it at a fixed rate.

Every controller has the same contract, so the loop treats them alike: per control period,
``update(h, meas, ref, adapt)`` (the semi-implicit update: the state of this period from the
rate at this period's measurement, the previous state and the command the valves held over the
last period, kept inside the projection bounds; the rates-only generated function), then
``command(meas, ref, adapt) -> u`` with the updated state, then ``applied(u_app)`` with the
command the valves get this period (after the computation delay). The forward-Euler variant
(scenario ``estimator_update = "euler"``) calls ``command``, ``applied``, then ``advance(h)``. What differs
between controllers (state layout, default gains, numeric inputs made once) comes from the
controller's module in :mod:`hydrogen.controllers`.
"""
from __future__ import annotations

import numpy as np

from ..controllers import (COMMON_GAINS, CONTROLLERS, LEAN, controller as controller_module, function_name,
                           gain_names, rates_function_name, step_function_name)
from ..controllers.common import check_coupling_gains, normalised_adaptation, runs_lean
from ..controllers.spec import Start
from .. import diagram, pressures
from ..plant import supply
from ..errors import ScenarioError
from ..layout import model_summary, plant_ports, robot_sizes
from ..names import NUMBERS
from .checks import check_gain_values

__all__ = ["make_controller", "default_gains", "CONTROLLERS", "gain_scale", "COMMON_GAINS", "gain_names"]

def gain_scale(dyn) -> np.ndarray:
    """Per-coordinate inertia scale of the default gains: the model's ``[control] scale``, else the
    diagonal of D at the neutral pose with the true parameters."""
    m = dyn.model
    if m.scale is not None:
        return np.asarray(m.scale, float)
    return np.abs(np.diag(dyn.mass_matrix(m.neutral_pose, m.theta))).copy()


def default_gains(dyn, kind) -> dict:
    """Gains of controller ``kind`` for ``dyn``'s model: the controller's defaults, then the model's
    ``[gains.common]`` (for the gains the controller has) and ``[gains.<kind>]``."""
    return _default_gains(dyn, kind, {})


def _default_gains(dyn, kind, origin: dict) -> dict:
    """:func:`default_gains`, writing into ``origin`` where each gain the description set came from."""
    mod = controller_module(kind)
    g = mod.default_gains(dyn.model, gain_scale(dyn))
    model_gains = dyn.model.gains or {}
    for table in (COMMON_GAINS, kind):
        for k, v in (model_gains.get(table) or {}).items():
            if table == COMMON_GAINS and k not in g:
                continue
            origin[k] = f"{dyn.model.source}: [gains.{table}]"
            g[k] = _checked(kind, g, k, v, origin[k], dyn.model)
    return g


def _sizes(model, size: int) -> str:
    """"6 values (n = m = 6)": ``size`` and the model's counts it equals (n coordinates, m actuators,
    p θ parameters)."""
    names = [k for k, c in (("n", model.n), ("m", model.n_cylinders), ("p", model.n_theta)) if c == size]
    return f"{size} value{'s' * (size != 1)}" + (f" ({' = '.join(names)} = {size})" if names else "")


def _checked(kind, g, k, v, where, model):
    """Gain ``k`` of controller ``kind`` from ``v``: a scalar applies to every entry; a list must hold
    exactly the default's entries (never broadcast: [900.0] for three actuators is a typo, not 900 each)."""
    if k not in g:
        raise ScenarioError(f"{where}: controller '{kind}' has no gain '{k}'; it has {sorted(g)}")
    shape = np.shape(g[k])
    try:
        if np.asarray(v).dtype == bool:  # True is no gain of 1 (a switch given where a number belongs)
            raise ValueError
        value = np.asarray(v, float)
        if value.ndim and value.shape != shape:
            raise ValueError
        value = np.broadcast_to(value, shape).copy()
    except (TypeError, ValueError):
        raise ScenarioError(f"{where}: controller '{kind}': gain '{k}' needs {_sizes(model, int(np.prod(shape)))} "
                            f"(or one scalar for all), got {v!r}") from None
    if not np.all(np.isfinite(value)):
        raise ScenarioError(f"{where}: controller '{kind}': gain '{k}' must be finite, got {v!r}")
    return value


def _gains(dyn, kind, overrides, origin: dict, sources: dict):
    g = _default_gains(dyn, kind, origin)
    for k, v in (overrides or {}).items():
        origin[k] = sources.get(k, "gains")
        g[k] = _checked(kind, g, k, v, origin[k], dyn.model)
    return g


class _Controller:
    def __init__(self, dyn, kind, gains, theta0, gamma0, model):
        self.kind = kind
        #: the generated variant run: the lean one (no composite terms) when the composite rates are 0
        #: and the dynamics have it (those of the derived functions alone may not)
        self.variant = LEAN if runs_lean(gains) and function_name(kind, LEAN) in dyn.functions else None
        # Buffers of its own: runners, steppers and threads sharing one library never see each other's gains.
        self.fn = dyn.functions[function_name(kind, self.variant)].clone()
        self.values = dict(gains)
        self.layout = controller_module(kind).state_layout(model)
        self.model = model
        self.leg_lengths = dyn.leg_lengths  # l(q0) for the composite law's copy of the last length
        self.theta0, self.gamma0 = np.asarray(theta0, float), np.asarray(gamma0, float)
        self.xc = np.zeros(sum(n for _, n in self.layout))
        self.xc_dot = np.zeros_like(self.xc)
        # the state's rates alone (same inputs as fn): the semi-implicit update calls it, not fn; looked
        # up on first use (rates_fn), so a run of the C loop never compiles its library
        self._functions = dyn.functions
        self._rates_fn = None
        # the C loop's semi-implicit period in one call (rates, clip, command): for the loop runner
        # (composed at generation: dynamics made of derived functions alone, e.g. the benchmarks'
        # lambdify and CasADi routes of the Python loop, have none; the C loop runner requires it)
        step = dyn.functions.get(step_function_name(kind, self.variant)) if self.xc.size else None
        self.step_fn = step.clone() if step is not None else None
        #: spool commands the valves held over the last period, m (the γ̂2 law's u_applied)
        self.u_applied = np.zeros(model.n_cylinders)
        self.slices, i = {}, 0
        for name, n in self.layout:
            self.slices[name] = slice(i, i + n)
            i += n
        m = model
        if "theta_min" in self.fn.in_names:
            self.values.update(theta_min=m.theta_min, theta_max=m.theta_max,
                               gamma1_min=np.array([m.gamma1_min]), gamma1_max=np.array([m.gamma1_max]),
                               gamma2_min=np.array([m.gamma2_min]), gamma2_max=np.array([m.gamma2_max]))
        # each block's projection, as it declares it (its gains' or the model's ranges, or numbers)
        lo, hi = np.full(self.xc.size, -np.inf), np.full(self.xc.size, np.inf)
        for block in self.layout:
            lo[self.slices[block.name]], hi[self.slices[block.name]] = block.limit_values(m, self.values)
        self.bounds = (lo, hi)
        # Every input is wired: to the loop's signal of its name, of the size the robot gives it, or to a
        # value given once (a gain no table gives would otherwise be a KeyError in the Python loop and a
        # silent 0 in the C loop). The slots index the C argument table (the description's numbers too).
        shapes = dict(zip(self.fn.in_names, self.fn.in_shapes))
        summary = model_summary(m)
        self.slots = diagram.wire(f"controller '{kind}'", [(k, int(np.prod(shapes[k])) if k in shapes else 0)
                                                           for k in self.fn.arg_names],
                                  set(self.values) | {NUMBERS}, robot_sizes(summary), plant_ports(summary))
        #: the plant's outputs it reads by name (a rig part's state: hydrogen.layout.plant_ports), which
        #: every call's signals must give (never a value left from an earlier call)
        self.plant_reads = tuple(pp.name for pp in plant_ports(summary) if pp.name in self.fn.in_names)
        self.tau_d = np.zeros(m.n)
        self.tau_d_dot = np.zeros(m.n)
        self.f_d = np.zeros(m.n_cylinders)

    def part(self, name):
        s = self.slices.get(name)
        return None if s is None else self.xc[s]

    def offset(self, name) -> int:
        """Where state block ``name`` starts in :attr:`xc`, or -1 if the controller has none."""
        s = self.slices.get(name)
        return -1 if s is None else s.start

    def own_parameters(self):
        """(θ, γ1, γ2) of the controller's own model: its estimates where it adapts them, else the
        initial (known) values; SI, γ1 = β and γ2 = β c per cylinder."""
        th, g1, g2 = (self.part(b) for b in ("theta_hat", "gamma1_hat", "gamma2_hat"))
        return (self.theta0 if th is None else th, self.gamma0[0] if g1 is None else g1,
                self.gamma0[1] if g2 is None else g2)

    def reset(self, q0, qdot0, pc0=None):
        """The state at the start: each block at the initial value it declares (estimates at θ0, γ0,
        observers at (q0, q̇0), …) from q0, q̇0, l(q0) and ``pc0`` (Pa; default the middle of each
        pressure state's range, half the supply pressure for three-way cylinders)."""
        if self.layout:
            if pc0 is None:
                lo, hi = pressures.bounds(self.model)
                pc0 = 0.5 * self.model.supply_pressure if pressures.uniform_three_way(self.model) else (lo + hi) / 2
            start = Start(q0=np.asarray(q0, float), qdot0=np.asarray(qdot0, float), theta0=self.theta0,
                          gamma0=self.gamma0, l0=np.asarray(self.leg_lengths(q0), float).ravel(),
                          pc0=np.asarray(pc0, float), gains=self.values)
            for block in self.layout:
                self.xc[self.slices[block.name]] = block.initial_value(start)
        self.u_applied[:] = 0.0

    def _signals(self, signals: dict):
        """Write the loop's ``signals`` (by port name, :func:`hydrogen.diagram.signals`) into the inputs."""
        missing = [name for name in self.plant_reads if name not in signals]
        if missing:
            raise ScenarioError(f"controller '{self.kind}' reads the plant's {', '.join(missing)}: give "
                                f"{'it' if len(missing) == 1 else 'them'} with the signals (command(..., "
                                "plant={name: value}), or by name in command_for's signals)")
        v = self.values
        v.update(signals)
        # a copy of u_applied: the spool held over the period ending at this measurement, also for the
        # forward Euler update after this period's command is applied (as the C loop's input slot)
        v.update(adapt=np.array([float(signals["adapt"])]), xc=self.xc, u_applied=self.u_applied.copy())
        return v

    @property
    def rates_fn(self):
        """The generated function of the state's rates alone (None without a state), loaded (and, the first
        time, compiled) on first use."""
        if self._rates_fn is None and self.xc.size:
            self._rates_fn = self._functions[rates_function_name(self.kind, self.variant)].clone()
        return self._rates_fn

    def _rates(self):
        """F(measurement, xc, u_applied) at the signals last written into ``values``."""
        v = self.values
        v.update(xc=self.xc)
        return self.rates_fn(*[v[n] for n in self.rates_fn.in_names])

    def _supply(self, ps):
        """The ``ps`` signal of the wrappers: the given supply pressure (Pa), else the description's
        nominal one where the controller reads a supply (a robot whose supply is a state), else None."""
        if ps is not None or supply.PRESSURE not in self.fn.in_names:
            return ps
        return np.array([supply.nominal(self.model)], float)

    def command(self, q, qdot, pc, l, ref, adapt, ps=None, plant=None):
        """The spool commands (m) for the measured pose ``q``, velocities ``qdot``, pressures ``pc``, travel
        ``l``, reference ``ref`` (4 rows), the adaptation switch, the supply pressure ``ps`` (Pa; default
        the description's nominal one) and ``plant``, the rig parts' states it reads by name
        (:attr:`plant_reads`): :meth:`command_for` their ports."""
        return self.command_for({**diagram.signals(q, qdot, pc, l, ref, adapt, self._supply(ps)), **(plant or {})})

    def command_for(self, signals: dict):
        """The spool commands (m) for the loop's signals by port name (:data:`hydrogen.diagram.SLOTS`)."""
        v = self._signals(signals)
        out = self.fn(*[v[n] for n in self.fn.in_names])
        if not isinstance(out, tuple):
            return out
        u = out[0]
        if self.xc.size:
            self.xc_dot = out[1]
        self.tau_d, self.tau_d_dot, self.f_d = out[-3], out[-2], out[-1]
        return u

    def applied(self, u_app):
        """Record the spool commands (m) the valves get this period: the next state update's u_applied."""
        self.u_applied[:] = u_app

    def update(self, h, q, qdot, pc, l, ref, adapt, ps=None, plant=None):
        """:meth:`update_for` the signals of a measured pose, velocities, … (as :meth:`command`)."""
        self.update_for(h, {**diagram.signals(q, qdot, pc, l, ref, adapt, self._supply(ps)), **(plant or {})})

    def update_for(self, h, signals: dict):
        """Semi-implicit step: xc ← clip(xc + h F(measurement, xc, u_applied)) with the rates-only
        function (the C loop's "controller state" block), for the loop's ``signals`` by port name."""
        if self.xc.size:
            self._signals(signals)
            np.clip(self.xc + h * self._rates(), *self.bounds, out=self.xc)

    def advance(self, h):
        """Forward Euler: the rate the last command's call gave (its measurement, state and
        u_applied, the spool the valves held over the period that ended at that measurement)."""
        if self.xc.size:
            np.clip(self.xc + h * self.xc_dot, *self.bounds, out=self.xc)


def make_controller(dyn, kind, gains=None, theta0=None, gamma0=None, period=None, sources=None):
    """A controller runtime of ``kind`` (one of :data:`CONTROLLERS`) for compiled dynamics ``dyn``.

    ``theta0``/``gamma0`` are the initial estimates (the known values for ``backstepping``);
    ``gamma0`` has shape (2, m): [β, βc] per cylinder. ``period``: the control period h (s) the
    state is updated at (the composite adaptation copies signals from one period to the next);
    a run passes its own, 1 ms otherwise. ``sources``: where gains of ``gains`` came from, by name
    (e.g. the scenario's table), for the messages about them; ``gains`` otherwise.
    """
    if kind not in CONTROLLERS:
        raise ScenarioError(f"unknown controller '{kind}'; choose one of {', '.join(CONTROLLERS)}")
    model = dyn.model
    if kind not in model.controllers:
        raise ScenarioError(model.not_listed(kind))
    if function_name(kind) not in dyn.functions:  # a build for some controllers only
        held = [k for k in CONTROLLERS if function_name(k) in dyn.functions]
        raise ScenarioError(f"controller '{kind}' is not in this build of '{model.name}' (it holds "
                            f"{', '.join(held) or 'no controller'}); build with hydrogen.build(model, "
                            f"controllers=[..., '{kind}']), or with no controllers named for all")
    theta0 = model.theta if theta0 is None else np.asarray(theta0, float)
    gamma0 = model.gamma if gamma0 is None else np.asarray(gamma0, float)
    origin = {}  # where a gain set by the description or the caller came from, for the messages
    g = _gains(dyn, kind, gains, origin, sources or {})
    mod = controller_module(kind)
    if hasattr(mod, "complete_gains"):  # gains derived from others (e.g. the robust observer's K_o from Λ, K_d)
        try:
            g = mod.complete_gains(g, gain_scale(dyn))
        except ValueError as exc:
            raise ScenarioError(f"controller '{kind}': {exc}") from None
    g = normalised_adaptation(model, g, theta0, gamma0)  # Γ⁻¹ from the rates where not given raw
    try:
        check_coupling_gains(model, g)
    except ValueError as exc:
        raise ScenarioError(f"{model.source}: controller '{kind}': {exc}") from None
    check_gain_values(kind, g, origin)
    g.update(mod.static_inputs(dyn, theta0, gamma0))
    g["period"] = np.array([1.0e-3 if period is None else float(period)])
    # The explicit update keeps the least-squares gain positive definite only while k h < 1, and a
    # filter λ_f/(s + λ_f) stable and monotone only while λ_f h < 1.
    for k in ("rate_ls_gamma", "lambda_f_gamma", "rate_ls_theta", "lambda_f_theta"):
        if k in g and float(np.asarray(g[k]).ravel()[0]) * g["period"][0] >= 1.0:
            where = f"{origin[k]}: " if k in origin else ""
            raise ScenarioError(f"{where}controller '{kind}': gain '{k}' = {float(np.asarray(g[k]).ravel()[0]):g} "
                                f"must be below 1/h = {1.0 / g['period'][0]:g} (the control rate)")
    return _Controller(dyn, kind, g, theta0, gamma0, model)
