"""What a controller declares about itself, once (numpy-free plain data).

The loop, the documented gain search, the figures and the command line read these fields
instead of testing a controller's name; a new controller states them in its module as ``SPEC``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ControllerSpec", "StateBlock", "Start", "POSITION_BOUND", "VELOCITY_BOUND"]

#: |position estimate| (m or rad) past which an observer has left the robot: no hydraulic joint
#: travels a thousand metres or radians (160 turns).
POSITION_BOUND = 1.0e3
#: |velocity estimate| (m/s or rad/s) past which an observer has left the robot: a hydraulic joint
#: moves at a few m/s or rad/s at most.
VELOCITY_BOUND = 1.0e3


@dataclass(frozen=True)
class ControllerSpec:
    """A controller's contract beyond its gains, state layout and derivation.

    name : str
        The user-facing name (``hydrogen simulate --controller NAME``).
    doc : str
        One line: what it is (the paper's theorem, the baseline).
    main_gain : str
        The gain the documented search scales (``hydrogen tune``) and the stability margin is
        measured on.
    main_gain_symbol : str
        How tables and figures write the main gain (the paper's symbol, e.g. "Λ"); empty: its name.
    grid_low : float
        The documented search's first main-gain value (in the gain's own unit); the grid runs
        six octaves up from it.
    main_gain_shared : bool
        True: one value of the main gain for every entry (the search sets it whole); False: the
        search scales the defaults, keeping their proportions across coordinates.
    secondary_search : bool
        Whether the search also varies K_d/K_p (by octaves) and K_τ with the main gain.
    knows_true_parameters : bool
        Runs with the true θ and γ (no estimation): a scenario's wrong initial estimates do not apply.
    baseline : bool
        The fixed-gain comparison the nonlinear controllers are measured against (the paper's P).
    compared : bool
        One of the fixed-gain controllers the nonlinear ones are compared with (the figures take the
        better of them on each scenario); the baseline is one.
    search_description_proportions : bool
        The search scales the main gain as the robot's description gives it (per-axis proportions a
        robot chooses), not the controller's uniform defaults.
    adaptation_search : tuple
        ``((gain, how, values), ...)``: the gains the search's second stage tries one at a time, at
        the point the main and secondary search chose (adaptation rates, observer gains), each over
        its values: ``how`` "=" values in the gain's own unit (NaN: the controller's rule for it),
        "x" factors of the robot's own value. Empty: no second stage.
    rank : float
        Where it comes among the controllers (generation order, listings, the command line's
        choices): the shipped ones 0 to 4; a new one leaves it at inf and comes after them, by
        module name.
    """

    name: str
    doc: str
    main_gain: str
    grid_low: float
    main_gain_symbol: str = ""
    main_gain_shared: bool = False
    secondary_search: bool = True
    knows_true_parameters: bool = False
    baseline: bool = False
    compared: bool = False
    search_description_proportions: bool = False
    adaptation_search: tuple = ()
    rank: float = math.inf

    @property
    def main_gain_label(self) -> str:
        """The main gain as tables write it: :attr:`main_gain_symbol`, else its name."""
        return self.main_gain_symbol or self.main_gain

    @property
    def command_gains(self) -> tuple:
        """The gains that set how hard it drives the valves, to lower when they saturate: the main
        gain, and K_d and K_τ where the search varies them with it."""
        return (self.main_gain, *(("Kd", "Ktau") if self.secondary_search else ()))


@dataclass(frozen=True)
class Start:
    """What a state block's initial value is made from at the start of a run (SI).

    q0, qdot0
        The pose (m or rad per coordinate) and its rate.
    theta0, gamma0
        The initial parameter estimates: θ0 (p) and γ0 (2, m) as [β, β c] per actuator.
    l0
        The actuator lengths (or angles) at q0, l(q0).
    pc0
        The pressure states at the start (Pa).
    gains
        The controller's gains and numeric inputs, by name.
    """

    q0: object
    qdot0: object
    theta0: object
    gamma0: object
    l0: object
    pc0: object
    gains: dict


@dataclass(frozen=True)
class StateBlock:
    """A block of a controller's state xc, as ``state_layout`` declares it; unpacks as the pair
    ``(name, size)``.

    name, size
        The block and its number of entries.
    role : str
        What it is, for a message: "the adaptive observer's velocity estimate (z / q_hat_dot)".
    lower : str
        What to lower when it diverges: "its gains (Lambda, Kd_obs) or the adaptation rates (...)".
    bound : float
        |entry| past which the run has diverged, in the block's own unit (inf: a non-finite value
        only; an estimate's projection bounds hold it anyway). The first block of a diverged run's
        state to go non-finite or past its bound is named with its role and what to lower.
    initial : number or callable
        Its value at the start of a run: one number for every entry, or a rule taking the run's
        :class:`Start` and giving the entries (or one number for all).
    limits : (low, high)
        The projection the loop keeps every entry inside (both loops clip the state to it each
        period), in the block's own unit: each a number (one for all entries or one per entry), a
        name, the controller's gain of that name, else the model's attribute (``"theta_min"``), or a
        rule taking the model and the gains (``lambda model, gains: -gains["d_max"]``).
    unit : str, callable or None
        The unit of its entries as the FMU and the logs show it (FMI spelling: "Pa", "m/s"): one for
        every entry, or a rule taking the model and giving one per entry; None: not declared.
    entries : str
        What its entries are, to name them: "coordinates", "actuators" or "parameters" (θ's), one
        entry each; "" (numbered from 1).
    """

    name: str
    size: int
    role: str
    lower: str
    bound: float = math.inf
    initial: object = 0.0
    limits: tuple = (-math.inf, math.inf)
    unit: object = None
    entries: str = ""

    def initial_value(self, start: Start):
        """Its entries at the start of a run (a number or a sequence; the caller fills the block)."""
        return self.initial(start) if callable(self.initial) else self.initial

    def units(self, model) -> list:
        """The unit of each entry (None where it is not declared)."""
        unit = self.unit(model) if callable(self.unit) else [self.unit] * self.size
        return list(unit)

    def entry_names(self, model) -> list:
        """A name per entry: the model's coordinate, actuator or parameter names (:attr:`entries`), else
        ``"[1]"``, ``"[2]"``, … (numbered from 1)."""
        names = {"coordinates": lambda: model.coordinate_names, "actuators": lambda: [c.name for c in model.cylinders],
                 "parameters": lambda: model.theta_names}.get(self.entries)
        names = list(names()) if names else []
        return names if len(names) == self.size else [f"[{i + 1}]" for i in range(self.size)]

    def limit_values(self, model, gains: dict) -> tuple:
        """(low, high) of :attr:`limits` for ``model`` and the controller's ``gains`` (numbers or sequences)."""
        return tuple(v(model, gains) if callable(v) else (gains[v] if v in gains else getattr(model, v))
                     if isinstance(v, str) else v for v in self.limits)

    def __iter__(self):  # the layout's (name, size) pairs: ``for name, size in state_layout(model)``
        return iter((self.name, self.size))
