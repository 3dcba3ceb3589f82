#!/usr/bin/env python3
"""Check the excavator_arm description against its stroke, valve force range and references.

Standalone (numpy + pinocchio + tomllib; not part of the hydrogen package). It reads
hydrogen/data/excavator_arm.toml and the URDF it names, builds the tree with Pinocchio, and:

  (a) computes every cylinder's pin-to-pin length l(q) over a grid of the proposed workspace and of
      the URDF joint-limit box, and checks l_min <= l <= l_max (a cylinder with a ``linkage`` table
      ends on the pin joining its rocker and coupler, found here by intersecting their circles in
      the arm's x-z plane: an implementation independent of hydrogen's);
  (b) computes JL = dl/dq by central differences and reports its condition number;
  (c) checks that gravity G(q) (pin.computeGeneralizedGravity) is held by cylinder forces
      f = JL^-T G inside the four-way cylinder's range [-(P_s A_B - P_t A_A), P_s A_A - P_t A_B],
      reporting the worst ratio |f| / (limit in the direction of f); the design aim is <= 0.6;
  (d) estimates each cylinder's hydraulic natural frequency: two compliant chambers, stiffness
      k = beta (A_A^2 / V_A + A_B^2 / V_B), against the effective mass m_eff = 1 / (JL D^-1 JL^T)_ii;
      also the modes of D^-1 JL^T diag(k) JL;
  (e) runs the proposed arm-sim and arm-dig references (multi-sines about the neutral pose) through
      inverse dynamics (pin.rnea), adding cylinder friction for arm-dig, and checks stroke, force
      range, cylinder speed, the cap-side valve flow A_A l' (oil compressibility neglected), the
      spool opening that flow needs at the force's steady chamber pressures (the four-way valve's
      orifice law) against u_max, and the net pump flow (A_A l' extending, A_B |l'| retracting).

Usage:  python tools/check_excavator_arm.py [--toml PATH] [--grid N]
Exit status 0 when every check passes.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_TOML = ROOT / "hydrogen" / "data" / "excavator_arm.toml"

#: Proposed scenario workspace (rad), per joint [low, high]; docs/excavator_arm.md.
WORKSPACE = np.array([[-0.55, 0.75],     # boom
                      [-2.45, -0.85],    # stick
                      [-1.65, -0.15]])   # bucket
FORCE_AIM = 0.6          # worst |f| / force limit for gravity alone
U_MAX = 3.0e-3           # proposed controller spool limit, m
PUMP_FLOW = 429.0        # Cat 320 implement pumps, L/min (2 x 214.5)

#: Proposed references: q_d(t) = neutral + sum a sin(2 pi f t) over (joint, amplitude rad, Hz);
#: friction: whether each cylinder's own friction table (its Coulomb and viscous terms, tanh
#: smoothing FRICTION_SPEED) acts, as on hydrogen's rig; the ideal plant has none.
REFERENCES = {
    # counterpart of the paper's section V multi-sine: slow wide sweeps plus faster small terms
    "arm-sim": dict(duration=10.0, friction=False, terms=(
        (0, 0.22, 0.10), (0, 0.03, 0.30),
        (1, -0.28, 0.10), (1, 0.03, 0.40),
        (2, 0.28, 0.15), (2, 0.03, 0.50))),
    # digging cycle, period 5 s: first half boom down (leading), stick crowds, bucket curls
    # (lagging); second half boom up, stick out, bucket opens (dump)
    "arm-dig": dict(duration=10.0, friction=True, terms=(
        (0, -0.12, 0.20), (0, -0.03, 0.40),
        (1, -0.21, 0.20),
        (2, -0.24, 0.20), (2, 0.05, 0.40))),
}
#: Bucket tooth tip in the bucket frame, m, and the Cat 320 working ranges to compare with
#: (reach boom, R2.9 stick: 32.3 ft, 22 ft, 30.7 ft; docs/excavator_arm.md), m.
TIP = np.array([1.47, 0.0, 0.0])
CAT320_RANGES = {"max reach at ground level": 9.85, "max digging depth": 6.71, "max cutting height": 9.36}


FRICTION_SPEED = 1e-3   # m/s: the tanh smoothing of the rig's friction


def valve_constants(valve: dict) -> dict:
    """The orifice constant c (m²/(s √Pa)) and underlap d (m) of a datasheet valve: at full opening
    (spool_travel) one metering edge passes rated_flow with rated_drop across it, q = c (u + d) √Δp."""
    travel = float(valve["spool_travel"])
    d = max(-float(valve.get("overlap", 0.0)), 0.0) * travel
    return dict(c=float(valve["rated_flow"]) / ((travel + d) * np.sqrt(float(valve["rated_drop"]))), d=d)


def load(toml_path: Path):
    desc = tomllib.loads(toml_path.read_text())
    model = pin.buildModelFromUrdf(str((toml_path.parent / desc["urdf"]).resolve()))
    model.gravity.linear = np.array([0.0, 0.0, -desc["gravity"]])
    data = model.createData()
    hyd = desc["hydraulics"]
    urdf_joints = {model.names[j]: j for j in range(1, model.njoints)}
    cyls = []
    for c in desc["cylinders"]:
        get = lambda k: float(c.get(k, hyd.get(k)))  # noqa: E731  (cylinder overrides the default)
        kind = c.get("kind", hyd.get("kind"))
        if kind != "four_way_cylinder":
            raise SystemExit(f"cylinder {c['name']}: kind {kind!r}; this script checks four-way cylinders")
        cyl = dict(
            name=c["name"],
            frm=(model.getFrameId(c["from"]["link"], pin.BODY), np.array(c["from"]["point"], float)),
            AA=get("cap_area"), AB=get("annulus_area"), VA0=get("dead_volume_A"), VB0=get("dead_volume_B"),
            stroke=tuple(map(float, c["stroke"])), Ps=get("supply_pressure"), Pt=get("tank_pressure"),
            beta=get("bulk_modulus"), **valve_constants(c.get("valve", hyd.get("valve"))),
            friction=(float(c.get("friction", {}).get("coulomb", 0.0)), float(c.get("friction", {}).get("viscous", 0.0))))
        if "linkage" in c:
            lk = c["linkage"]
            j = urdf_joints[lk["joint"]]
            parent = model.frames[model.getFrameId(c["from"]["link"], pin.BODY)]
            child = [f for f in model.frames if f.type == pin.BODY and f.parentJoint == j][0]
            cyl["linkage"] = dict(pivot=(model.getFrameId(parent.name, pin.BODY), np.array(lk["rocker_pivot"], float)),
                                  pin=(model.getFrameId(child.name, pin.BODY), np.array(lk["crank_pin"], float)),
                                  rocker=float(lk["rocker"]), coupler=float(lk["coupler"]), branch=int(lk["branch"]))
        else:
            cyl["to"] = (model.getFrameId(c["to"]["link"], pin.BODY), np.array(c["to"]["point"], float))
        cyls.append(cyl)
    if model.nq != len(cyls):
        raise SystemExit(f"{model.nq} coordinates but {len(cyls)} cylinders")
    return desc, model, data, cyls


def rod_end(data, lk):
    """The pin joining rocker and coupler (base frame): the intersection of the circles about the
    rocker pivot (radius rocker) and the crank pin (radius coupler) in the arm's x-z plane, on the
    side of crank pin -> pivot that ``branch`` names (x right, z up: the joint axes -y towards the
    viewer, so +1 is to the left)."""
    B = data.oMf[lk["pin"][0]].act(lk["pin"][1])
    O4 = data.oMf[lk["pivot"][0]].act(lk["pivot"][1])
    b, o = B[[0, 2]], O4[[0, 2]]
    d = o - b
    D = np.linalg.norm(d)
    a = (lk["coupler"] ** 2 - lk["rocker"] ** 2 + D ** 2) / (2 * D)
    h2 = lk["coupler"] ** 2 - a ** 2
    if h2 < 0:
        return np.full(3, np.nan)
    c2 = b + a / D * d + lk["branch"] * np.sqrt(h2) / D * np.array([-d[1], d[0]])
    return np.array([c2[0], B[1], c2[1]])


def lengths(model, data, cyls, q):
    pin.framesForwardKinematics(model, data, q)
    out = np.empty(len(cyls))
    for i, c in enumerate(cyls):
        p0 = data.oMf[c["frm"][0]].act(c["frm"][1])
        p1 = rod_end(data, c["linkage"]) if "linkage" in c else data.oMf[c["to"][0]].act(c["to"][1])
        out[i] = np.linalg.norm(p1 - p0)
    return out


def jacobian(model, data, cyls, q, h=1e-6):
    J = np.empty((len(cyls), model.nv))
    for j in range(model.nv):
        e = np.zeros(model.nv)
        e[j] = h
        J[:, j] = (lengths(model, data, cyls, q + e) - lengths(model, data, cyls, q - e)) / (2 * h)
    return J


def force_limits(c):
    """The four-way cylinder's force range (N): [-(P_s A_B - P_t A_A), P_s A_A - P_t A_B]."""
    return -(c["Ps"] * c["AB"] - c["Pt"] * c["AA"]), c["Ps"] * c["AA"] - c["Pt"] * c["AB"]


def force_ratio(c, f):
    """|f| over the four-way cylinder's limit in the direction of f."""
    lo, hi = force_limits(c)
    return f / hi if f >= 0 else f / lo


def stiffness(c, l):
    """Hydraulic stiffness of both chambers, beta (A_A^2/V_A + A_B^2/V_B), N/m."""
    VA = c["VA0"] + c["AA"] * (l - c["stroke"][0])
    VB = c["VB0"] + c["AB"] * (c["stroke"][1] - l)
    return c["beta"] * (c["AA"] ** 2 / VA + c["AB"] ** 2 / VB)


def spool_for_speed(c, v, f):
    """Spool opening u (m) moving the cylinder at v (m/s) against force f at steady chamber pressures:
    flows A_A v in and A_B v out through matched orifices (P->A, B->T extending; A->T, P->B retracting),
    so the pressure drops are in the ratio (A_A/A_B)^2; underlap subtracted, compressibility neglected."""
    AA, AB, Ps, Pt, k, d = c["AA"], c["AB"], c["Ps"], c["Pt"], c["c"], c["d"]
    r2 = (AA / AB) ** 2
    if v >= 0:   # x = P_s - p_A = r2 (p_B - P_t)
        y = (Ps * AA - Pt * AB - f) / (AA * r2 + AB)
    else:        # x = p_A - P_t = r2 (P_s - p_B)
        y = (f - Pt * AA + Ps * AB) / (AA * r2 + AB)
    if y <= 0:
        return np.inf
    u = AA * abs(v) / (k * np.sqrt(r2 * y))
    return max(u - d, 0.0)


def grid(box, n):
    axes = [np.linspace(lo, hi, n) for lo, hi in box]
    return (np.array(q) for q in itertools.product(*axes))


def joint_limit_box(model):
    return np.stack([model.lowerPositionLimit, model.upperPositionLimit], axis=1)


def reference(neutral, terms, t):
    """q, q', q'' of a multi-sine (terms: joint, amplitude rad, Hz) at times t, as hydrogen's MultiSine."""
    n = len(neutral)
    q = np.tile(np.asarray(neutral, float), (t.size, 1))
    qd, qdd = np.zeros((t.size, n)), np.zeros((t.size, n))
    for j, a, f in terms:
        w = 2 * np.pi * f
        q[:, j] += a * np.sin(w * t)
        qd[:, j] += a * w * np.cos(w * t)
        qdd[:, j] -= a * w * w * np.sin(w * t)
    return q, qd, qdd


def check_static(model, data, cyls, box, n, with_gravity):
    ncyl = len(cyls)
    lmin, lmax = np.full(ncyl, np.inf), np.full(ncyl, -np.inf)
    cond = [np.inf, 0.0]
    worst = np.zeros(ncyl)
    worst_q = [None] * ncyl
    fn_cyl = [np.full(ncyl, np.inf), np.zeros(ncyl)]
    fn_mode = [np.inf, 0.0]
    for q in grid(box, n):
        l = lengths(model, data, cyls, q)
        lmin, lmax = np.minimum(lmin, l), np.maximum(lmax, l)
        JL = jacobian(model, data, cyls, q)
        k = np.linalg.cond(JL)
        cond = [min(cond[0], k), max(cond[1], k)]
        if not with_gravity:
            continue
        G = pin.computeGeneralizedGravity(model, data, q)
        f = np.linalg.solve(JL.T, G)
        for i, c in enumerate(cyls):
            r = force_ratio(c, f[i])
            if r > worst[i]:
                worst[i], worst_q[i] = r, q.copy()
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        Minv = np.linalg.inv(M)
        kh = np.array([stiffness(c, l[i]) for i, c in enumerate(cyls)])
        meff = 1.0 / np.diag(JL @ Minv @ JL.T)
        fc = np.sqrt(kh / meff) / (2 * np.pi)
        fn_cyl = [np.minimum(fn_cyl[0], fc), np.maximum(fn_cyl[1], fc)]
        w2 = np.linalg.eigvals(Minv @ JL.T @ np.diag(kh) @ JL).real
        fm = np.sqrt(w2) / (2 * np.pi)
        fn_mode = [min(fn_mode[0], fm.min()), max(fn_mode[1], fm.max())]
    return dict(lmin=lmin, lmax=lmax, cond=cond, worst=worst, worst_q=worst_q,
                fn_cyl=fn_cyl, fn_mode=fn_mode)


def check_reference(model, data, cyls, neutral, spec, h=1e-3):
    t = np.arange(0.0, spec["duration"] + h / 2, h)
    q, qd, qdd = reference(neutral, spec["terms"], t)
    on = spec["friction"]
    ncyl = len(cyls)
    L = np.empty((t.size, ncyl))
    Ld = np.empty_like(L)
    F = np.empty_like(L)
    for k in range(t.size):
        L[k] = lengths(model, data, cyls, q[k])
        JL = jacobian(model, data, cyls, q[k])
        Ld[k] = JL @ qd[k]
        tau = pin.rnea(model, data, q[k], qd[k], qdd[k])
        F[k] = np.linalg.solve(JL.T, tau)
        if on:
            for i, c in enumerate(cyls):
                Fc, b = c["friction"]
                F[k, i] += Fc * np.tanh(Ld[k, i] / FRICTION_SPEED) + b * Ld[k, i]
    out = dict(l=(L.min(0), L.max(0)), q=(q.min(0), q.max(0)), vmax=np.abs(Ld).max(0),
               ratio=np.zeros(ncyl), qmax=np.zeros(ncyl), umax=np.zeros(ncyl), pump=0.0)
    pump = np.zeros(t.size)
    for i, c in enumerate(cyls):
        ratio = np.array([force_ratio(c, f) for f in F[:, i]])
        u = np.array([spool_for_speed(c, Ld[k, i], F[k, i]) for k in range(t.size)])
        out["ratio"][i] = ratio.max()
        out["qmax"][i] = np.abs(c["AA"] * Ld[:, i]).max() * 6e4
        out["umax"][i] = np.abs(u).max()
        # four-way circuit: the pumps fill the cap side extending and the annulus retracting
        v = Ld[:, i]
        pump += np.where(v > 0, c["AA"] * v, -c["AB"] * v)
    out["pump"] = pump.max() * 6e4
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--toml", type=Path, default=DEFAULT_TOML)
    ap.add_argument("--grid", type=int, default=13, help="points per joint (default 13)")
    args = ap.parse_args(argv)
    desc, model, data, cyls = load(args.toml)
    names = [c["name"] for c in cyls]
    ok = True

    def verdict(cond, what):
        nonlocal ok
        ok &= bool(cond)
        return f"{'PASS' if cond else 'FAIL'}  {what}"

    print(f"model {desc['name']}: {model.nq} joints "
          f"{[model.names[j] for j in range(1, model.njoints)]}, cylinders {names}")
    neutral = np.array(desc["coordinates"]["neutral"], float)
    print(f"neutral q = {neutral}, l(neutral) = {np.round(lengths(model, data, cyls, neutral), 4)} m")

    # --- inertial parameters theta (about the link-frame origin) and their bounds
    print("\nadaptation parameters (Pinocchio dynamic parameters, link frame):")
    pidx = {"mass": 0, "mcx": 1, "mcy": 2, "mcz": 3, "Ixx": 4, "Ixy": 5, "Iyy": 6, "Ixz": 7, "Iyz": 8, "Izz": 9}
    ad = desc["adaptation"]
    for name, lo, hi in zip(ad["parameters"], ad["theta_min"], ad["theta_max"]):
        link, p = name.split(".")
        joint = model.frames[model.getFrameId(link, pin.BODY)].parentJoint
        val = model.inertias[joint].toDynamicParameters()[pidx[p]]
        inside = lo < 0.7 * val < hi and lo < 1.3 * val < hi if val > 0 else lo < val < hi
        print(f"  {name:12s} true {val:10.1f}   bounds [{lo:9.1f}, {hi:9.1f}]  "
              + verdict(inside, "contains 0.7x and 1.3x the truth"))
    for i in range(1, model.njoints):
        I = model.inertias[i]
        ev = np.linalg.eigvalsh(I.inertia)
        tri = ev[0] + ev[1] >= ev[2] - 1e-9
        print(f"  {model.names[i]:12s} mass {I.mass:7.1f} kg, principal inertia {np.round(ev, 1)}  "
              + verdict(ev.min() > 0 and tri, "positive definite, triangle inequality"))

    # --- mechanical limits: the angle at which each cylinder reaches its stroke ends
    print("\njoint limits (URDF), cylinder lengths there, largest moment arm and torque:")
    for j in range(model.nq):
        for qj in (model.lowerPositionLimit[j], model.upperPositionLimit[j]):
            q = neutral.copy()
            q[j] = qj
            print(f"  {names[j]:16s} q = {qj:+.3f}  l = {lengths(model, data, cyls, q)[j]:.4f}  "
                  f"stroke [{cyls[j]['stroke'][0]}, {cyls[j]['stroke'][1]}]")
        arm = 0.0
        for qj in np.linspace(model.lowerPositionLimit[j], model.upperPositionLimit[j], 181):
            q = neutral.copy()
            q[j] = qj
            arm = max(arm, abs(jacobian(model, data, cyls, q)[j, j]))
        c = cyls[j]
        fmax = max(-force_limits(c)[0], force_limits(c)[1])
        print(f"  {'':16s} max |dl/dq| = {arm:.3f} m/rad -> torque {arm * fmax / 1e3:.0f} kN m "
              f"(URDF effort {model.effortLimit[j] / 1e3:.0f} kN m)")

    # --- the bucket tip's working range over the joint-limit box, against the Cat 320's
    tip_frame = model.getFrameId("bucket", pin.BODY)
    pts = []
    for q in grid(joint_limit_box(model), 41):
        pin.framesForwardKinematics(model, data, q)
        pts.append(data.oMf[tip_frame].act(TIP))
    pts = np.array(pts)
    ground = np.abs(pts[:, 2]) < 0.05
    ours = {"max reach at ground level": pts[ground, 0].max(), "max digging depth": -pts[:, 2].min(),
            "max cutting height": pts[:, 2].max()}
    print("\nbucket tip working range (joint-limit box) vs Cat 320 (reach boom, R2.9 stick):")
    for k, v in ours.items():
        print(f"  {k:26s} {v:5.2f} m   (Cat 320: {CAT320_RANGES[k]:.2f} m)")

    # --- (a)-(d) over grids
    box_lim = joint_limit_box(model)
    for label, box, grav in (("URDF joint-limit box", box_lim, False),
                             ("proposed workspace", WORKSPACE, True)):
        r = check_static(model, data, cyls, box, args.grid, grav)
        print(f"\n{label}: {np.round(box, 3).tolist()} rad, {args.grid}^{model.nq} points")
        print(f"  {'cylinder':16s} {'l min':>7s} {'l max':>7s} {'stroke':>15s}  (a)")
        for i, c in enumerate(cyls):
            inside = c["stroke"][0] - 1e-9 <= r["lmin"][i] and r["lmax"][i] <= c["stroke"][1] + 1e-9
            print(f"  {c['name']:16s} {r['lmin'][i]:7.4f} {r['lmax'][i]:7.4f} "
                  f"[{c['stroke'][0]:.3f}, {c['stroke'][1]:.3f}]  " + verdict(inside, "within stroke"))
        print(f"  (b) cond(JL) in [{r['cond'][0]:.2f}, {r['cond'][1]:.2f}]  "
              + verdict(np.isfinite(r["cond"][1]) and r["cond"][1] < 1e3, "JL non-singular"))
        if grav:
            print(f"  (c) gravity: worst |f| / force limit (aim <= {FORCE_AIM}):")
            for i, c in enumerate(cyls):
                rng = tuple(v / 1e3 for v in force_limits(c))
                print(f"      {c['name']:16s} {r['worst'][i]:.3f} at q = {np.round(r['worst_q'][i], 3)}"
                      f"  range [{rng[0]:.0f}, {rng[1]:.0f}] kN  " + verdict(r["worst"][i] <= FORCE_AIM, "margin"))
            print("  (d) hydraulic natural frequency sqrt(k/m_eff)/2pi, k = beta (A_A^2/V_A + A_B^2/V_B):")
            for i, c in enumerate(cyls):
                print(f"      {c['name']:16s} {r['fn_cyl'][0][i]:5.2f} .. {r['fn_cyl'][1][i]:5.2f} Hz")
            print(f"      coupled modes of D^-1 JL^T K JL: {r['fn_mode'][0]:.2f} .. {r['fn_mode'][1]:.2f} Hz")

    # --- (e) references
    for name, spec in REFERENCES.items():
        r = check_reference(model, data, cyls, neutral, spec)
        print(f"\n(e) {name}: {spec['duration']} s, terms {spec['terms']}, friction {'each cylinder' + chr(39) + 's table' if spec['friction'] else 'none'}")
        print(f"    q range: {np.round(r['q'][0], 3)} .. {np.round(r['q'][1], 3)} rad  "
              + verdict(np.all(r["q"][0] >= WORKSPACE[:, 0] - 1e-9) and np.all(r["q"][1] <= WORKSPACE[:, 1] + 1e-9),
                        "inside the proposed workspace"))
        print(f"    {'cylinder':16s} {'l min':>7s} {'l max':>7s} {'|f|/lim':>8s} {'v max':>7s} "
              f"{'q_l max':>9s} {'|u| max':>8s}")
        for i, c in enumerate(cyls):
            good = (c["stroke"][0] <= r["l"][0][i] and r["l"][1][i] <= c["stroke"][1]
                    and r["ratio"][i] <= 1.0 and r["umax"][i] <= U_MAX)
            print(f"    {c['name']:16s} {r['l'][0][i]:7.4f} {r['l'][1][i]:7.4f} {r['ratio'][i]:8.3f} "
                  f"{r['vmax'][i]:6.3f}  {r['qmax'][i]:6.0f} L/min {r['umax'][i] * 1e3:5.2f} mm  "
                  + verdict(good, f"stroke, force range, u <= {U_MAX * 1e3:.0f} mm"))
        print(f"    net pump flow max {r['pump']:.0f} L/min (Cat 320: {PUMP_FLOW:.0f})  "
              + verdict(r["pump"] <= PUMP_FLOW, "within the pumps"))

    print("\nALL CHECKS PASS" if ok else "\nSOME CHECKS FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
