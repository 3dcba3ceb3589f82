"""The list of functions derived for a model: names, symbolic inputs, expressions.

This is the single place where the derivation is assembled (acados style:
register everything, then code generation turns the whole list into C in one
pass). Each :class:`SymbolicFunction` holds SymPy symbols and expressions only.
Sizes come from the model: n coordinates, m cylinders (m = n), p adapted parameters.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import sympy as sp

from ..actuators import actuator, baked_parameters
from ..names import NUMBERS
from ..plant import FUNCTION as PLANT_FUNCTION, plant_layout
from ..plant.supply import PRESSURE
from ..pressures import blocks, n_pressures, uniform_three_way
from .body_functions import SymbolicFunction, rigid_body_functions  # noqa: F401 (also their public path)
from .constants import PRESSURE_EPS
from .kinematics import leg_stages, pose_symbols, rate_symbols
from .plant import plant_rhs

__all__ = ["SymbolicFunction", "SemiImplicitStep", "Specialisation", "derive_functions", "derive_parametric",
           "CORE_PARTS", "PLANT_PART",
           "with_numbers_input", "NUMBERS", "PRESSURE_EPS"]


@dataclass
class SemiImplicitStep:
    """The loop's semi-implicit period of a controller with a state, as one function:
    xc⁺ = clip(xc + h F(y, xc, u_applied), xc_lo, xc_hi), then u = U(y, xc⁺), where F is
    ``rates`` and U is ``controller``'s first output. Code generation composes it from the two
    (CasADi shares what depends on the measurement only: the kinematics, JL⁻ᵀ, the forces)."""

    name: str
    controller: SymbolicFunction
    rates: SymbolicFunction
    doc: str


@dataclass
class Specialisation:
    """``base`` (a :class:`SymbolicFunction`) with some input entries held constant and some output
    rows 0: the same inputs and outputs, and code generation folds the constants through (partial
    evaluation), so what only the fixed entries fed drops out. ``fixed``: ``(input, index, value)``,
    value a number or ``(input, index)`` of another input; ``zero``: ``(output, start, stop)``."""

    name: str
    base: SymbolicFunction
    fixed: list
    zero: list
    doc: str


def kinematics_functions(model) -> list:
    q = pose_symbols(model)
    l, JL, stages = leg_stages(model, q)
    return [
        SymbolicFunction("leg_lengths", [("q", q)], [("l", l)],
                         "Cylinder lengths l(q), m.", stages[:-1]),
        SymbolicFunction("leg_jacobian", [("q", q)], [("JL", JL)],
                         "JL = dl/dq (m x n).", stages),
        SymbolicFunction("leg_kinematics", [("q", q)], [("l", l), ("JL", JL)],
                         "Cylinder lengths l(q) (m) and JL = dl/dq together (one Newton step of forward "
                         "kinematics).", stages),
    ]


def hydraulic_functions(model) -> list:
    """The actuator laws as functions over the pressure vector ``pc`` (one block per actuator,
    :mod:`hydrogen.pressures`). A robot of three-way cylinders only keeps eq. (57)'s flow q_l/c and its
    inverse; any other gets the per-state valve flows and the inverse of g0 (its kind's laws)."""
    m, n_p = model.n_cylinders, n_pressures(model)
    u, l, ld, wq = (rate_symbols(k, m) for k in ("u", "l", "ldot", "w"))
    pc = rate_symbols("pc", n_p)
    p = [tuple(pc[a:b]) for a, b in blocks(model)]
    g1, g2 = rate_symbols("gamma1", m), rate_symbols("gamma2", m)
    kinds = [actuator(c.kind) for c in model.cylinders]
    P = [baked_parameters(c) for c in model.cylinders]
    laws = [k.Symbolic for k in kinds]
    # Plant: ṗ with q = c · (unit flow), c = γ2/γ1, β = γ1, orifice linearised near Δp = 0.
    rate = sp.Matrix([r for i in range(m)
                      for r in laws[i].pressure_rates(l[i], ld[i], p[i], u[i], g1[i], g2[i] / g1[i], P[i], smooth=True)])
    # With a supply state the forces take its pressure as an input: a three-way cylinder's rod side is
    # at the supply's pressure, not at the nominal one (a constant supply keeps today's function).
    ps_in = [] if model.supply.constant else [(PRESSURE, rate_symbols(PRESSURE, 1))]
    PF = [{**Pi, "supply_pressure": ps_in[0][1][0]} for Pi in P] if ps_in else P
    force = sp.Matrix([laws[i].force(p[i], PF[i]) for i in range(m)])
    # one valve pair for every kind: flow per pressure state, and the spool that gives the force loop's g0
    flow = sp.Matrix([q for i in range(m) for q in laws[i].valve_flows(u[i], p[i], P[i])])
    inv = sp.Matrix([laws[i].valve_inverse(wq[i], l[i], p[i], P[i], PRESSURE_EPS) for i in range(m)])
    valve = [
        SymbolicFunction("valve_flow", [("u", u), ("pc", pc)], [("q_per_c", flow)],
                         "Valve flow per unit flow gain into each pressure state's chamber, m sqrt(Pa) "
                         "(the kind's law, drops clipped at 0; q_l / c of (57) for a three-way cylinder)."),
        SymbolicFunction("valve_inverse", [("g0", wq), ("l", l), ("pc", pc)], [("u", inv)],
                         "Spool position u (m) with g0(l, p, u) = g0 per actuator (the kind's valve inverse; "
                         "(57) inverted at q_l / c = g0 (l - L) for a three-way cylinder)."),
    ]
    if uniform_three_way(model):
        rate_doc, force_doc = "Control-chamber pressure rate (56)-(57)", "f = pc A - ps a, N."
    else:
        rate_doc, force_doc = "Chamber pressure rates", "Actuator forces from the pressures (the kinds' laws), N."
    return [
        *valve,
        SymbolicFunction("pressure_rate", [("l", l), ("ldot", ld), ("pc", pc), ("u", u), ("gamma1", g1),
                                           ("gamma2", g2)], [("pc_dot", rate)],
                         f"{rate_doc} of the simulated plant, Pa/s "
                         "(orifice law linear below orifice_linear_below)."),
        SymbolicFunction("leg_force", [("pc", pc), *ps_in], [("f", force)],
                         force_doc + (" ps: the supply pressure state, Pa." if ps_in else "")),
    ]


def plant_functions(model) -> list:
    inputs, xdot, intermediates = plant_rhs(model)
    size = "2n + 3m" if uniform_three_way(model) else "2n + pressures + 2m"
    parts = ", ".join(s.label for s in plant_layout(model))
    return [SymbolicFunction(PLANT_FUNCTION, inputs, [("xdot", xdot)],
                             f"Plant state rate: x = [{parts}] ({size}), SI units; valve = [lag s, natural frequency rad/s, damping, overlap m, full opening m] per actuator.", intermediates)]


def controller_functions(model, kinds=None) -> list:
    """Each controller (of ``kinds``, in the registry's order; None: those ``model`` lists); and, for a controller with a state, its rates-only function: the same inputs
    (so one argument table serves both) and the output ``xc_dot`` alone, from which CasADi keeps only
    what the rates need (no τ̇_d, ḟ_d, v or valve inverse): the loop's semi-implicit state update;
    and its semi-implicit step. A controller with the composite adaptation's blocks gets the three
    again as its lean variant (:func:`hydrogen.controllers.common.lean_variant`): the composite
    rates fixed at 0, what the paper's law computes and no more."""
    from ..controllers import CONTROLLERS, LEAN, controller, function_name, rates_function_name, step_function_name
    from ..controllers.common import lean_variant

    out = []
    listed = model.controllers if kinds is None else kinds
    for name in CONTROLLERS:
        if name not in listed:
            continue
        mod = controller(name)
        parts = mod.derive(model)
        full = SymbolicFunction(function_name(name), parts.inputs, parts.outputs, mod.DOC, parts.intermediates)
        out.append(full)
        rates = [(k, v) for k, v in parts.outputs if k == "xc_dot"]
        if not rates:
            continue
        rates = SymbolicFunction(rates_function_name(name), parts.inputs, rates,
                                 f"{mod.DOC} State rates xc_dot only (same inputs).", parts.intermediates,
                                 selects=full.name)
        step_doc = "Semi-implicit period: state xc+ = clip(xc + h xc_dot), command u at xc+."
        out += [rates, SemiImplicitStep(step_function_name(name), full, rates, f"{mod.DOC} {step_doc}")]
        lean = lean_variant(mod.state_layout(model))
        if lean is not None:
            doc = f"{mod.DOC} Lean: the composite adaptation left out (its rates 0, its states held)."
            lc = Specialisation(function_name(name, LEAN), full, doc=doc, **lean)
            lr = Specialisation(rates_function_name(name, LEAN), rates, doc=f"{doc} State rates xc_dot only.", **lean)
            out += [lc, lr, SemiImplicitStep(step_function_name(name, LEAN), lc, lr, f"{doc} {step_doc}")]
    return out


#: The core's parts, in the order they are derived and listed: (name, the model's functions of it).
#: The plant's part is derived from the plant's blocks (hydrogen/plant) and may be derived again alone.
CORE_PARTS = (("kinematics", kinematics_functions), ("rigid_body", rigid_body_functions),
              ("hydraulics", hydraulic_functions), ("plant", plant_functions))
#: The core part derived from the plant's blocks.
PLANT_PART = "plant"


def derive_functions(model, controllers=True, core=True, on_part=None) -> list:
    """Every function generated for ``model``, in a fixed order: the core's (:data:`CORE_PARTS`:
    kinematics, rigid body, hydraulics, plant; ``core``: True for all, False for none, or the names
    of some), then the controllers' (``controllers``: True for those ``model`` lists, False for
    none, or the names of some). ``on_part(name)`` is called after each core part is derived."""
    wanted = [name for name, _ in CORE_PARTS] if core is True else [] if core is False else list(core)
    unknown = sorted(set(wanted) - {name for name, _ in CORE_PARTS})
    if unknown:
        raise ValueError(f"derive_functions: no core part {', '.join(unknown)}")
    funcs = []
    for name, part in CORE_PARTS:
        if name in wanted:
            funcs += part(model)
            if on_part is not None:
                on_part(name)
    if controllers is False:
        return funcs
    return funcs + controller_functions(model, None if controllers is True else tuple(controllers))




def with_numbers_input(f, vector) -> SymbolicFunction:
    """``f`` taking the description's numbers (the column ``vector`` of their symbols, a
    :class:`~hydrogen.symbolic.constants.NumberTable`'s) as one more input, :data:`NUMBERS`."""
    return dataclasses.replace(f, inputs=[*f.inputs, (NUMBERS, vector)])


def derive_parametric(model, controllers=True, key: str = "name", core=True, seed=None, tail=(),
                      marks=None) -> tuple:
    """(functions, names, values): :func:`derive_functions` with the description's numbers left as
    symbols (:func:`~hydrogen.symbolic.constants.numbers_as_symbols`), each :class:`SymbolicFunction`
    taking them as one more input, :data:`NUMBERS` (the same vector for all, the numbers in the order
    the derivation met them); ``names`` of its entries (``key`` "name": those of
    ``model.numbers()``), ``values`` the description's. The specialisations and steps are made of
    the parametric functions, so they take the input too. ``controllers`` and ``core``: as for
    :func:`derive_functions`. ``seed``: names of numbers to enter first, in order (the vector of
    functions derived before, which functions derived now must share); a number met that is not
    among them is appended (the caller sees ``names`` grow). ``tail``: names entered after the
    derivation, those it did not meet (the rest of a vector a function derived again alone must
    take whole). ``marks``: a dict given is filled with the count of numbers met by the end of each
    core part derived (:data:`CORE_PARTS`), ``seed`` included."""
    from .constants import numbers_as_symbols

    with numbers_as_symbols(key) as table:
        values = model.numbers() if seed or tail else None
        for name in seed or ():
            table.symbol(values[name], name)
        on_part = None if marks is None else (lambda part: marks.__setitem__(part, len(table.symbols)))
        funcs = derive_functions(model, controllers, core, on_part)
        for name in tail:
            table.symbol(values[name], name)
    vector = sp.Matrix(table.symbols)
    made = {}

    def parametric(f):
        if f.name in made:
            return made[f.name]
        if isinstance(f, SymbolicFunction):
            g = with_numbers_input(f, vector)
        elif isinstance(f, Specialisation):
            g = Specialisation(f.name, parametric(f.base), f.fixed, f.zero, f.doc)
        else:
            g = SemiImplicitStep(f.name, parametric(f.controller), parametric(f.rates), f.doc)
        made[f.name] = g
        return g

    return [parametric(f) for f in funcs], list(table.names), list(table.values)
