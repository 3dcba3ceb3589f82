"""The actuator registry and the physics of every kind: flows, settling, f0/g0 against the plant's
force rate, the valve inverse on every branch, equilibrium pressures, SymPy = numpy."""
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from hydrogen.actuators import KINDS, actuator
from hydrogen.actuators.declarations import state_bounds
from hydrogen.errors import ModelError

#: Each kind's example (SI), its sampled coordinate range (m or rad) and the sign of each chamber's
#: pressure rate with the valve opened the positive way: tests/data/actuators/<kind>.toml, one file a
#: kind, so a new kind's module and its example file are all the physics checks need.
EXAMPLE_DIR = Path(__file__).parent / "data" / "actuators"


def _example(kind):
    path = EXAMPLE_DIR / f"{kind}.toml"
    if not path.is_file():
        pytest.fail(f"actuator kind {kind!r} has no example {path}: add one for the physics checks")
    return tomllib.loads(path.read_text())


EXAMPLES = {k: _example(k)["parameters"] for k in KINDS}
RANGE = {k: tuple(_example(k)["range"]) for k in KINDS}
#: sign of each chamber's pressure rate with the valve opened the positive way (u > d), blocked
OPEN_POSITIVE = {k: tuple(_example(k)["open_positive"]) for k in KINDS}
#: the kinds hydrogen ships, in the order every list of kinds gives them
SHIPPED = ("three_way_cylinder", "four_way_cylinder", "rotary")
EPS = 1.0  # Pa, the controllers' pressure floor in the valve inverse


def _kind(name, **over):
    mod = actuator(name)
    return mod, mod.parameters({**EXAMPLES[name], **over})


def _bounds(mod, P):
    return state_bounds(mod.STATES, P)


def _random_state(mod, P, rng, k, margin=2e5):
    """k random coordinates, rates and pressures (each pressure ``margin`` Pa inside its bounds)."""
    lo, hi = RANGE[mod.NAME]
    x = rng.uniform(lo, hi, k)
    xdot = rng.normal(size=k) * 0.1
    p = tuple(rng.uniform(b0 + margin, b1 - margin, k) for b0, b1 in _bounds(mod, P))
    return x, xdot, p


def _branch_spools(d, rng, k):
    """k spool positions on each branch of the valve law: u < −d, |u| < d, u > d (m)."""
    return {"below": -d - rng.uniform(0.1, 50, k) * max(d, 1e-5), "inside": rng.uniform(-0.95, 0.95, k) * d,
            "above": d + rng.uniform(0.1, 50, k) * max(d, 1e-5)}


def _gamma(P):
    return P["bulk_modulus"], P["flow_gain"]


# --- the registry ---------------------------------------------------------------------------------

def test_registry_lists_the_kinds():
    assert KINDS[0] == "three_way_cylinder" and list(KINDS[1:]) == sorted(KINDS[1:])
    assert [k for k in KINDS if k in SHIPPED] == list(SHIPPED)
    for kind in KINDS:
        mod = actuator(kind)
        assert mod.NAME == kind and mod.DOC and mod.MOTION in ("prismatic", "revolute")
        assert mod.STATES and mod.SENSORS and mod.PARAMETERS
        for law in ("force", "pressure_rates", "f0", "g0", "valve_inverse", "equilibrium_pressures",
                    "force_range", "spring_rate", "f0_potential"):
            assert callable(getattr(mod.Symbolic, law)) and callable(getattr(mod.Numeric, law)), (kind, law)
    assert [s.name for s in actuator("four_way_cylinder").STATES] == ["pA", "pB"]
    assert actuator("rotary").MOTION == "revolute"


@pytest.mark.parametrize("bad", ["piston", "", None, "Three_Way_Cylinder"])
def test_unknown_kind_is_a_clear_error(bad):
    with pytest.raises(ModelError, match=r"unknown actuator kind .*; known kinds: three_way_cylinder, "
                                         r"four_way_cylinder, (.*, )?rotary"):
        actuator(bad)


def test_the_registry_finds_a_kind_module_by_itself(tmp_path, monkeypatch):
    """A module declaring NAME and Symbolic is a kind with no list to edit; a helper module is not;
    the default kind comes first, the others by name."""
    from hydrogen import actuators
    pkg = tmp_path / "fake_kinds"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    rest = "".join(f"{a} = None\n" for a in actuators.DECLARES)  # a whole kind declares each
    for mod, name in (("zeta", "zeta_kind"), ("alpha", "three_way_cylinder"), ("beta", "beta_kind")):
        (pkg / f"{mod}.py").write_text(f"NAME = {name!r}\nSymbolic = object()\n{rest}")
    (pkg / "helpers.py").write_text("NAME = 'not a kind: no laws'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import fake_kinds
    found = actuators._discover(fake_kinds.__path__, "fake_kinds")
    assert list(found) == ["three_way_cylinder", "beta_kind", "zeta_kind"]
    # a kind without MOTION and COUPLING_GAIN: refused naming them (a run met an AttributeError)
    (pkg / "half.py").write_text("NAME = 'half_kind'\nSymbolic = object()\n"
                                 + rest.replace("MOTION = None\n", "").replace("COUPLING_GAIN = None\n", ""))
    with pytest.raises(ImportError, match=r"actuator kind 'half_kind' \(fake_kinds.half\) does not declare "
                                          r"MOTION, COUPLING_GAIN"):
        actuators._discover(fake_kinds.__path__, "fake_kinds")
    (pkg / "half.py").unlink()
    (pkg / "gamma.py").write_text(f"NAME = 'zeta_kind'\nSymbolic = object()\n{rest}")
    with pytest.raises(ImportError, match=r"'zeta_kind' is declared twice"):
        actuators._discover(fake_kinds.__path__, "fake_kinds")


def test_missing_or_bad_parameter_names_it():
    data = dict(EXAMPLES["four_way_cylinder"])
    del data["annulus_area"]
    with pytest.raises(ValueError, match=r"actuator 'four_way_cylinder': parameter 'annulus_area' .* missing"):
        actuator("four_way_cylinder").parameters(data)
    with pytest.raises(ValueError, match=r"parameter 'displacement' must be a finite number .* got nan"):
        actuator("rotary").parameters({**EXAMPLES["rotary"], "displacement": float("nan")})
    # defaults fill the rest
    data = dict(EXAMPLES["rotary"])
    del data["tank_pressure"], data["underlap"]
    P = actuator("rotary").parameters(data)
    assert P["tank_pressure"] == 0.0 and P["underlap"] == 0.0


def test_numeric_layer_does_not_import_sympy():
    code = ("import sys; from hydrogen.actuators import actuator; import numpy as np\n"
            "m = actuator('four_way_cylinder'); P = m.parameters(%r)\n"
            "m.Numeric.g0(1.2, (1e6, 2e6), 1e-4, P); print('sympy' in sys.modules)" % EXAMPLES["four_way_cylinder"])
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# --- physics of every kind ------------------------------------------------------------------------

@pytest.mark.parametrize("kind", KINDS)
def test_flow_into_a_chamber_raises_its_pressure(kind):
    mod, P = _kind(kind)
    rng = np.random.default_rng(1)
    x, _, p = _random_state(mod, P, rng, 50)
    beta, c = _gamma(P)
    d = P["underlap"]
    for sign in (1, -1):
        rates = mod.Numeric.pressure_rates(x, 0 * x, p, sign * 3 * d, beta, c, P)
        for r, expected in zip(rates, OPEN_POSITIVE[kind]):
            assert np.all(np.sign(r) == sign * expected)
    # moving the actuator the positive way compresses chamber B / expands A: with the valve shut
    # (critically centred, u = 0) p_A falls and p_B rises
    Pc = {**P, "underlap": 0.0}
    rates = mod.Numeric.pressure_rates(x, np.full_like(x, 0.05), p, 0.0, beta, c, Pc)
    assert np.all(rates[0] < 0)
    if len(rates) > 1:
        assert np.all(rates[1] > 0)


@pytest.mark.parametrize("kind", KINDS)
def test_the_supply_flow_is_the_oil_the_supply_edges_pass(kind):
    """The flow a valve draws from the supply, against the oil balance of its chambers: with the
    valve open the positive way (u > d) only the supply edge into the first chamber passes oil from the
    supply (c (u + d) √(P_s − p)); the negative way, a four-way valve's edge into chamber B, a
    three-way valve's none. A three-way cylinder's rod side, at supply, takes a ẋ back."""
    mod, P = _kind(kind)
    rng = np.random.default_rng(4)
    x, _, p = _random_state(mod, P, rng, 20)
    _, c = _gamma(P)
    d, ps = P["underlap"], P["supply_pressure"]
    # drops above the plant's linear region: each edge's flow is its square root's
    p = tuple(np.minimum(pi, ps - 2 * P["orifice_linear_below"]) for pi in p)
    u = d + rng.uniform(1e-4, 1e-3, 20)
    for smooth in (True, False):
        np.testing.assert_allclose(mod.Numeric.supply_flow(x, 0 * x, p, u, c, P, smooth=smooth),
                                   c * (u + d) * np.sqrt(ps - p[0]), rtol=1e-12)
        below = mod.Numeric.supply_flow(x, 0 * x, p, -u, c, P, smooth=smooth)
        if len(mod.STATES) == 2:
            np.testing.assert_allclose(below, c * (u + d) * np.sqrt(ps - p[1]), rtol=1e-12)
        else:
            np.testing.assert_array_equal(below, 0.0)
    if kind == "three_way_cylinder":
        np.testing.assert_allclose(mod.Numeric.supply_flow(x, np.full_like(x, 0.1), p, -u, c, P),
                                   -0.1 * P["rod_area"], rtol=1e-12)


def _settle(mod, P, x, u, p0, t_end):
    beta, c = _gamma(P)
    rhs = lambda t, p: np.array(mod.Numeric.pressure_rates(x, 0.0, tuple(p), u, beta, c, P), float)  # noqa: E731
    sol = solve_ivp(rhs, (0, t_end), np.asarray(p0, float), method="BDF", rtol=1e-9, atol=1.0)
    assert sol.success
    return sol.y[:, -1]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("sign", [1, -1])
def test_blocked_actuator_with_the_valve_open_settles_at_supply_or_tank(kind, sign):
    mod, P = _kind(kind)
    lo, hi = RANGE[kind]
    bounds = _bounds(mod, P)
    p0 = [0.5 * (b0 + b1) for b0, b1 in bounds]
    p_end = _settle(mod, P, 0.5 * (lo + hi), sign * 3 * P["underlap"], p0, 20.0)
    for pj, (b0, b1), open_dir in zip(p_end, bounds, OPEN_POSITIVE[kind]):
        target = b1 if sign * open_dir > 0 else b0
        assert abs(pj - target) < 1e-4 * P["supply_pressure"], (pj, target)


@pytest.mark.parametrize("kind", KINDS)
def test_blocked_actuator_in_the_underlap_settles_at_the_equilibrium_pressures(kind):
    """With the spool held inside the underlap both flows vanish at the equilibrium pressures of the
    force the actuator settles to: the pair equilibrium_pressures chooses is the physical one."""
    mod, P = _kind(kind)
    lo, hi = RANGE[kind]
    for u_over_d in (-0.6, 0.0, 0.3):
        p_end = _settle(mod, P, 0.5 * (lo + hi), u_over_d * P["underlap"],
                        [b0 + 0.2 * (b1 - b0) for b0, b1 in _bounds(mod, P)], 60.0)
        f = mod.Numeric.force(tuple(p_end), P)
        np.testing.assert_allclose(mod.Numeric.equilibrium_pressures(f, P), p_end, rtol=1e-6)


def _force_rate_by_chain_rule(mod, P, x, xdot, p, u, beta, c, smooth):
    """ḟ = Σ_j ∂f/∂p_j ṗ_j, ∂f/∂p_j by central differences of the force law, ṗ from the plant."""
    rates = mod.Numeric.pressure_rates(x, xdot, p, u, beta, c, P, smooth=smooth)
    fdot = 0.0
    for j in range(len(p)):
        dp = 1e3
        hi = tuple(pk + (dp if k == j else 0.0) for k, pk in enumerate(p))
        lo = tuple(pk - (dp if k == j else 0.0) for k, pk in enumerate(p))
        fdot = fdot + (mod.Numeric.force(hi, P) - mod.Numeric.force(lo, P)) / (2 * dp) * rates[j]
    return fdot


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("smooth", [False, True])
def test_f0_and_g0_give_the_plants_force_rate(kind, smooth):
    mod, P = _kind(kind)
    rng = np.random.default_rng(2)
    x, xdot, p = _random_state(mod, P, rng, 40, margin=4 * P["orifice_linear_below"])  # past the linear zone
    beta, c = rng.uniform(0.5, 1.5) * P["bulk_modulus"], rng.uniform(0.5, 1.5) * P["flow_gain"]
    for u in _branch_spools(P["underlap"], rng, 40).values():
        fdot = _force_rate_by_chain_rule(mod, P, x, xdot, p, u, beta, c, smooth)
        model = beta * mod.Numeric.f0(x, xdot, p, P) + beta * c * mod.Numeric.g0(x, p, u, P)
        np.testing.assert_allclose(model, fdot, rtol=1e-7, atol=1e-9 * np.abs(fdot).max())
        # f0 is the closed-valve share and is −ẋ × the spring rate
        np.testing.assert_allclose(mod.Numeric.f0(x, xdot, p, P), -xdot * mod.Numeric.spring_rate(x, P), rtol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_f0_is_the_rate_of_its_potential(kind):
    mod, P = _kind(kind)
    rng = np.random.default_rng(3)
    x, xdot, p = _random_state(mod, P, rng, 20)
    h = 1e-6
    fd = (mod.Numeric.f0_potential(x + h * xdot, P) - mod.Numeric.f0_potential(x - h * xdot, P)) / (2 * h)
    np.testing.assert_allclose(fd, mod.Numeric.f0(x, xdot, p, P), rtol=1e-6)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("underlap", ["model", 0.0])
def test_g0_increases_in_u(kind, underlap):
    mod, P = _kind(kind, **({} if underlap == "model" else {"underlap": underlap}))
    rng = np.random.default_rng(4)
    x, _, p = _random_state(mod, P, rng, 30, margin=10.0)
    u = np.linspace(-5e-4, 5e-4, 2001)[:, None]
    g = mod.Numeric.g0(x[None, :], tuple(pj[None, :] for pj in p), u, P)
    assert np.all(np.diff(g, axis=0) > 0)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("underlap", ["model", 0.0])
def test_valve_inverse_returns_u_on_every_branch(kind, underlap):
    mod, P = _kind(kind, **({} if underlap == "model" else {"underlap": underlap}))
    rng = np.random.default_rng(5)
    x, _, p = _random_state(mod, P, rng, 200, margin=10 * EPS)  # the floor at √EPS inactive
    branches = _branch_spools(P["underlap"], rng, 200)
    if P["underlap"] == 0.0:
        del branches["inside"]
    for name, u in branches.items():
        y = mod.Numeric.g0(x, p, u, P)
        back = mod.Numeric.valve_inverse(y, x, p, P, EPS)
        np.testing.assert_allclose(back, u, rtol=1e-9, atol=1e-15, err_msg=name)


@pytest.mark.parametrize("kind", KINDS)
def test_equilibrium_pressures_give_the_force(kind):
    mod, P = _kind(kind)
    lo, hi = mod.Numeric.force_range(P)
    f = np.linspace(lo, hi, 101)
    p = mod.Numeric.equilibrium_pressures(f, P)
    np.testing.assert_allclose(mod.Numeric.force(p, P), f, rtol=1e-12, atol=1e-9 * max(abs(lo), abs(hi)))
    for pj, (b0, b1) in zip(p, _bounds(mod, P)):
        assert np.all(pj >= b0 - 1e-6) and np.all(pj <= b1 + 1e-6)
    # the ends of the range put some pressure on its bound
    assert any(np.isclose(pj[0], b, rtol=1e-12) for pj, bb in zip(p, _bounds(mod, P)) for b in bb)


# --- SymPy = numpy --------------------------------------------------------------------------------

def _symbolic_numeric_pairs(mod, P):
    x, xd, u, y, beta, c, f = sp.symbols("x xdot u y beta c f", real=True)
    p = sp.symbols(f"p0:{len(mod.STATES)}", real=True)
    S, N = mod.Symbolic, mod.Numeric
    Ps = {k: sp.Float(repr(v)) for k, v in P.items()}
    return [(x, xd, u, y, beta, c, f, *p), [
        ("force", S.force(p, Ps), lambda a: N.force(a["p"], P)),
        ("f0", S.f0(x, xd, p, Ps), lambda a: N.f0(a["x"], a["xdot"], a["p"], P)),
        ("g0", S.g0(x, p, u, Ps), lambda a: N.g0(a["x"], a["p"], a["u"], P)),
        ("inverse", S.valve_inverse(y, x, p, Ps, EPS), lambda a: N.valve_inverse(a["y"], a["x"], a["p"], P, EPS)),
        ("spring", S.spring_rate(x, Ps), lambda a: N.spring_rate(a["x"], P)),
        ("potential", S.f0_potential(x, Ps), lambda a: N.f0_potential(a["x"], P)),
        *[(f"eq{j}", e, (lambda a, j=j: N.equilibrium_pressures(a["f"], P)[j]))
          for j, e in enumerate(S.equilibrium_pressures(f, Ps))],
        *[(f"rate{j}_{s}", e, (lambda a, j=j, s=s: N.pressure_rates(a["x"], a["xdot"], a["p"], a["u"], a["beta"],
                                                                     a["c"], P, smooth=s)[j]))
          for s in (True, False) for j, e in enumerate(S.pressure_rates(x, xd, p, u, beta, c, Ps, smooth=s))],
        *[(f"supply_{s}", S.supply_flow(x, xd, p, u, c, Ps, smooth=s),
           (lambda a, s=s: N.supply_flow(a["x"], a["xdot"], a["p"], a["u"], a["c"], P, smooth=s)))
          for s in (True, False)],
    ]]


@pytest.mark.parametrize("kind", KINDS)
def test_symbolic_and_numeric_layers_agree(kind):
    mod, P = _kind(kind)
    rng = np.random.default_rng(6)
    syms, pairs = _symbolic_numeric_pairs(mod, P)
    k = 30
    x, xdot, p = _random_state(mod, P, rng, k, margin=-3e4)  # also a little outside the bounds
    beta, c = _gamma(P)
    for u in _branch_spools(P["underlap"], rng, k).values():
        args = dict(x=x, xdot=xdot, p=p, u=u, y=rng.normal(size=k) * 10.0 ** rng.uniform(-3, 3, k),
                    beta=np.full(k, beta), c=np.full(k, c), f=rng.uniform(*mod.Numeric.force_range(P), k))
        values = [args[n] for n in ("x", "xdot", "u", "y", "beta", "c", "f")] + list(p)
        for name, expr, numeric in pairs:
            fn = sp.lambdify(syms, expr, "numpy")
            np.testing.assert_allclose(np.broadcast_to(fn(*values), (k,)), numeric(args), rtol=1e-12, atol=1e-300,
                                       err_msg=f"{kind} {name}")


def test_three_way_cylinder_is_the_papers_actuator():
    """f = p_c A − P_s a, (59)'s f0, g0 and (57), and the former hydraulics names still give them."""
    from hydrogen.symbolic import hydraulics as hyd
    mod, P = _kind("three_way_cylinder")
    l, ld, pc, u = 1.8, 0.03, 4e6, 7e-5
    A, a, L, ps, d = (P[k] for k in ("piston_area", "rod_area", "chamber_length", "supply_pressure", "underlap"))
    assert mod.Numeric.force((pc,), P) == pc * A - ps * a
    assert mod.Numeric.f0(l, ld, (pc,), P) == -A * ld / (l - L)
    q_unit = (u + d) * np.sqrt(ps - pc)  # u > d: the supply orifice alone
    np.testing.assert_allclose(mod.Numeric.g0(l, (pc,), u, P), q_unit / (l - L), rtol=1e-15)
    Ps = {k: sp.Float(v) for k, v in P.items()}
    s = sp.Symbol("s", real=True)
    assert hyd.leg_force(s, Ps["supply_pressure"], Ps["piston_area"], Ps["rod_area"]) == \
        mod.Symbolic.force((s,), Ps)
    assert hyd.valve_inverse_unit(s, pc, Ps["supply_pressure"], Ps["underlap"], EPS) == \
        mod.Symbolic.flow_inverse(s, (pc,), Ps, EPS)


def test_the_derivation_hash_covers_the_actuators_a_robot_uses(package_copy):
    """An edit to an actuator module changes what is generated for a robot using the kind, so it must
    make that code stale; a robot without the kind stays current."""
    import hydrogen.codegen.generate as gen
    tmp_path = package_copy
    before = {kinds: gen.derivation_hash(kinds) for kinds in (("rotary",), ("three_way_cylinder",))}
    path = tmp_path / "actuators" / "rotary.py"
    path.write_text(path.read_text() + "\n# an edit\n")
    assert gen.derivation_hash(("rotary",)) != before[("rotary",)]
    assert gen.derivation_hash(("three_way_cylinder",)) == before[("three_way_cylinder",)]
    before = gen.derivation_hash(("three_way_cylinder",))
    path = tmp_path / "pressures.py"  # the pressure blocks shape the plant state and the controllers' inputs
    path.write_text(path.read_text() + "\n# an edit\n")
    assert gen.derivation_hash(("three_way_cylinder",)) != before
    before = gen.derivation_hash(("three_way_cylinder",))
    path = tmp_path / "actuators" / "two_chamber.py"  # shared by kinds: every robot's
    path.write_text(path.read_text() + "\n# an edit\n")
    assert gen.derivation_hash(("three_way_cylinder",)) != before


def test_a_new_kind_leaves_other_robots_code_current(package_copy, monkeypatch):
    """The module of a kind a robot does not use is outside its derivation hash: adding a kind keeps
    the committed code of the robots that do not use it current; editing it stales those that do."""
    import types

    import hydrogen.actuators as acts
    import hydrogen.codegen.generate as gen
    tmp_path = package_copy
    crane = gen.derivation_hash(("four_way_cylinder", "rotary"))
    new = tmp_path / "actuators" / "new_kind.py"
    new.write_text("NAME = 'new_kind'\n")
    monkeypatch.setattr(acts, "_REGISTRY", {**acts._REGISTRY, "new_kind": types.SimpleNamespace(__file__=str(new))})
    monkeypatch.setattr(acts, "KINDS", (*acts.KINDS, "new_kind"))
    assert gen.derivation_hash(("four_way_cylinder", "rotary")) == crane
    mine = gen.derivation_hash(("new_kind",))
    new.write_text("NAME = 'new_kind'\n# an edit\n")
    assert gen.derivation_hash(("new_kind",)) != mine
    assert gen.derivation_hash(("four_way_cylinder", "rotary")) == crane
