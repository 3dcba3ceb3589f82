"""The rigid body's two forms, closed and staged (``rigid_body_form``, hydrogen.symbolic.forms), on
the shipped robots and a spatial 3-DOF leg: per form, the derivation time and CasADi instructions of
the rigid-body functions "auto" counts, and of every controller (what the count stands in for).

The leg (:func:`leg_description`): hip ab/ad about x, hip flexion and knee about y, a 0.1 m hip
link, 0.4 m thigh and shank (4, 3 and 2 kg, slender rods), one three-way cylinder per joint, θ the
thigh's and the shank's mcx, mcz, Iyy. Each (robot, form) runs in a fresh Python process, so no
derivation is shared between the forms.

Run: ``python benchmarks/bench_forms.py [--models NAME ...] [--json FILE]``
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def leg_description() -> dict:
    """A spatial leg of three revolute joints (parsed-TOML form): hip ab/ad (x), hip flexion (y),
    knee (y), each on a three-way cylinder pinned between neighbouring links; neutral pose
    [0, 0.3, -0.6] rad (thigh forward, knee bent). Units SI."""
    def rod(m, L):
        return [m * L * L / 12.0, m * L * L / 12.0, 1e-3]
    links = [{"name": "hip", "mass": 4.0, "com": [0.0, 0.05, 0.0], "inertia": [0.01, 0.01, 0.01]},
             {"name": "thigh", "mass": 3.0, "com": [0.0, 0.0, -0.2], "inertia": rod(3.0, 0.4)},
             {"name": "shank", "mass": 2.0, "com": [0.0, 0.0, -0.2], "inertia": rod(2.0, 0.4)}]
    joints = [{"name": "hip_abad", "type": "revolute", "parent": "base", "child": "hip", "axis": [1.0, 0.0, 0.0]},
              {"name": "hip_flex", "type": "revolute", "parent": "hip", "child": "thigh",
               "origin_xyz": [0.0, 0.1, 0.0], "axis": [0.0, 1.0, 0.0]},
              {"name": "knee", "type": "revolute", "parent": "thigh", "child": "shank",
               "origin_xyz": [0.0, 0.0, -0.4], "axis": [0.0, 1.0, 0.0]}]
    cylinders = [{"name": "abad_cyl", "from": {"link": "base", "point": [0.0, 0.30, 0.10]},
                  "to": {"link": "hip", "point": [0.0, 0.05, -0.20]}},
                 {"name": "hip_cyl", "from": {"link": "hip", "point": [0.25, 0.10, 0.05]},
                  "to": {"link": "thigh", "point": [0.08, 0.0, -0.20]}},
                 {"name": "knee_cyl", "from": {"link": "thigh", "point": [0.08, 0.0, -0.10]},
                  "to": {"link": "shank", "point": [0.06, 0.0, -0.10]}}]
    params = [f"{lk}.{k}" for lk in ("thigh", "shank") for k in ("mcx", "mcz", "Iyy")]
    m = {"thigh": 3.0, "shank": 2.0}
    true = {f"{lk}.{k}": v for lk in m for k, v in
            (("mcx", 0.0), ("mcz", -0.2 * m[lk]), ("Iyy", m[lk] * 0.4 ** 2 / 12 + m[lk] * 0.04))}
    lo = [true[p] - 0.5 * abs(true[p]) - 0.01 for p in params]
    hi = [true[p] + 0.5 * abs(true[p]) + 0.01 for p in params]
    return {
        "name": "spatial_leg", "gravity": 9.81, "links": links, "joints": joints,
        "coordinates": {"neutral": [0.0, 0.3, -0.6]},
        "hydraulics": {"piston_area": 5.0e-4, "rod_area": 2.5e-4, "chamber_length": 0.05,
                       "supply_pressure": 20.0e6, "underlap": 2.0e-5, "flow_gain": 2.0e-5,
                       "bulk_modulus": 7.0e8, "orifice_linear_below": 5.0e4, "stroke": [0.1, 0.6]},
        "cylinders": cylinders,
        "adaptation": {"parameters": params, "theta_min": lo, "theta_max": hi, "gamma1_min": 3.5e8,
                       "gamma1_max": 1.4e9, "gamma2_min": 3.5e3, "gamma2_max": 5.6e4},
        "sensors": {"joint_encoders": True},
    }


def leg_model(form: str = "auto"):
    from hydrogen.model import model_from_dict

    return model_from_dict({**leg_description(), "rigid_body_form": form}, source="<bench_forms spatial_leg>")


_ONE = """
import json, sys, time
sys.path.insert(0, {here!r})
import hydrogen
from hydrogen.symbolic.forms import form_costs, with_form
from hydrogen.symbolic.functions import controller_functions
from hydrogen.codegen.casadi_functions import casadi_function
name, form = {name!r}, {form!r}
if name == "spatial_leg":
    from bench_forms import leg_model
    model = leg_model()
else:
    model = hydrogen.load_model(name)
t = time.perf_counter()
rb = form_costs(model, form)
rb_s = time.perf_counter() - t
t = time.perf_counter()
m = with_form(model, form)
funcs = controller_functions(m)
derive_s = time.perf_counter() - t
t = time.perf_counter()
cache = {{}}
ctrl = {{f.name: int(casadi_function(f, cache=cache).n_instructions()) for f in funcs
        if type(f).__name__ == "SymbolicFunction"}}
convert_s = time.perf_counter() - t
print(json.dumps({{"rigid_body": rb, "rigid_body_total": sum(rb.values()), "rigid_body_s": rb_s,
                   "controllers": ctrl, "controllers_derive_s": derive_s, "controllers_convert_s": convert_s}}))
"""


def measure(name: str, form: str) -> dict:
    out = subprocess.run([sys.executable, "-c", _ONE.format(here=str(HERE), name=name, form=form)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", default=["excavator_arm", "loader_crane", "spatial_leg"])
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    results = {}
    for name in args.models:
        for form in ("closed", "staged"):
            r = measure(name, form)
            results[f"{name}/{form}"] = r
            print(f"{name:14s} {form:7s} rigid body {r['rigid_body_total']:7d} instr {r['rigid_body_s']:6.1f} s | "
                  f"controllers {sum(r['controllers'].values()):8d} instr, derive {r['controllers_derive_s']:6.1f} s"
                  f" convert {r['controllers_convert_s']:6.1f} s", flush=True)
            print("   ", json.dumps(r["rigid_body"]), json.dumps(r["controllers"]), flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
