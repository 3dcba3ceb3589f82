"""Helpers shared by the benchmark modules: paths, machine description, C drivers, plausible inputs.

Importable both as ``benchmarks.common`` (from the repository root or through ``hydrogen bench``)
and as ``common`` when a benchmark is run as a script from ``benchmarks/``.
"""
from __future__ import annotations

import os
import platform
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TEMPLATES = REPO / "templates"
#: Flags of every benchmark C driver (the generated code must build cleanly under them).
CFLAGS = ("-O2", "-std=c99", "-Wall", "-Wextra", "-Werror")

# ---------------------------------------------------------------------------------------------
# plausible input values, by input name (model: generated/ubc_stewart, SI units)
# ---------------------------------------------------------------------------------------------
NEUTRAL_POSE = np.array([0.0, 0.0, -2.34, 0.0, 0.0, 0.0])
#: Offsets from the neutral pose: every entry non-zero, away from symmetric configurations.
DQ = np.array([0.012, -0.021, 0.034, 0.051, -0.043, 0.027])
THETA = np.array([250.0, 45.0, 45.0, 43.0])     # [M_p kg, I_x, I_y, I_z kg m^2]
GAMMA = np.array([7.0e8, 1.05e5])               # [beta Pa, beta c]
INERTIA6 = np.array([250.0, 250.0, 250.0, 45.0, 45.0, 43.0])
LEG_LENGTH = 1.843                              # m, every leg at the neutral pose

#: Fixed values (gains, bounds, model parameters): name -> values (column-major when a matrix).
FIXED = {
    "theta": THETA,
    "gamma": GAMMA,
    "theta_min": np.array([150.0, 25.0, 25.0, 25.0]),
    "theta_max": np.array([350.0, 65.0, 65.0, 65.0]),
    "gamma1_min": np.array([3.5e8]), "gamma1_max": np.array([1.4e9]),
    "gamma2_min": np.array([5.0e4]), "gamma2_max": np.array([2.2e5]),
    "Dbar_inv": np.diag(1.0 / INERTIA6).ravel(order="F"),
    "Gbar": np.array([0.0, 0.0, 250.0 * 9.81, 0.0, 0.0, 0.0]),
    "friction": np.array([100.0, 300.0, 1e-3]),
    "valve": np.zeros(3),
    "adapt": np.array([1.0]),
    "u_max": np.array([5e-3]),
    "sat_width": np.array([1e-3]),
    # gains: positive, of the order of the defaults in hydrogen/simulation/control.py
    "Lambda": np.full(6, 60.0), "Lambda2": np.full(6, 60.0),
    "Kp": np.full(6, 3000.0), "Kd": np.full(6, 600.0), "Kd_obs": np.full(6, 600.0),
    "Ktau": np.full(6, 150.0), "Gtau_inv": np.full(6, 1.0e4),
    "Ko": np.full(6, 30.0), "lambda_o": np.array([1.0, 2.0, 3.0, 4.0]),
    "Gz_inv": 1.0 / INERTIA6, "Lp": np.full(6, 3000.0),
    "Gtheta_inv": np.array([1.0e3, 2.0e3, 2.0e3, 2.0e3]),
    "Ggamma1_inv": np.full(6, 1.0e4), "Ggamma2_inv": np.full(6, 1.0e3),
    "Kleg": np.full(6, 0.035),
}

#: Scale of the small random values of the remaining (state-like) inputs.
RANDOM_SCALE = {
    "qdot": 0.1, "qd1": 0.1, "qd2": 0.5, "qd3": 2.0, "v": 0.1, "w": 0.1, "a": 1.0,
    "u": 1e-3, "ldot": 0.05, "ql_per_c": 1.0, "z": 0.01,
}


def input_value(name: str, rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
    """Plausible values (flat, column-major) for the input ``name`` of shape rows x cols."""
    n = rows * cols
    small = lambda s=0.05: s * rng.uniform(-1.0, 1.0, n)  # noqa: E731
    if name in ("q", "qd0", "q_hat") and n == 6:
        return NEUTRAL_POSE + DQ + small(0.005)
    if name in FIXED and FIXED[name].size == n:
        return np.array(FIXED[name], float)
    if name == "pc":
        return 5.0e6 + small(2.0e5)
    if name == "l" and n == 6:
        return LEG_LENGTH + small(0.02)
    if name == "x" and n == 30:  # plant state [q, qdot, pc, spool, spool rate]
        return np.concatenate([NEUTRAL_POSE + DQ, small(0.1)[:6], 5.0e6 + small(2.0e5)[:6], small(1e-3)[:6],
                               small(1e-2)[:6]])
    if name == "xc" and n in (22, 28):  # [q_hat (6)], z (6), theta_hat (4), gamma1_hat (6), gamma2_hat (6)
        xc = [np.full(6, 0.01), THETA, np.full(6, GAMMA[0]), np.full(6, GAMMA[1])]
        if n == 28:
            xc.insert(0, NEUTRAL_POSE + DQ + small(0.005)[:6])
        return np.concatenate(xc)
    return small(RANDOM_SCALE.get(name, 0.05))


def function_inputs(entry: dict, seed: int = 0) -> list:
    """[(name, flat column-major values)] for a manifest function entry (inputs [[name, rows, cols]])."""
    rng = np.random.default_rng(seed)
    return [(name, input_value(name, int(r), int(c), rng)) for name, r, c in entry["inputs"]]


# ---------------------------------------------------------------------------------------------
# machine, tools, subprocesses
# ---------------------------------------------------------------------------------------------
def cc_version(cc: str = "cc") -> str:
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30)
        return out.stdout.splitlines()[0] if out.stdout else "unknown"
    except OSError:
        return "unknown"


def cpu_name() -> str:
    name = platform.processor()
    if name and name not in ("x86_64", "aarch64", "arm64"):
        return name
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def machine_info(cc: str = "cc") -> dict:
    import casadi
    import sympy

    return {"processor": cpu_name(), "cpu_count": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version(), "numpy": np.__version__, "sympy": sympy.__version__,
            "casadi": casadi.__version__, "cc": cc_version(shutil.which(cc) or cc)}


def require_cc(cc: str = "cc") -> str:
    path = shutil.which(cc)
    if path is None:
        raise RuntimeError(f"C compiler '{cc}' not found on PATH")
    return path


def jinja_env():
    import jinja2

    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                              undefined=jinja2.StrictUndefined, trim_blocks=True,
                              lstrip_blocks=True, keep_trailing_newline=True)


def c_float(x: float) -> str:
    """A C double literal that round-trips ``x`` exactly."""
    r = repr(float(x))
    if r in ("inf", "-inf", "nan"):
        raise ValueError(f"non-finite value {r} cannot be a C literal")
    return r if any(ch in r for ch in ".eE") else r + ".0"


def python_env() -> dict:
    """Environment for a benchmark subprocess: this interpreter's hydrogen, unbuffered output."""
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    return env


def run_python(code: str, timeout: float = 600.0, env: dict | None = None) -> tuple[str, float]:
    """Run ``code`` with this interpreter in a fresh process; return (stdout, wall seconds)."""
    import time

    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=timeout, env=env or python_env(), cwd=str(REPO))
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed (exit {proc.returncode}):\n{code}\n"
                           f"--- stderr ---\n{proc.stderr.strip()}")
    return proc.stdout, wall


def parse_keyed(stdout: str) -> dict:
    """Lines ``KEY value`` (value a float) of a subprocess's output, as a dict."""
    out = {}
    for line in stdout.splitlines():
        parts = line.split()
        if len(parts) == 2:
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                pass
    return out


def median(values) -> float:
    return float(statistics.median(values))
