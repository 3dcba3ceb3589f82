"""The paper's actuator: a cylinder on a three-way valve, rod side at supply pressure (eqs. (56)-(59)).

Control chamber (cap side, area A = ``piston_area``) at pressure p_c, the only state; the rod side
(annulus area a = ``rod_area``: the piston's area on the rod side, not the rod's own section) is
held at the supply pressure P_s. Force f = p_c A − P_s a (N, positive extends the cylinder). The
valve meters the control chamber from supply and to the tank at 0 Pa (gauge), eq. (57):

    q_l / c = (u + d) √(P_s − p_c) [u ≥ −d] + (u − d) √p_c [u ≤ d]   (spool u, underlap d in m).

Chamber volume convention (the paper's choice of q and l in (58)): V(l) = A (l − L), l the cylinder
length pin to pin (m) and L the ``chamber_length``, smaller than the shortest length so V stays
positive. Then (56), V_t/β ṗ_c = q_l + c_l (P_s − p_c) − V̇_t, with c_l = ``leakage`` (m³/(s Pa), the
total leakage into the control chamber from the rod side at supply; default 0, the paper's c_l ≈ 0)
gives

    ṗ_c = β (q_l + c_l (P_s − p_c) − A l̇) / (A (l − L)),   ḟ = A ṗ_c = β f0 + βc g0,
    f0 = (−A l̇ + c_l (P_s − p_c)) / (l − L),   g0 = (q_l / c) / (l − L)   (59).

The leakage is a known function of the measured p_c times β, so it joins f0 (the controllers know it
as they know A and L) and (59) stays linear in γ = [β, βc]; for c_l = 0, (58)-(59) as printed. A
leakage of 0 is structure (an exact 0 in the derivation): the laws are then the expressions they were.

Every law has the uniform signature of :mod:`hydrogen.actuators` (``x`` the length l, ``xdot`` l̇,
``p`` the tuple of chamber pressures ``(p_c,)``, ``P`` the parameters by name); :class:`Symbolic`
gives SymPy expressions, :class:`Numeric` their numpy twins (tested equal).
"""
from __future__ import annotations

import numpy as np

from . import orifices as orf
from .declarations import (AREA, BULK_MODULUS, CHAMBER_LENGTH, FLOW_GAIN, LEAKAGE, LENGTH, ORIFICE_LINEAR_BELOW, SUPPLY_PRESSURE,
                           UNDERLAP, Parameter, Sensor, State, readers, sp)

__all__ = ["NAME", "DOC", "MOTION", "TRAVEL", "COUPLING_GAIN", "STATES", "PARAMETERS", "SENSORS", "Symbolic", "Numeric",
           "parameters", "stacked"]

NAME = "three_way_cylinder"
DOC = "Cylinder on a three-way valve, rod side at supply pressure (the paper's eqs. (56)-(59))."
#: The coordinate the actuator moves: its length l (m), l̇ (m/s).
MOTION = "prismatic"
#: Its coordinate, units and range key (messages and rig settings name them).
TRAVEL = LENGTH
#: Default Γ_τ⁻¹ of the force loop (N/m: the paper's platform legs).
COUPLING_GAIN = 1.0e4
STATES = (State("pc", "Pa", 0.0, "supply_pressure", "control (cap-side) chamber pressure"),)
PARAMETERS = (
    Parameter("piston_area", "m^2", None, "A, cap-side (control chamber) area", range=AREA),
    Parameter("rod_area", "m^2", None, "a, annulus area on the rod side (at supply pressure), < A", range=AREA),
    Parameter("chamber_length", "m", None, "L: length at which the control chamber would be empty",
              range=CHAMBER_LENGTH),
    Parameter("supply_pressure", "Pa", None, "P_s", range=SUPPLY_PRESSURE),
    UNDERLAP,
    Parameter("flow_gain", "m^2/(s sqrt(Pa))", None, "c: q = c u sqrt(dp)", gamma=True, range=FLOW_GAIN),
    Parameter("bulk_modulus", "Pa", None, "beta, effective oil bulk modulus", gamma=True, range=BULK_MODULUS),
    ORIFICE_LINEAR_BELOW,
    Parameter("leakage", "m^3/(s Pa)", 0.0, "c_l of (56): total laminar leakage into the control chamber, "
              "Q = c_l (P_s - p_c)", range=LEAKAGE, zero_is_structure=True),
)
SENSORS = (Sensor("l", "m", "cylinder length, pin to pin"),
           Sensor("pc", "Pa", "control-chamber pressure"))


#: Its parameters from a cylinder or joint actuator (or a mapping), defaults filled in; and those of
#: several actuators as arrays (m,), for the numeric laws.
parameters, stacked = readers(__name__)


class Symbolic:
    """SymPy laws (the derivation layer); ``P`` maps parameter names to SymPy numbers or symbols."""

    @staticmethod
    def orifice_roots(pc, ps):
        """√(p_s − p_c), √p_c with the pressure drops clipped at 0 (√Pa): the roots of (57) for a
        measured p_c, which noise can push outside [0, p_s]; inside, exactly the unclipped roots."""
        return orf.clipped_root(ps - pc), orf.clipped_root(pc)

    @staticmethod
    def valve_flow(u, p, P, clipped=False):
        """q_l / c of eq. (57): load flow per unit flow gain c (m·√Pa), three branches.

        ``clipped``: the roots of :meth:`orifice_roots` (shared with the valve inverse), so a measured
        p_c outside [0, p_s] gives no root of a negative number; the model's own law (unclipped)
        otherwise, for p_c inside."""
        (pc,), ps = p, P["supply_pressure"]
        up, down = Symbolic.orifice_roots(pc, ps) if clipped else (sp.sqrt(ps - pc), sp.sqrt(pc))
        return orf.orifice_terms(u, P["underlap"], up, down)

    @staticmethod
    def valve_flow_smooth(u, p, P):
        """Plant version of (57): the orifice roots turn linear below ``orifice_linear_below`` Pa of
        drop. The drops are signed, so a chamber pushed past p_s (or below 0) by an integration step
        flows back instead of taking the root of a negative number."""
        (pc,), ps, p_lin = p, P["supply_pressure"], P["orifice_linear_below"]
        return orf.orifice_terms(u, P["underlap"], orf.signed_sqrt_linearised(ps - pc, p_lin),
                                 orf.signed_sqrt_linearised(pc, p_lin))

    @staticmethod
    def valve_flows(u, p, P, smooth=False):
        """(q_l/c,): the uniform interface's flow per pressure state (the two-chamber kinds give two),
        drops clipped at 0, or the plant's smooth law (``smooth``)."""
        return (Symbolic.valve_flow_smooth(u, p, P) if smooth else Symbolic.valve_flow(u, p, P, clipped=True),)

    @staticmethod
    def flow_inverse(w, p, P, eps):
        """Spool position u with q_l/c = w, inverting (57) over its three branches. Pressure drops are
        clipped at ``eps`` Pa so no root of a negative number is taken and the outer branches never
        divide by zero."""
        # √max(Δp, eps) written as max(√max(Δp, 0), √eps): the same numbers (√ is monotone and
        # correctly rounded), with the roots a controller's g0 shares (orifice_roots)
        root_eps = sp.sqrt(sp.Float(eps))
        up, down = (sp.Max(r, root_eps) for r in Symbolic.orifice_roots(p[0], P["supply_pressure"]))
        return orf.branch_inverse(w, P["underlap"], up, down)

    @staticmethod
    def leakage_flow(p, P):
        """c_l (P_s − p_c) of (56), m³/s into the control chamber; an exact 0 (no term) where c_l is
        an exact 0 or ``P`` gives none (the paper's c_l ≈ 0)."""
        cl = P.get("leakage", sp.S.Zero)
        if cl == 0:
            return sp.S.Zero
        return cl * (P["supply_pressure"] - p[0])

    @staticmethod
    def supply_flow(x, xdot, p, u, c, P, smooth=True):
        """The flow drawn from the supply (m³/s): (57)'s supply edge (open for u ≥ −d), the leakage
        into the control chamber (:meth:`leakage_flow`) and the rod side's, held at supply, −a l̇
        (extending returns oil to the supply)."""
        (pc,), ps = p, P["supply_pressure"]
        root = (orf.signed_sqrt_linearised(ps - pc, P["orifice_linear_below"]) if smooth
                else orf.clipped_root(ps - pc))
        edge = orf.orifice_terms(u, P["underlap"], root, sp.S.Zero)
        return c * edge + Symbolic.leakage_flow(p, P) - P["rod_area"] * xdot

    @staticmethod
    def chamber_pressure_rate(l, ldot, q_l, P, beta):
        """ṗ_c = β (q_l − A l̇) / (A (l − L)), Pa/s (eq. (56) with V = A (l − L)); q_l in m³/s, the
        valve's flow plus the leakage's (:meth:`leakage_flow`)."""
        A, L = P["piston_area"], P["chamber_length"]
        return beta * (q_l - A * ldot) / (A * (l - L))

    @staticmethod
    def force(p, P):
        """f = p_c A − p_s a, N; positive extends the cylinder."""
        return p[0] * P["piston_area"] - P["supply_pressure"] * P["rod_area"]

    @staticmethod
    def chamber_forces(p, P):
        """(p_c A, −P_s a), N: each chamber's push on the piston (the seals' load), summing to the force."""
        return p[0] * P["piston_area"], -P["supply_pressure"] * P["rod_area"]

    @staticmethod
    def pressure_rates(x, xdot, p, u, beta, c, P, smooth=True):
        """(ṗ_c,) of the plant, Pa/s: the flow q_l = c (q_l/c), with the plant's smooth orifice law
        (``smooth``) or the controllers' (57) with clipped drops."""
        flow = Symbolic.valve_flow_smooth(u, p, P) if smooth else Symbolic.valve_flow(u, p, P, clipped=True)
        return (Symbolic.chamber_pressure_rate(x, xdot, c * flow + Symbolic.leakage_flow(p, P), P, beta),)

    @staticmethod
    def f0(x, xdot, p, P):
        """f0 = (−A l̇ + c_l (P_s − p_c)) / (l − L) of (59) (m²/s), so that β f0 is in N/s; without
        leakage independent of ``p`` (which may then be None)."""
        L = P["chamber_length"]
        return -P["piston_area"] * xdot / (x - L) + Symbolic.leakage_flow(p, P) / (x - L)

    @staticmethod
    def g0(x, p, u, P):
        """g0 = (q_l/c) / (l − L) of (59), with (57)'s drops clipped at 0 (a measured p_c outside
        [0, p_s]); βc g0 is in N/s."""
        return Symbolic.valve_flow(u, p, P, clipped=True) / (x - P["chamber_length"])

    @staticmethod
    def valve_inverse(y, x, p, P, eps):
        """The spool u with g0(l, p, u) = y, on every branch of (57): q_l/c = y (l − L), inverted."""
        return Symbolic.flow_inverse(y * (x - P["chamber_length"]), p, P, eps)

    @staticmethod
    def spring_rate(x, P):
        """−∂f0/∂l̇ = A / (l − L) (m): β times it is the oil column's stiffness, N/m."""
        return P["piston_area"] / (x - P["chamber_length"])

    @staticmethod
    def f0_potential(x, P):
        """Φ(l) = −A ln(l − L), whose time derivative is f0 (m²)."""
        return -P["piston_area"] * sp.log(x - P["chamber_length"])

    @staticmethod
    def equilibrium_pressures(force, P):
        """(p_c,) whose force is ``force`` (N): the one chamber holds it alone."""
        return ((force + P["supply_pressure"] * P["rod_area"]) / P["piston_area"],)

    @staticmethod
    def force_range(P):
        """(lowest, highest) force with p_c within [0, P_s], N."""
        ps = P["supply_pressure"]
        return -ps * P["rod_area"], ps * (P["piston_area"] - P["rod_area"])


class Numeric:
    """numpy twins of :class:`Symbolic` (broadcast over arrays; ``P`` of floats or arrays (m,))."""

    @staticmethod
    def valve_flow(u, p, P):
        """q_l / c of (57), drops clipped at 0 (m·√Pa): inside [0, p_s] exactly (57)."""
        (pc,), ps = p, P["supply_pressure"]
        return orf.orifice_terms_np(u, P["underlap"], orf.clipped_root_np(ps - pc), orf.clipped_root_np(pc))

    @staticmethod
    def valve_flow_smooth(u, p, P):
        (pc,), ps, p_lin = p, P["supply_pressure"], P["orifice_linear_below"]
        return orf.orifice_terms_np(u, P["underlap"], orf.signed_sqrt_linearised_np(ps - pc, p_lin),
                                    orf.signed_sqrt_linearised_np(pc, p_lin))

    @staticmethod
    def valve_flows(u, p, P, smooth=False):
        return (Numeric.valve_flow_smooth(u, p, P) if smooth else Numeric.valve_flow(u, p, P),)

    @staticmethod
    def flow_inverse(w, p, P, eps):
        root_eps = np.sqrt(eps)
        ps = P["supply_pressure"]
        up = np.maximum(orf.clipped_root_np(ps - p[0]), root_eps)
        down = np.maximum(orf.clipped_root_np(p[0]), root_eps)
        return orf.branch_inverse_np(w, P["underlap"], up, down)

    @staticmethod
    def force(p, P):
        return p[0] * P["piston_area"] - P["supply_pressure"] * P["rod_area"]

    @staticmethod
    def leakage_flow(p, P):
        return P["leakage"] * (P["supply_pressure"] - p[0])

    @staticmethod
    def chamber_forces(p, P):
        return p[0] * P["piston_area"], -P["supply_pressure"] * P["rod_area"]

    @staticmethod
    def supply_flow(x, xdot, p, u, c, P, smooth=True):
        (pc,), ps = p, P["supply_pressure"]
        root = (orf.signed_sqrt_linearised_np(ps - pc, P["orifice_linear_below"]) if smooth
                else orf.clipped_root_np(ps - pc))
        edge = orf.orifice_terms_np(u, P["underlap"], root, 0.0)
        return c * edge + Numeric.leakage_flow(p, P) - P["rod_area"] * np.asarray(xdot, float)

    @staticmethod
    def pressure_rates(x, xdot, p, u, beta, c, P, smooth=True):
        flow = Numeric.valve_flow_smooth(u, p, P) if smooth else Numeric.valve_flow(u, p, P)
        A, L = P["piston_area"], P["chamber_length"]
        return (beta * (c * flow + Numeric.leakage_flow(p, P) - A * xdot) / (A * (x - L)),)

    @staticmethod
    def f0(x, xdot, p, P):
        L = P["chamber_length"]
        return -P["piston_area"] * xdot / (x - L) + Numeric.leakage_flow(p, P) / (x - L)

    @staticmethod
    def g0(x, p, u, P):
        return Numeric.valve_flow(u, p, P) / (x - P["chamber_length"])

    @staticmethod
    def valve_inverse(y, x, p, P, eps):
        return Numeric.flow_inverse(y * (x - P["chamber_length"]), p, P, eps)

    @staticmethod
    def spring_rate(x, P):
        return P["piston_area"] / (x - P["chamber_length"])

    @staticmethod
    def f0_potential(x, P):
        return -P["piston_area"] * np.log(x - P["chamber_length"])

    @staticmethod
    def equilibrium_pressures(force, P):
        return ((force + P["supply_pressure"] * P["rod_area"]) / P["piston_area"],)

    @staticmethod
    def force_range(P):
        """(lowest, highest) force with p_c within [0, P_s], N."""
        ps = P["supply_pressure"]
        return -ps * P["rod_area"], ps * (P["piston_area"] - P["rod_area"])
