"""Sizes, names and signal layouts of a generated model, from its manifest (plain data).

The one template context: the loop driver and its header (codegen), the ctypes structures of the
loop runner (runtime) and the export bundle are all built from :func:`loop_context`, which reads
only the manifest's ``model`` summary (written by :func:`model_summary` at generation). Imports
neither SymPy, CasADi nor numpy.
"""
from __future__ import annotations

__all__ = ["SLOTS", "MAX_DELAY", "model_summary", "loop_context", "log_widths", "loop_functions", "c_double"]

#: Signals the loop writes into a controller's inputs, by input name, in this order (``u_applied``:
#: the spool commands the valves held over the last period, after the clip and the computation delay).
SLOTS = ("q", "qdot", "pc", "l", "qd0", "qd1", "qd2", "qd3", "xc", "adapt", "u_applied")

#: Longest computation delay the loop's command ring buffer holds, control periods (a scenario's
#: ``delay_periods`` is refused above it). A real-time target applies a command one period after the
#: measurement it came from; 8 leaves room for slower targets and delay-margin studies.
MAX_DELAY = 8


def c_double(x) -> str:
    """A C double literal that reads back to exactly ``x`` (shortest round-trip repr)."""
    return repr(float(x))


def model_summary(model) -> dict:
    """What the manifest records about the model for the drivers and the runtime.

    A robot of three-way cylinders only: their areas (the loop computes f = p_c A − P_s a). Any
    other: the kinds, the pressure vector's size and each state's clip bounds (Pa), the loop's
    forces from the generated ``leg_force``."""
    from .pressures import bounds, n_pressures, uniform_three_way
    out = {
        "name": model.name,
        "n": model.n, "m": model.n_cylinders, "p": model.n_theta,
        "coordinates": list(model.coordinate_names),
        "cylinders": [c.name for c in model.cylinders],
        "theta_names": list(model.theta_names),
    }
    if uniform_three_way(model):
        out["piston_area"] = [float(c.piston_area) for c in model.cylinders]
        out["rod_area"] = [float(c.rod_area) for c in model.cylinders]
    else:
        lo, hi = bounds(model)
        out.update(kinds=[c.kind for c in model.cylinders], n_pressures=n_pressures(model),
                   pressure_low=lo.tolist(), pressure_high=hi.tolist())
    out["supply_pressure"] = [float(c.supply_pressure) for c in model.cylinders]
    out["joint_encoders"] = bool(model.joint_encoders)
    return out


def n_pressures(summary: dict) -> int:
    """Size of the pressure vector (one state per three-way cylinder)."""
    return summary.get("n_pressures", summary["m"])


def loop_functions(summary: dict) -> tuple:
    """The generated functions the loop driver calls (an export or FMU compiles them with it): the
    forces of a robot whose actuators are not all three-way cylinders come from ``leg_force``."""
    base = ("leg_lengths", "leg_kinematics", "plant_rhs")
    return base if "piston_area" in summary else (*base, "leg_force")


def log_widths(summary: dict) -> dict:
    """Row width of each log of the loop (``xc``'s is the controller's state size)."""
    n, m = summary["n"], summary["m"]
    return {"t": 1, "q": n, "q_d": n, "l": m, "f": m, "pc": n_pressures(summary), "u": m, "u_applied": m, "l_meas": m}


def loop_context(manifest: dict) -> dict:
    """Everything the loop templates and the ctypes structures need, from a manifest."""
    s = manifest["model"]
    n, m, name = s["n"], s["m"], s["name"]
    pressures = "chamber pressures (one block per actuator), Pa" if "n_pressures" in s else "control pressures, Pa"
    what = {"t": "time, s", "q": "true pose", "q_d": "reference", "l": "true cylinder lengths, m",
            "f": "cylinder forces, N", "pc": pressures, "u": "spool commands computed, m",
            "u_applied": "spool commands applied (delay_periods later), m",
            "l_meas": "measured cylinder lengths (noise, quantisation), m"}
    logs = [(k, w, what[k]) for k, w in log_widths(s).items()] + [("xc", "n_xc", "controller state")]
    n_p, three_way = n_pressures(s), "piston_area" in s
    ctx = {
        "model": name, "p": name, "P": name.upper(), "guard": f"{name.upper()}_LOOP_H",
        "n": n, "m": m, "nx": 2 * n + n_p + 2 * m, "max_delay": MAX_DELAY,
        "n_noise": m + n_p + (n if s["joint_encoders"] else 0), "n_pressures": n_p, "three_way": three_way,
        "encoders": bool(s["joint_encoders"]), "slots": SLOTS, "logs": logs,
        "p_theta": ", ".join(s["theta_names"]),
        "supply_pressure": ", ".join(map(c_double, s["supply_pressure"])),
    }
    if three_way:
        ctx.update(piston_area=", ".join(map(c_double, s["piston_area"])),
                   rod_area=", ".join(map(c_double, s["rod_area"])))
    else:
        ctx.update(pressure_low=", ".join(map(c_double, s["pressure_low"])),
                   pressure_high=", ".join(map(c_double, s["pressure_high"])))
    return ctx
