"""Cheap checks of the benchmark suite (benchmarks/): every module loads, the helpers give what each
robot needs, and the comparisons of bench_release and the partial profiles of bench_scaling read
right. The benchmarks themselves (minutes each) run with ``hydrogen bench``."""
import importlib
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.bench import SUITE
from hydrogen.simulation.scenarios import actuator_settings, scenario, scenario_names

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(BENCH))

import bench_release  # noqa: E402
import bench_scaling  # noqa: E402
import common  # noqa: E402


@pytest.mark.parametrize("name", [n for n, _ in SUITE])
def test_every_suite_module_loads(name):
    if not (BENCH / f"{name}.py").is_file():
        pytest.skip(f"{name} is not in this checkout")
    mod = importlib.import_module(name)
    assert callable(mod.run) and callable(mod.print_table)


def test_robots_lists_every_shipped_model_default_first():
    names = common.robots()
    assert sorted(names) == sorted(hydrogen.models())
    assert names[0] == hydrogen.load_model().name


def test_each_robot_has_a_simulation_scenario(robot_model):
    sim = common.sim_scenario(robot_model)
    assert sim in scenario_names(robot_model)
    assert not robot_model.scenarios[sim].get("rig", False)
    rig = common.rig_scenario(robot_model)
    assert rig is None or robot_model.scenarios[rig].get("rig") is True


def test_input_values_fit_every_generated_function(robot_dyn):
    values = common.InputValues(robot_dyn)
    for entry in robot_dyn.library.manifest["functions"]:
        for (name, vals), (_, r, c) in zip(values.function_inputs(entry), entry["inputs"]):
            assert vals.shape == (int(r) * int(c),), (entry["name"], name)
            assert np.all(np.isfinite(vals)), (entry["name"], name)
    # the controllers' inputs are what the simulator gives them, not random numbers
    entry = next(e for e in robot_dyn.library.manifest["functions"] if e["name"] == "ctrl_backstepping")
    got = dict(values.function_inputs(entry))
    np.testing.assert_array_equal(got["theta"], robot_dyn.model.theta)
    np.testing.assert_array_equal(got["gamma1"], robot_dyn.model.gamma[0])
    np.testing.assert_array_equal(got["numbers"], robot_dyn.numbers)  # the description's, not random


def test_the_loop_benchmarks_slower_routes_run_the_python_loop(model, dyn):
    """bench_loop's CasADi and lambdify routes stand in for the compiled functions in the Python
    loop (the controller runtime takes their argument names and shapes); both follow the compiled
    functions' run."""
    import bench_loop
    functions = bench_loop.derive_functions(model)
    _, ref = bench_loop.python_loop_per_period(dyn, "z-1hz", 3)
    for kind in ("casadi", "lambdify"):
        proxy = bench_loop.proxy_dynamics(model, kind, functions, compiled=dyn.library)
        _, q = bench_loop.python_loop_per_period(proxy, "z-1hz", 3)
        np.testing.assert_allclose(q, ref, rtol=0, atol=1e-9, err_msg=kind)


def test_the_calls_benchmark_agrees_with_the_c_and_times_every_route():
    import bench_calls

    res = bench_calls.run(quick=True)  # asserts each route's result against the C through CasADi
    for name, routes in res["per_call"].items():
        assert {"extension", "ctypes", "casadi_external"} <= set(routes), name
        assert all(r["min_s"] > 0 for r in routes.values()), name


@pytest.mark.parametrize("n", range(2, 8))
def test_scaling_chain_loads_with_a_well_conditioned_jl(n):
    from hydrogen.tree import cylinder_jacobian, cylinder_lengths

    model = bench_scaling.chain_model(n)  # model_from_dict checks strokes and JL at the neutral pose
    assert (model.n, model.n_cylinders, model.n_theta) == (n, n, 3 * n)
    np.testing.assert_allclose(cylinder_lengths(model, model.neutral_pose), 1.0, atol=1e-12)
    J = cylinder_jacobian(model, model.neutral_pose)
    assert np.linalg.cond(J) < 1.001  # diagonal, 0.25 m lever arms (J numeric here)
    sc = scenario(bench_scaling.SCENARIO, model)
    assert len(sc.theta0_factor) == model.n_theta


def test_scaling_reports_the_stage_a_stopped_process_was_in():
    r = bench_scaling._parse("import_s 1.5\nstart kinematics\nstage kinematics 0.4\nstart rigid_body\n"
                             "start rigid_body.D\nstage rigid_body.D 0.1\nops_D 167\nstart rigid_body.C\n")
    assert r["running"] == "rigid_body.C" and r["stages"]["rigid_body.D"] == 0.1 and r["sizes"] == {"D": 167}


def test_scaling_stops_at_the_budget():
    r = bench_scaling.run_one(2, budget=0.5, quick=True)
    assert r["timed_out"] and "derive_s" not in r


def _runs_file(path, q_shift=0.0, duration=10.0, theta_scale=1.0):
    t = np.arange(5) * 1e-3
    arrays = {"s__c__t": t, "s__c__q": np.ones((5, 2)) + q_shift, "s__c__q_d": np.ones((5, 2)),
              "s__c__theta_hat": np.full((5, 3), 2.0) * theta_scale, "s__c__gamma1_hat": np.ones((5, 2)),
              "s__c__gamma2_hat": np.ones(5)}
    np.savez(str(path), **arrays)
    info = {"s__c": {"scenario": "s", "controller": "c", "error": None,
                     "fields": {"duration": duration, "noise_q": 0.0, "gains": {"c": {"Lambda": 30.0}}}}}
    Path(str(path) + ".json").write_text(json.dumps(info))
    return path


def test_release_trajectory_comparison(tmp_path):
    prev = _runs_file(tmp_path / "a.npz")
    (_runs_file(tmp_path / "b.npz"))
    assert bench_release.compare_runs(prev, tmp_path / "b.npz")["s__c"]["status"] == "ok"
    _runs_file(tmp_path / "c.npz", q_shift=1e-7)
    row = bench_release.compare_runs(prev, tmp_path / "c.npz")["s__c"]
    assert row["status"] == "FAIL" and row["max_abs_dq"] == pytest.approx(1e-7)
    _runs_file(tmp_path / "d.npz", theta_scale=1 + 1e-6)
    assert bench_release.compare_runs(prev, tmp_path / "d.npz")["s__c"]["max_rel_dtheta"] == pytest.approx(1e-6)
    _runs_file(tmp_path / "e.npz", duration=6.0)
    row = bench_release.compare_runs(prev, tmp_path / "e.npz")["s__c"]
    assert row["status"] == "scenario changed" and row["scenario_changed"] == ["duration"]


def test_release_instruction_bounds():
    prev = {"regressor": 182, "ctrl_backstepping": 3021, "plant_rhs": 1084, "valve_flow": 129}
    cur = {"regressor": 183, "ctrl_backstepping": 3031, "plant_rhs": 1200, "valve_flow": 400, "new_fn": 5}
    out = bench_release.compare_instructions(prev, cur)
    assert out["regressor"]["status"] == "FAIL"
    assert out["ctrl_backstepping"]["status"] == "ok"
    assert out["plant_rhs"]["status"] == "FAIL"
    assert out["valve_flow"]["status"] == "-" and out["new_fn"]["status"] == "new"


def test_release_compares_an_adaptive_controller_like_for_like():
    """The lean variant (the previous release's gradient law) is held to the bound against the
    previous controller; the full function (composite law) is reported, not bounded."""
    prev = {"ctrl_adaptive_robust": 3846}
    ok = bench_release.compare_instructions(prev, {"ctrl_adaptive_robust": 5637, "ctrl_adaptive_robust_lean": 3960})
    assert ok["ctrl_adaptive_robust_lean"]["status"] == "ok" and ok["ctrl_adaptive_robust_lean"]["previous"] == 3846
    assert ok["ctrl_adaptive_robust"]["status"] == "composite law (new)"
    bad = bench_release.compare_instructions(prev, {"ctrl_adaptive_robust": 5637, "ctrl_adaptive_robust_lean": 4100})
    assert bad["ctrl_adaptive_robust_lean"]["status"] == "FAIL"
    # without a lean variant the controller itself is bounded
    assert bench_release.compare_instructions(prev, {"ctrl_adaptive_robust": 5637})["ctrl_adaptive_robust"]["status"] \
        == "FAIL"


def test_release_spread_row_reads_the_loop_and_generation_ratios():
    res = {"loop_per_period": {"previous": {"us": 4.0}, "current": {"us": 5.0}, "current_gradient_law": {"us": 4.2},
                               "change": 0.25, "change_gradient_law": 0.05},
           "generation": {"ratio": 1.5}}
    row = bench_release.spread_row(res)
    assert row == {"previous_us": 4.0, "current_us": 5.0, "current_gradient_law_us": 4.2, "change": 0.25,
                   "change_gradient_law": 0.05, "generation_ratio": 1.5}


def _release_result():
    """A bench_release result whose bounds do not all hold (a trajectory and a count over)."""
    runs = {"z-1hz__p": {"scenario": "z-1hz", "controller": "p", "max_abs_dq": 1e-7, "max_rel_dtheta": 0.0,
                         "max_rel_dgamma": 0.0, "status": "FAIL", "scenario_changed": [],
                         "error_previous": None, "error_current": None}}
    instructions = bench_release.compare_instructions({"regressor": 100}, {"regressor": 120})
    return {"previous": "abc1234", "model": "ubc_stewart", "scenario": "paper-sim", "controller": "p",
            "runs": runs, "instructions": instructions,
            "loop_per_period": {"previous": {"us": 4.0, "runs": [4.0]}, "current": {"us": 5.0, "runs": [5.0]},
                                "current_gradient_law": {"us": 4.2, "runs": [4.2]}, "change": 0.25,
                                "change_gradient_law": 0.05},
            "generation": {"previous": {"process_wall_s": 1.0, "render_s": 0.5, "runs": [{}]},
                           "current": {"process_wall_s": 3.0, "render_s": 2.0, "runs": [{}]}, "ratio": 3.0},
            "other_robots": {},
            "checks": {"trajectories_within_1e-9": False, "scenarios_changed": [], "instructions": False,
                       "loop_within_10pct": False, "loop_within_10pct_gradient_law": True,
                       "generation_within_2x": False, "all_bounds_hold": False},
            "quick": True, "wall_s": 12.0}


def test_a_users_bench_reports_figures_not_the_projects_release_targets(capsys, tmp_path, monkeypatch):
    import hydrogen.bench as hb
    res = _release_result()
    bench_release.print_table(res, checks=False)
    out = capsys.readouterr().out
    assert "FAIL" not in out and "all bounds hold" not in out and "bound" not in out and ": ok" not in out
    assert "1.0e-07" in out and "+20.0" in out and "5.00 us" in out and "3.00x" in out  # the figures stay
    # the developer's release comparison still checks each bound
    bench_release.print_table(res, checks=True)
    dev = capsys.readouterr().out
    assert "all bounds hold: False" in dev and "FAIL" in dev
    # through the suite runner: figures only, in the table and the JSON, unless --release-checks
    monkeypatch.setattr(bench_release, "run", lambda quick: _release_result())
    hb.run_suite(quick=True, json_path=str(tmp_path / "b.json"), only=["bench_release"], progress=False)
    out = capsys.readouterr().out
    assert "FAIL" not in out and "all bounds hold" not in out
    written = json.loads((tmp_path / "b.json").read_text())["bench_release"]
    assert "checks" not in written and "status" not in written["instructions"]["regressor"]
    assert written["instructions"]["regressor"]["current"] == 120
    hb.run_suite(quick=True, only=["bench_release"], progress=False, release_checks=True)
    assert "all bounds hold: False" in capsys.readouterr().out


def test_bench_only_replaces_its_modules_sections_and_keeps_the_others(capsys, tmp_path, monkeypatch):
    """``bench --only M --json FILE`` on results bench wrote (a copy of docs/bench.json) replaces M's
    section only, in its place, and renders the page from the whole file."""
    from hydrogen.cli import main as cli

    docs = Path(__file__).resolve().parents[1] / "docs"
    suite = json.loads((docs / "bench.json").read_text(encoding="utf-8"))
    assert "bench_release" in suite and len(suite) > 2
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(suite), encoding="utf-8")
    monkeypatch.setattr(bench_release, "run", lambda quick: _release_result())
    assert cli(["bench", "--quiet", "--only", "bench_release", "--json", str(path)]) == 0
    written = json.loads(path.read_text(encoding="utf-8"))
    assert list(written) == list(suite)
    assert {k: v for k, v in written.items() if k != "bench_release"} == {
        k: v for k, v in suite.items() if k != "bench_release"}
    assert written["bench_release"]["instructions"]["regressor"]["current"] == 120
    assert written["bench_release"] != suite["bench_release"]
    page = (tmp_path / "benchmarks.md").read_text(encoding="utf-8")
    assert "## Side by side with the previous release" in page and "bench_loop" not in capsys.readouterr().out
    for heading in ("## The closed loop", "## Build", "## Sensitivity: "):  # the other modules' sections
        assert heading in page


def test_a_failing_module_is_named_and_the_others_results_are_kept(capsys, tmp_path, monkeypatch):
    import hydrogen.bench as hb
    from hydrogen.cli import main as cli

    import bench_edit

    monkeypatch.setattr(bench_release, "run", lambda quick: _release_result())

    def broken(quick):
        raise RuntimeError("benchmark subprocess failed (exit 1):\nthe details")

    monkeypatch.setattr(bench_edit, "run", broken)
    target = tmp_path / "b.json"
    target.write_text("{}\n")  # an earlier run's results: not overwritten by a partial one
    assert cli(["bench", "--quiet", "--json", str(target), "--only", "bench_release", "bench_edit"]) == 2
    err = capsys.readouterr().err
    assert "bench_edit: benchmark subprocess failed (exit 1)" in err and "Traceback" not in err
    assert target.read_text() == "{}\n"
    kept = json.loads((tmp_path / "b.partial.json").read_text())
    assert set(kept) == {"bench_release"} and kept["bench_release"]["instructions"]["regressor"]["current"] == 120
    with pytest.raises(hb.HydrogenError, match="bench_edit"):
        hb.run_suite(quick=True, only=["bench_edit"], progress=False)


def test_bench_json_never_writes_its_page_over_a_users_file_or_its_own_results(capsys, tmp_path, monkeypatch):
    """``--json d/x.json`` writes d/benchmarks.md: refused (exit 2, before any benchmark runs) when that
    file is not a page bench wrote, or when it is the JSON itself; a page bench wrote is replaced."""
    from hydrogen.cli import main as cli

    ran = []
    monkeypatch.setattr(bench_release, "run", lambda quick: ran.append(1) or _release_result())
    mine = tmp_path / "benchmarks.md"
    mine.write_text("# My notes on the benchmarks\n")
    argv = ["bench", "--quiet", "--only", "bench_release", "--json"]
    assert cli(argv + [str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err
    assert f"{mine}: not a page 'hydrogen bench' wrote" in err and "Traceback" not in err
    assert mine.read_text() == "# My notes on the benchmarks\n" and not (tmp_path / "x.json").exists() and not ran
    assert cli(argv + [str(mine)]) == 2
    assert "the results would be overwritten by the page rendered from them" in capsys.readouterr().err
    assert mine.read_text() == "# My notes on the benchmarks\n" and not ran
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "benchmarks.md").mkdir()  # a folder where the page goes
    assert cli(argv + [str(tmp_path / "sub" / "x.json")]) == 2 and "not a regular file" in capsys.readouterr().err
    # its own page (as a run writes it) is replaced by the next run
    own = tmp_path / "own"
    own.mkdir()
    assert cli(argv + [str(own / "x.json")]) == 0 and ran
    first = (own / "benchmarks.md").read_text()
    assert cli(argv + [str(own / "x.json")]) == 0 and (own / "benchmarks.md").read_text() == first
    assert json.loads((own / "x.json").read_text())["bench_release"]["instructions"]["regressor"]["current"] == 120
    # nor its results over a user's file: the JSON named (or its partial twin) must be results it wrote
    ran.clear()
    for name, text in (("mine.json", '{"mine": "precious"}'), ("notes.json", "not JSON"),
                       ("x.partial.json", '{"mine": 1}')):
        folder = tmp_path / f"user-{name}"
        folder.mkdir()
        (folder / name).write_text(text)
        target = folder / (name if name != "x.partial.json" else "x.json")
        assert cli(argv + [str(target)]) == 2
        assert f"{folder / name}: not results 'hydrogen bench' wrote" in capsys.readouterr().err
        assert (folder / name).read_text() == text and not ran
    assert cli(argv + [str(own / "x.json")]) == 0 and ran  # its own results are replaced


def test_bench_scaling_states_its_target_only_for_developers(capsys):
    res = {"rows": [], "not_attempted": [], "budget_s": 600.0, "cores": 2, "wall_s": 1.0,
           "target": {"n": 7, "seconds": 120.0, "measured_generate_s": 150.0, "met": False,
                      "derive_estimate_s": None}}
    bench_scaling.print_table(res, checks=False)
    out = capsys.readouterr().out
    assert "generation 150.0 s" in out and "target" not in out and "met" not in out
    bench_scaling.print_table(res, checks=True)
    assert "(target < 120 s): NOT met" in capsys.readouterr().out


@pytest.mark.parametrize("name", list(hydrogen.models()))
def test_the_edit_benchmark_edits_a_number_and_keeps_the_structure(name, tmp_path):
    import bench_edit

    from hydrogen.codegen.generate import structure_hash

    model, edited = hydrogen.load_model(name), hydrogen.load_model(bench_edit.edited_copy(name, tmp_path))
    assert edited.gravity == pytest.approx(model.gravity * 0.999, rel=1e-12)
    assert edited.baked_hash() != model.baked_hash() and structure_hash(edited) == structure_hash(model)


@pytest.mark.parametrize("name", list(hydrogen.models()))
def test_the_cold_benchmark_edits_the_structure(name, tmp_path):
    """bench_cold's copy of a shipped robot differs in structure (gravity 0), so nothing committed or
    cached serves it: its first run generates and compiles."""
    import bench_cold

    from hydrogen.codegen.generate import structure_hash

    model, edited = hydrogen.load_model(name), hydrogen.load_model(bench_cold.structural_copy(name, tmp_path))
    assert edited.gravity == 0.0 and structure_hash(edited) != structure_hash(model)


def test_the_code_edit_benchmarks_rig_part_stales_the_plant_and_drivers_alone(package_copy):
    """bench_code_edit's premise: its damper, added to the package as one module, leaves every
    committed robot current but for the plant's function and the loop drivers."""
    import bench_code_edit

    from hydrogen.codegen import generate as gen
    from hydrogen.runtime.build import repo_generated_dir

    (package_copy / "plant" / "damper.py").write_text(bench_code_edit.DAMPER)  # what add_damper writes
    for name in hydrogen.models():
        assert gen.stale_parts(hydrogen.load_model(name), repo_generated_dir() / name) == \
            {"plant": True, "drivers": True}, name


@pytest.mark.parametrize("name", list(hydrogen.models()))
def test_the_structural_benchmark_adds_a_fixed_link_and_reverses_an_axis(name, tmp_path):
    """bench_structural's edits load, keep the coordinates, and change the structure (so the first
    run generates): a payload fixed to the last link; the first moving joint turned the other way."""
    import bench_structural

    from hydrogen.codegen.generate import structure_hash

    model = hydrogen.load_model(name)
    (tmp_path / "link").mkdir()
    linked = hydrogen.load_model(bench_structural.with_fixed_link(name, tmp_path / "link"))
    assert linked.coordinate_names == model.coordinate_names and structure_hash(linked) != structure_hash(model)
    mount = next(j for j in linked.joints if j.name == "payload_mount")
    assert mount.type == "fixed" and mount.parent == model.links[-1].name
    assert sum(lk.mass for lk in linked.links) == pytest.approx(sum(lk.mass for lk in model.links)
                                                               + bench_structural.PAYLOAD_KG)
    (tmp_path / "axis").mkdir()
    toml = bench_structural.with_axis_reversed(name, tmp_path / "axis")
    moving = [j for j in model.joints if j.type in ("revolute", "prismatic")]
    assert (toml is None) == (not moving)
    if toml is not None:
        turned = hydrogen.load_model(toml)
        first = next(j for j in turned.joints if j.name == moving[0].name)
        np.testing.assert_array_equal(first.axis, -np.asarray(moving[0].axis))
        assert structure_hash(turned) != structure_hash(model)


def test_the_cold_benchmark_states_targets_only_for_developers(capsys):
    import bench_cold

    row = {"case": "leg", "process_wall_s": 20.0, "cpu_s": 30.0, "generate_s": 9.0, "core_compile_s": 2.0,
           "first_use_s": 8.0, "target_s": 30.0, "within_target": True}
    res = {"rows": [row], "controller": "adaptive-robust", "runs": 1, "wall_s": 20.0}
    bench_cold.print_table(res)
    assert "target" not in capsys.readouterr().out
    bench_cold.print_table(res, checks=True)
    assert "yes" in capsys.readouterr().out


def test_recursive_reference_equals_pinocchio_in_quick_mode():
    """bench_recursive's quick mode (n = 2 ... 4): its SX ABA, RNEA and CRBA agree with pinocchio's
    at random states, and each row has hydrogen's counts, the reference's and their ratios."""
    pytest.importorskip("pinocchio")
    import bench_recursive

    res = bench_recursive.run(quick=True)
    assert [r["n"] for r in res["rows"]] == list(bench_recursive.QUICK_NS)
    for r in res["rows"]:
        assert max(r["check_max_rel"].values()) < 1e-12, r["check_max_rel"]
        for h, k in bench_recursive.PAIRS:
            assert r["hydrogen"][h] > 0 and r["reference"][k] > 0
            assert r["ratio"][h] == pytest.approx(r["hydrogen"][h] / r["reference"][k])
        # with the numbers as inputs: the same numbers in both, the functions agree
        i = r["inputs"]
        assert i["numbers"] > 0 and i["agree"] < 1e-12, i
        for h, k in bench_recursive.PAIRS:
            assert i["ratio"][h] == pytest.approx(i["hydrogen"][h] / i["reference"][k])
    from hydrogen.pages import benchmarks_page

    page = benchmarks_page({"bench_recursive": res})
    assert "## Against the recursive algorithms" in page and "With the description's numbers as inputs" in page


def test_a_joint_axis_is_structure_with_the_numbers_as_inputs():
    """With the numbers as inputs a coordinate axis's 0 and ±1 entries stay exact (the description's
    structure holds them, as a Pinocchio joint's axis is its type): no axis entry is an input, and the
    mass matrix as inputs costs no more than folded (the chain's axes are all unit)."""
    import bench_recursive

    model = bench_scaling.chain_model(3)
    folded, inputs = (bench_recursive.hydrogen_counts(model, inputs=k) for k in (False, True))
    assert inputs["numbers"] and not [k for k in inputs["numbers"] if ".axis[" in k]
    assert inputs["counts"]["mass_matrix"] <= folded["counts"]["mass_matrix"]


def test_recursive_urdf_gives_pinocchio_the_same_chain():
    """The URDF bench_recursive hands Pinocchio's SX trace describes the chain it checks against."""
    pin = pytest.importorskip("pinocchio")
    import bench_recursive

    model = bench_scaling.chain_model(3)
    built = pin.buildModelFromXML(bench_recursive.urdf_text(model))
    ours = bench_recursive.pinocchio_model(model)
    built.gravity.linear = ours.gravity.linear
    q, v, a = np.array([1.6, -0.3, 0.4]), np.array([0.2, -1.0, 0.5]), np.array([0.3, 0.1, -0.7])
    np.testing.assert_allclose(pin.rnea(built, built.createData(), q, v, a),
                               pin.rnea(ours, ours.createData(), q, v, a), rtol=1e-12, atol=1e-9)


def test_the_period_benchmark_states_its_bound_only_for_developers(capsys):
    import bench_period

    row = {"robot": "r", "what": "loop", "name": "s", "earlier": 5.0, "folded": 5.0, "current": 6.0, "ratio": 1.2,
           "ratio_earlier": 1.2}
    res = {"baseline": "abc", "controller": "p", "rounds": 1, "bound": 1.1, "rows": [row], "wall_s": 1.0}
    bench_period.print_table(res)
    assert "FAIL" not in capsys.readouterr().out
    bench_period.print_table(res, checks=True)
    assert "FAIL" in capsys.readouterr().out


def test_the_period_benchmark_measures_every_robot_in_every_route(monkeypatch):
    """run() hands each route's measurement the robots and that route's build options: with a stand-in
    measurement, one row per robot's scenario and shared function, and an empty table is no pass."""
    import bench_period

    seen = []

    def measure(version, robots, build_kw, described=None):
        seen.append((version.label, tuple(robots), dict(build_kw), dict(described or {})))
        per = {"loops": {"s": 2.0}, "variants": {"s": "full"}, "setups": {"s": "x"}, "robot": "d",
               "calls": {"f": {"ns": 100.0, "inputs": ["q"]}}}
        return {name: per for name in robots}

    files = {"r": "earlier/r.toml"}
    monkeypatch.setattr(bench_period, "_extract_previous", lambda dest, commit: None)
    monkeypatch.setattr(bench_period, "earlier_descriptions", lambda data, dest: files)
    monkeypatch.setattr(bench_period, "_measure", measure)
    res = bench_period.run(quick=True)
    robots = tuple(common.robots())
    assert {(label, r) for label, r, _, _ in seen} == {(f"commit {bench_period.BASELINE}", robots), ("current", robots)}
    assert {"numbers": "constants"} in [kw for _, _, kw, _ in seen] and {} in [kw for _, _, kw, _ in seen]
    assert [d for _, _, _, d in seen].count(files) == bench_period.QUICK_ROUNDS  # one route on the earlier files
    assert len(seen) == 4 * bench_period.QUICK_ROUNDS
    assert len(res["rows"]) == 2 * len(robots) and res["within_bound"]
    assert all(r["ratio_described"] == 1.0 for r in res["rows"])
    monkeypatch.setattr(bench_period, "_measure", lambda version, robots, build_kw, described=None: {})
    assert not bench_period.run(quick=True)["within_bound"]


def test_the_period_benchmark_compares_with_the_baseline_and_bound_it_is_given(monkeypatch):
    """run(baseline=, bound=) extracts and labels that commit and holds the ratios against it to that
    bound; current / folded keeps its own bound."""
    import bench_period

    extracted = []

    def measure(version, robots, build_kw, described=None):
        # the earlier commit 10 % faster than every current route; folded as fast as current
        ns = 100.0 if version.label.startswith("commit ") else 110.0
        per = {"loops": {"s": ns / 50}, "variants": {"s": "full"}, "setups": {"s": "x"}, "robot": "d",
               "calls": {"f": {"ns": ns, "inputs": ["q"]}}}
        return {name: per for name in robots}

    monkeypatch.setattr(bench_period, "_extract_previous", lambda dest, commit: extracted.append(commit))
    monkeypatch.setattr(bench_period, "earlier_descriptions", lambda data, dest: {})
    monkeypatch.setattr(bench_period, "_measure", measure)
    loose = bench_period.run(quick=True, baseline="abc1234", bound=1.2)
    assert set(extracted) == {"abc1234"} and loose["baseline"] == "abc1234" and loose["bound"] == 1.2
    assert all(r["ratio_earlier"] == pytest.approx(1.1) for r in loose["rows"]) and loose["within_bound"]
    assert not bench_period.run(quick=True, baseline="abc1234", bound=1.05)["within_bound"]
    assert len(bench_period.run(quick=True, rounds=3)["rows"]) == 2 * len(common.robots())
    default = bench_period.run(quick=True)
    assert default["rounds"] == bench_period.QUICK_ROUNDS and extracted[-1] == bench_period.BASELINE
    assert default["baseline"] == bench_period.BASELINE and default["bound"] == bench_period.BOUND
    # current / folded at 1.08: within the folded bound (1.10), whatever the bound against the earlier commit
    row = {"ratio": 1.08, "ratio_earlier": 1.0, "like_for_like": True}
    assert bench_period.within_bound(row, 1.05) and not bench_period.within_bound(row, 1.05, folded_bound=1.05)


def test_the_period_benchmark_script_takes_a_baseline_and_a_bound(monkeypatch, capsys):
    """--baseline and --bound reach run(); a bound below 1 or a commit not in the repository stops the
    script before any benchmark, exit 2 and one message."""
    import bench_period

    seen = []

    def run(quick=False, baseline=bench_period.BASELINE, bound=bench_period.BOUND, rounds=None):
        seen.append((quick, baseline, bound, rounds))
        return {}

    monkeypatch.setattr(run, "__module__", "bench_period")
    args = (bench_period.__doc__, run, lambda r: None)
    assert common.script_main(*args, argv=["--quick", "--bound", "1.2"], options=bench_period.OPTIONS) == 0
    assert common.script_main(*args, argv=["--rounds", "9"], options=bench_period.OPTIONS) == 0
    assert seen == [(True, bench_period.BASELINE, 1.2, None), (False, bench_period.BASELINE, bench_period.BOUND, 9)]
    for bad, what in ((["--bound", "0.95"], "not a ratio of at least 1"), (["--bound", "nan"], "not a ratio"),
                      (["--baseline", "not-a-commit"], "not a commit"), (["--rounds", "0"], "not a number of rounds")):
        with pytest.raises(SystemExit) as exc:
            common.script_main(*args, argv=bad, options=bench_period.OPTIONS)
        assert exc.value.code == 2 and what in capsys.readouterr().err
    assert len(seen) == 2


def test_a_benchmark_script_writes_its_own_section_of_the_suites_results(tmp_path):
    """--json docs/bench.json from one module's script replaces that module's section only and renders
    the page beside it again; any other file is the module's results, whole; a page bench did not
    write stops it before anything is written."""
    from hydrogen.errors import OutputPathError

    docs = Path(__file__).resolve().parents[1] / "docs"
    suite = json.loads((docs / "bench.json").read_text(encoding="utf-8"))
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(suite), encoding="utf-8")
    new = {**suite["bench_period"], "baseline": "abc1234", "bound": 1.05}
    common.write_results(path, "bench_period", new)
    written = json.loads(path.read_text(encoding="utf-8"))
    assert written == {**suite, "bench_period": new} and list(written) == list(suite)
    page = (tmp_path / "benchmarks.md").read_text(encoding="utf-8")
    assert "commit `abc1234`" in page and "## Side by side with the previous release" in page
    own = tmp_path / "period.json"
    own.write_text(json.dumps({"baseline": "old"}), encoding="utf-8")
    common.write_results(own, "bench_period", new)
    assert json.loads(own.read_text(encoding="utf-8")) == new and not (tmp_path / "period.md").exists()
    (tmp_path / "benchmarks.md").write_text("my notes\n", encoding="utf-8")
    with pytest.raises(OutputPathError, match="benchmarks.md"):
        common.write_results(path, "bench_period", {"baseline": "other"})
    assert json.loads(path.read_text(encoding="utf-8"))["bench_period"] == new


def test_the_period_section_states_its_baseline_and_bound():
    """The page states the bounds the run was held to and names each figure above one."""
    import bench_period
    from hydrogen.pages import benchmarks_page

    row = {"robot": "r", "what": "call", "name": "f", "earlier": 100.0, "current": 103.0, "ratio_earlier": 1.03,
           "like_for_like": True, "above_bound": []}
    res = {"baseline": "abc1234", "controller": "p", "rounds": 5, "rows": [row], "within_bound": True}
    assert "Bounds where like for like" not in benchmarks_page({"bench_period": res})  # figures only
    page = benchmarks_page({"bench_period": {**res, "bound": 1.05, "bound_folded": 1.1}})
    assert ("Bounds where like for like: current / earlier and described / earlier 1.05 (within 5 % of commit "
            "`abc1234`), current / folded 1.10. This run keeps them.") in page
    slow = {**row, "name": "g", "ratio_earlier": 1.08, "ratio_described": 1.02, "described_like_for_like": True}
    slow["above_bound"] = bench_period.above_bound(slow, 1.05, 1.1)
    assert slow["above_bound"] == ["ratio_earlier"]
    page = benchmarks_page({"bench_period": {**res, "rows": [row, slow], "bound": 1.05, "bound_folded": 1.1}})
    assert "Above them in this run: r g (current / earlier 1.08)." in page


def test_the_period_benchmark_bounds_the_earlier_version_only_like_for_like(capsys):
    """current / earlier counts against the bound only with the same description and controller variant;
    the table says why a row is not like for like."""
    import bench_period

    base = {"robot": "r", "what": "loop", "name": "s", "earlier": 5.0, "folded": 6.0, "current": 6.3, "ratio": 1.05,
            "ratio_earlier": 1.26}
    same = {**base, "variants": ["full", "full"], "like_for_like": True}
    lean = {**base, "variants": ["lean", "full"], "like_for_like": False}
    other = {**base, "what": "call", "like_for_like": False}
    assert not bench_period.within_bound(same, 1.1)
    assert bench_period.within_bound(lean, 1.1) and bench_period.within_bound(other, 1.1)
    assert bench_period.unlike(lean) == "lean vs full variant"
    assert bench_period.unlike(other) == "other robot description"
    assert bench_period.unlike({**same, "like_for_like": False, "same_setup": False}) == "other rig, timing or scenario"
    assert bench_period.unlike(same) == ""
    # the current code on the earlier description: bounded unless another variant runs
    described = {**lean, "described": 6.0, "ratio_described": 1.2, "described_like_for_like": True}
    assert not bench_period.within_bound(described, 1.1)
    assert bench_period.within_bound({**described, "described_like_for_like": False}, 1.1)
    res = {"baseline": "abc", "controller": "p", "rounds": 1, "bound": 1.1, "rows": [same, lean, other], "wall_s": 1.0}
    bench_period.print_table(res, checks=True)
    lines = capsys.readouterr().out.splitlines()
    failing = [ln for ln in lines if ln.startswith("r ") and "FAIL" in ln]
    assert len(failing) == 1 and "not like for like" not in failing[0]
    assert sum("not like for like: lean vs full variant" in ln for ln in lines) == 1


def test_the_step_as_calls_computes_the_shipped_step():
    """bench_shared_step's alternative layout (the step calling the controller and its rates) is the
    same function as the shipped step, inlined: the comparison is between two routes to one result."""
    import casadi as ca

    import bench_shared_step
    from hydrogen.codegen.casadi_functions import casadi_function
    from hydrogen.codegen.generate import derive
    from hydrogen.controllers import function_name, rates_function_name, step_function_name

    model = hydrogen.load_model("loader_crane")
    by_name = {f.name: f for f in derive(model)[0]}
    kind, cache = "adaptive-robust", {}
    ctrl, rates, step = (casadi_function(by_name[namer(kind)], cache=cache)
                         for namer in (function_name, rates_function_name, step_function_name))
    shared = bench_shared_step.calls_step(step, ctrl, rates, "shared")
    assert shared.is_a("MXFunction") and list(shared.name_in()) == list(step.name_in())
    rng = np.random.default_rng(3)
    args = [rng.uniform(0.2, 0.8, step.nnz_in(i)) for i in range(step.n_in())]
    names = list(step.name_in())
    args[names.index("h")] = np.array([1e-3])
    # bounds that clip some entries, so both clips are exercised
    args[names.index("xc_lo")] = args[names.index("xc")] - 1e-6
    args[names.index("xc_hi")] = args[names.index("xc")] + 1e-6
    for a, b in zip(step.call(args), shared.call(args)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-12)
    assert float(ca.norm_inf(step.call(args)[1] - args[names.index("xc")])) > 0


def test_the_period_benchmark_migrates_renamed_keys_of_earlier_descriptions(tmp_path):
    import tomllib

    import bench_period

    data = tmp_path / "data"
    data.mkdir()
    (data / "r.toml").write_text("name = 'r'\n[rig]\ncontrol_rate = 512.0\ndelay_periods = 2\nnoise = 1\n"
                                 "[other]\ndelay_periods = 7\n[scenarios.s-1]\nduration = 1.0\n")
    files = bench_period.earlier_descriptions(data, tmp_path / "out")
    parsed = tomllib.loads(files["r"].read_text())
    # the defaults changed since stated as they were, in every table that runs a scenario
    former = bench_period.FORMER_DEFAULTS
    assert parsed["rig"] == {"control_rate": 512.0, "delay": 2 / 512.0, "noise": 1, **former}
    assert parsed["scenarios"]["s-1"] == {"duration": 1.0, **former}
    assert parsed["other"] == {"delay_periods": 7}  # only the table the key was renamed in
    assert (data / "r.toml").read_text().count("delay_periods") == 2  # the source is left as it was


def test_the_period_benchmarks_earlier_descriptions_load_with_the_current_code(tmp_path):
    """The route that runs the current code on the baseline's own descriptions needs them to load."""
    import bench_period

    if bench_period._extract_previous(tmp_path / "earlier", bench_period.BASELINE):
        pytest.skip("the baseline commit is not in this checkout")
    files = bench_period.earlier_descriptions(tmp_path / "earlier" / "hydrogen" / "data", tmp_path / "described")
    assert files
    for name, path in files.items():
        model = hydrogen.load_model(path)
        assert model.name == name
        for s in scenario_names(model):  # every scenario's rig settings, per actuator in its own unit
            settings = actuator_settings(scenario(s, model), model)
            sc = scenario(s, model)
            # as the earlier version applied them: the scenario's own to every actuator
            np.testing.assert_array_equal(settings["friction"], np.tile(sc.friction, (len(model.cylinders), 1)))
            np.testing.assert_array_equal(settings["quantization_l"], sc.quantization_l)


def test_the_period_benchmark_gives_joint_actuators_the_rigs_own_settings(tmp_path):
    """A description written before the rig's travel settings were per actuator: its rotary actuator
    gets the rig's numbers as its own, the cylinders keep the rig's; one given already is left alone."""
    import tomllib

    import bench_period

    data = tmp_path / "data"
    shutil.copytree(hydrogen.model.model_path("loader_crane").parent, data)
    toml = data / "loader_crane.toml"
    text = toml.read_text(encoding="utf-8")
    head = text.index("\n[rig.actuators.slew_motor]\n")
    toml.write_text(text[:head] + text[text.index("\n\n", head):], encoding="utf-8")
    rig = tomllib.loads(toml.read_text(encoding="utf-8"))["rig"]
    assert "actuators" not in rig
    out = tomllib.loads(bench_period.earlier_descriptions(data, tmp_path / "out")["loader_crane"].read_text())
    assert out["rig"]["actuators"] == {"slew_motor": {k: rig[k] for k in ("friction", "quantization_l", "noise_l")}}
    shipped = hydrogen.model.model_path("loader_crane")
    assert bench_period.own_rig_settings(shipped) == ""


def test_the_urdf_leg_is_timed_by_both_routes_and_edited_like_the_robots(tmp_path, monkeypatch):
    """bench_cold runs the URDF-born leg to its first backstepping run with the numbers as inputs
    (its target) and folded (shown beside it, no target); bench_edit edits its gravity like a
    shipped robot's, keeping its structure."""
    import bench_cold
    import bench_edit
    import common

    from hydrogen.codegen.generate import structure_hash

    leg = [c for c in bench_cold.cases(tmp_path) if c[1] == "urdf"]
    assert [(c[3], c[4], c[5]) for c in leg] == [(str(common.URDF_LEG), "backstepping", "inputs"),
                                                 (str(common.URDF_LEG), "backstepping", "constants")]
    assert bench_cold.TARGETS["urdf"] == 60.0
    model = hydrogen.load_model(common.URDF_LEG)
    edited = hydrogen.load_model(bench_edit.edited_copy(str(common.URDF_LEG), tmp_path))
    assert edited.gravity == pytest.approx(model.gravity * 0.999) and structure_hash(edited) == structure_hash(model)
    ran = []
    monkeypatch.setattr(bench_edit, "run_robot", lambda name, runs: ran.append(name) or {})
    assert "urdf_leg" in bench_edit.run(quick=True)["robots"] and ran[-1] == str(common.URDF_LEG)


def test_the_integrator_benchmark_tests_every_count_against_the_reference(capsys):
    """bench_integrator's quick run: each robot's first rig scenario and each of its counts (the
    scenario's own among them) against the reference, per controller and moving coordinate, with the
    cost of each count; the predictor's steps on a scenario that predicts; the table and the page."""
    import bench_integrator as bi
    from hydrogen.pages import benchmarks_page

    res = bi.run(quick=True)
    assert set(res["robots"]) == set(hydrogen.models()) and res["seeds"] == list(bi.QUICK_SEEDS)
    for name, rob in res["robots"].items():
        model = hydrogen.load_model(name)
        assert list(rob["scenarios"]) == bi.rig_scenarios(model, quick=True)
        assert list(rob["predictor"]) == bi.predicting_scenarios(model, quick=True) != []
        for key, field, tested in (("scenarios", "substeps", bi.QUICK_SUBSTEPS),
                                   ("predictor", "predictor_substeps", bi.QUICK_PRED_SUBSTEPS)):
            for s in rob[key].values():
                sc = scenario(s["scenario"], model)
                values = sorted({*tested, getattr(sc, field)})
                assert s["current"] == getattr(sc, field) and [r[field] for r in s["per_value"]] == values
                assert list(s["controllers"]) == list(model.controllers[:1])
                for r in s["controllers"].values():
                    moving = set(r["reference"])
                    assert moving and moving <= set(model.coordinate_names)
                    assert all(v["median"] <= v["worst"] for v in r["reference"].values())
                    assert [x[field] for x in r["counts"]] == values
                    assert all(x["dev"] is not None and x["dev"] >= 0 and x["keeps"] == (x["dev"] <= max(
                        bi.TOLERANCE, r["floor"])) for x in r["counts"])
                    assert r["cheapest"] in values
                    assert r["cheapest"] == bi.cheapest(values, {x[field]: x["keeps"] for x in r["counts"]})
                # the cost: plant_rhs calls per period, 4 per RK4 step of the plant and of the predictor
                for row in s["per_value"]:
                    at = sc.with_overrides(**{field: row[field]})
                    assert row["rhs_evaluations"] == 4 * (bi.plant_steps(at) + bi.predictor_steps(at)) > 0
                    assert row["rhs_instructions"] == rob["plant_rhs_instructions"] * row["rhs_evaluations"]
                    assert row["us_per_period"] > 0
                evals = [row["rhs_evaluations"] for row in s["per_value"]]
                assert evals == sorted(evals) and evals[0] < evals[-1]
    bi.print_table(res)
    out = capsys.readouterr().out
    assert out.count("cheapest that keeps every controller's errors") == sum(
        len(r["scenarios"]) + len(r["predictor"]) for r in res["robots"].values())
    page = benchmarks_page({"bench_integrator": res})
    assert "## The rig's plant integration" in page and "predictor_substeps" in page


def test_the_integrator_benchmark_counts_steps_and_picks_the_cheapest_count_that_holds():
    import bench_integrator as bi

    model = hydrogen.load_model("ubc_stewart")
    rig = scenario("z-1hz", model)  # a whole period of delay: the plant's sub-steps alone
    assert bi.plant_steps(rig) == rig.substeps and bi.predictor_steps(rig) == 0
    paper = scenario("z-1hz.low-latency", model)  # the command switches inside the period: one step more
    assert bi.plant_steps(paper) == paper.substeps + 1
    pred = scenario("z-1hz.predictor", model)
    assert bi.predictor_steps(pred) == pred.predictor_substeps
    # the smallest count from which every larger one holds, not the smallest that holds
    assert bi.cheapest([1, 2, 4, 8], {1: True, 2: False, 4: True, 8: True}) == 4
    assert bi.cheapest([1, 2], {1: True, 2: False}) is None
    ref = {"errors": {"z": [1.0, 2.0, 3.0]}, "failed": {}}
    assert bi.deviation({"errors": {"z": [1.0, 2.0, 3.05]}, "failed": {}}, ref)["dev"] == pytest.approx(0.05)
    assert bi.deviation({"errors": {"z": [1.2, 2.0, 3.0]}, "failed": {}}, ref) == pytest.approx(
        {"dev": 0.0, "paired": 0.2})  # the distribution holds, one seed moved
    assert bi.deviation({"errors": {"z": [1.0, None, 3.0]}, "failed": {"1": "diverged"}}, ref)["dev"] is None
    assert not bi._keeps(None, 1.0) and bi._keeps(0.3, 0.4) and not bi._keeps(0.3, 0.01)


def test_the_replay_benchmark_measures_the_integration_alone(capsys):
    """bench_local_error's quick run: the first rig scenario of the first robot replayed open loop at
    each count against the reference, with either way of holding the pressures; more sub-steps come
    closer to it, the cheapest count follows the rule, the table and the page."""
    import bench_integrator
    import bench_local_error as ble
    from hydrogen.pages import benchmarks_page

    res = ble.run(quick=True)
    (rob,) = res["robots"]
    (scen,) = bench_integrator.rig_scenarios(hydrogen.load_model(rob["model"]), quick=True)
    assert [(r["scenario"], r["pressure_bounds"]) for r in rob["rows"]] == [(scen, b) for b in ble.SCHEMES]
    for r in rob["rows"]:
        assert r["controller"] == ble.CONTROLLERS[0] and not r["failed"]
        lo, hi = ble.QUICK_COUNTS
        assert 0 < r["q_pts"][hi] < r["q_pts"][lo] and 0 < r["p_pa"][hi] < r["p_pa"][lo]
        assert r["cheapest"] == ble.cheapest(ble.QUICK_COUNTS, r)
    ble.print_table(res)
    assert scen in capsys.readouterr().out
    # read back from JSON (counts as text) the page renders the same cells
    page = benchmarks_page({"bench_local_error": json.loads(json.dumps(res))})
    assert "## The plant integration alone" in page and "fail" not in page.split("## The plant integration alone")[1]
    # the predictor's own integration: its first predicting scenario, more steps closer to the reference
    (prob,) = res["predictor"]["robots"]
    (r,) = prob["rows"]
    model = hydrogen.load_model(prob["model"])
    assert r["scenario"] == bench_integrator.predicting_scenarios(model, quick=True)[0] and not r["failed"]
    lo, hi = ble.QUICK_PREDICTOR_COUNTS
    assert 0 < r["q_pts"][hi] < r["q_pts"][lo] and 0 < r["p_pa"][hi] < r["p_pa"][lo]
    assert r["cheapest"] == ble.cheapest(ble.QUICK_PREDICTOR_COUNTS, r)
    assert r["predictor_substeps"] == scenario(r["scenario"], model).predictor_substeps
    assert "delay predictor's own integration" in page and r["scenario"] in page.split("delay predictor's own")[1]


def test_holding_the_pressures_at_every_stage_converges_where_a_chamber_cavitates():
    """On the crane's flow-limited cycle under P a chamber cavitates (its pressure rests on 0): clipping
    only after each RK4 step is a first-order error there (4 sub-steps 0.1 point of amplitude and more
    off 64 in the replay), clipping at every stage too keeps RK4 within 0.001 point at 4 sub-steps."""
    import bench_local_error as ble

    dyn = hydrogen.build(hydrogen.load_model("loader_crane"), controllers=("p",))
    kw = dict(counts=(4,), reference=64, duration=3.0)
    step = ble.replay_errors(dyn, "crane-flow", "p", pressure_bounds="step", **kw)
    stage = ble.replay_errors(dyn, "crane-flow", "p", pressure_bounds="stage", **kw)
    assert step["q_pts"][4] > 0.1 and stage["q_pts"][4] < 1e-3, (step, stage)


def test_the_rig_period_benchmark_runs_former_shipped_and_reference_side_by_side(capsys):
    """bench_rig_period's quick run: the first rig scenario of the first robot at the former
    integration, the shipped one and the reference, per seed in a row; the summary follows its rule,
    the table and the page render it."""
    import bench_integrator
    import bench_rig_period as brp
    from hydrogen.pages import benchmarks_page

    res = brp.run(quick=True, workers=1)
    (row,) = res["rows"]
    model = hydrogen.load_model(row["model"])
    (scen,) = bench_integrator.rig_scenarios(model, quick=True)
    sc = scenario(scen, model)
    assert row["scenario"] == scen and (row["substeps"], row["pressure_bounds"]) == (sc.substeps, sc.pressure_bounds)
    assert row["us_former"] > 0 and row["us_shipped"] > 0
    assert row["ratio"] == pytest.approx(row["us_former"] / row["us_shipped"])
    for c in row["controllers"].values():
        assert not c["failed"]
        assert c["chaotic"] == (c["paired_former"] > brp.TOLERANCE)
        assert c["keeps"] == (c["dev_shipped"] <= max(brp.TOLERANCE, c["dev_former"] if c["chaotic"] else 0.0))
    brp.print_table(res)
    assert scen in capsys.readouterr().out
    page = benchmarks_page({"bench_rig_period": json.loads(json.dumps(res))})
    assert "## The rig period" in page and f"{row['ratio']:.2f}×" in page


def test_the_rig_period_summary_judges_every_controller():
    import bench_rig_period as brp

    def runs(us, former, shipped):
        ref = {"errors": {"z": [1.0, 2.0]}, "failed": {}, "us": [1.0]}
        return {"former": {"errors": {"z": former}, "failed": {}, "us": [us]},
                "shipped": {"errors": {"z": shipped}, "failed": {}, "us": [us / 2]}, "reference": ref}

    # a: not chaotic (the former within 0.1 on every seed); b: chaotic (0.5 off on seed 0)
    s = brp.summarise({"a": runs(10.0, [1.0, 2.0], [1.05, 2.0]), "b": runs(12.0, [1.5, 2.0], [1.0, 2.2])})
    assert s["ratio"] == pytest.approx(2.0)
    assert s["chaotic"] == ["b"] and s["dev_shipped"] == pytest.approx(0.025)  # the median 1.525
    assert s["controllers"]["a"]["keeps"] and s["controllers"]["b"]["keeps"]  # b: 0.2, within the former's 0.25
    s = brp.summarise({"a": runs(12.0, [1.0, 2.05], [1.0, 2.2])})  # not chaotic: 0.2 is beyond 0.1
    assert not s["keeps"] and s["not_kept"] == ["a"] and s["dev_shipped"] == pytest.approx(0.2)
    s = brp.summarise({"b": runs(12.0, [1.5, 2.0], [1.0, 2.4])})  # chaotic, beyond the former's 0.25
    assert not s["keeps"] and s["dev_shipped_chaotic"] == pytest.approx(0.4)


def test_the_sensitivity_study_resolves_a_faster_valve_with_more_sub_steps():
    """A valve faster than the rig's sub-steps resolve is run with the fewest that do, never refused; the
    rig's own valve keeps the scenario's count."""
    import bench_sensitivity as bs

    model = hydrogen.load_model()
    sc = scenario("z-1hz", model)
    for f in bs.BANDWIDTHS:
        n = bs.resolving_substeps(sc, f)
        assert n >= sc.substeps and 2 * np.pi * f / (sc.control_rate * n) <= 1
        assert n == sc.substeps or 2 * np.pi * f / (sc.control_rate * (n - 1)) > 1
        sc.with_overrides(**bs.ELEMENTS["valve"][1](sc, f, model))  # accepted by the scenario's checks
    assert bs.resolving_substeps(sc, sc.valve_bandwidth_hz) == sc.substeps


def test_the_replay_rule_keeps_a_count_only_within_both_bounds():
    import bench_local_error as ble

    e = {"failed": {}, "noise_p": 1e4, "q_pts": {1: 0.5, 2: 5e-3, 4: 1e-5}, "p_pa": {1: 1e3, 2: 2e3, 4: 50.0}}
    assert [ble.keeps(e, n) for n in (1, 2, 4)] == [False, False, True]  # 2: 2 kPa is 20 % of the noise
    assert ble.cheapest((1, 2, 4), e) == 4
    assert ble.cheapest((1, 2, 4), {**e, "failed": {4: 10}}) is None


def test_the_python_stages_integrate_one_period_without_touching_the_state():
    """PythonStages.integrate is the plant stage's step: at the scenario's count it gives the state the
    loop moves to, and it leaves its argument alone."""
    from hydrogen.simulation.simulator import PythonStages, prepare_run

    dyn = hydrogen.build(hydrogen.load_model("excavator_arm"), controllers=("backstepping",))
    p = prepare_run(dyn, "arm-dig", "backstepping", None, 0.05, True, {}, keep_logs=False)
    loop = PythonStages(dyn, p.sc, p.ctrl, p.x0.copy(), p.q0, p.estimate, p.h)
    seen = {}
    for k in range(5):
        loop.k = k
        loop.run_period(p.noise[k], lambda s: seen.update(x=loop.x.copy(), s=s))
    x0, s = seen["x"], seen["s"]
    before = x0.copy()
    np.testing.assert_array_equal(loop.integrate(x0, s.u_held, s.u_app, p.sc.substeps), loop.x)
    np.testing.assert_array_equal(x0, before)


def test_the_delay_benchmark_gives_every_controller_at_every_delay(capsys):
    """bench_delay's quick run: the default robot's first rig scenario, every controller it lists at
    each delay (in periods, in s), with the rig's gains and the low-latency variant's where it gives
    a controller its own; median within [min, max] over the seeds; the table and the page."""
    import bench_delay as bd
    from hydrogen.pages import benchmarks_page
    from hydrogen.simulation.tuning import rig_scenarios

    model = hydrogen.load_model()
    res = bd.run(quick=True)
    assert res["seeds"] == list(bd.QUICK_SEEDS) and res["fractions"] == list(bd.QUICK_FRACTIONS)
    assert res["figure"] is None and list(res["scenarios"]) == list(rig_scenarios(model))[:1]
    own = model.variants["low-latency"]["gains"]
    for name, row in res["scenarios"].items():
        assert row["coordinates"] == list(rig_scenarios(model)[name])
        assert list(row["controllers"]) == list(model.controllers)
        period = 1.0 / scenario(name, model).control_rate
        for c, sets in row["controllers"].items():
            assert list(sets) == (["rig", "low-latency"] if c in own else ["rig"])
            for label, e in sets.items():
                assert e["gains"]["scenario"] == (name if label == "rig" else f"{name}.low-latency")
                assert e["gains"]["main_gain"] and e["gains"]["value"] > 0
                assert [p["periods"] for p in e["delays"]] == list(bd.QUICK_FRACTIONS)
                for p in e["delays"]:
                    assert p["delay_s"] == pytest.approx(p["periods"] * period)
                    assert p["completed"] + p["failed"] == len(bd.QUICK_SEEDS)
                    for k in row["coordinates"]:
                        assert p["min"][k] <= p["median"][k] <= p["max"][k]
        # the low-latency gains run what the rig's do not: other errors at the same delay
        ar = row["controllers"]["adaptive-robust"]
        assert ar["rig"]["delays"][0]["median"] != ar["low-latency"]["delays"][0]["median"]
    bd.print_table(res)
    out = capsys.readouterr().out
    for c in model.controllers:
        assert f"\n{c:20} rig " in out
    page = benchmarks_page({"bench_delay": res})
    lam = float(np.mean(own["adaptive-robust"]["Lambda"]))
    assert "## The computation delay" in page and f"| z-1hz | z | adaptive-robust | low-latency: Lambda {lam:.4g} |" in page


def test_the_sensitivity_benchmark_varies_one_rig_element_at_a_time(capsys):
    """bench_sensitivity's quick run: the default robot's first rig scenario, every controller it lists
    at each friction scale and valve frequency; friction 0 tracks better than the rig's for the
    model-based controllers (friction is unmodelled), a slower valve worse; the table and the page."""
    import bench_sensitivity as bs
    from hydrogen.pages import benchmarks_page
    from hydrogen.simulation.tuning import rig_scenarios

    model = hydrogen.load_model()
    res = bs.run(quick=True)
    assert res["seeds"] == list(bs.QUICK_SEEDS) and res["figure"] is None
    assert res["values"] == {"friction": list(bs.QUICK_FRICTION_SCALES), "valve": list(bs.QUICK_BANDWIDTHS)}
    (name,) = res["scenarios"]
    row = res["scenarios"][name]
    assert name == list(rig_scenarios(model))[0] and list(row["controllers"]) == list(model.controllers)
    coord = row["coordinates"][0]
    for c, e in row["controllers"].items():
        for element in ("friction", "valve"):
            assert [p["value"] for p in e[element]] == res["values"][element]
            for p in e[element]:
                assert p["completed"] + p["failed"] == len(bs.QUICK_SEEDS)
                assert p["min"][coord] <= p["median"][coord] <= p["max"][coord]
    for c in ("backstepping", "adaptive-robust"):
        e = row["controllers"][c]
        assert e["friction"][0]["median"][coord] < e["friction"][-1]["median"][coord]  # 0 x below 1 x the rig's
        assert e["valve"][0]["median"][coord] > e["valve"][-1]["median"][coord]  # 40 Hz above 80 Hz
    bs.print_table(res)
    assert f"\n{'adaptive-robust':20} " in capsys.readouterr().out
    page = benchmarks_page({"bench_sensitivity": res})
    assert "## Sensitivity" in page and "| friction x 0 | friction x 1 |" in page and "| valve 40 Hz |" in page


def test_the_supply_limits_benchmark_runs_the_pump_out_of_flow(capsys):
    """supply_limits' quick run: the crane on its pump in a scenario that asks more oil than the pump
    gives; the supply pressure falls below nominal on the pump and is not there on the constant supply;
    the controller fed the constant commands otherwise than the one reading the measurement; the table
    and the page."""
    import supply_limits as sl
    from hydrogen.pages import benchmarks_page

    res = sl.run(quick=True)
    assert res["seeds"] == list(sl.QUICK_SEEDS) and res["supplies"] == list(sl.SUPPLIES)
    (name,) = res["scenarios"]
    row = res["scenarios"][name]
    assert row["scenario"] == sl.ROBOTS[name]["scenario"] and row["supply"] == "compensated_pump"
    assert row["demand_peak_l_min"] > row["pump_l_min"] and 0 < row["demand_over_frac"] < 1
    for c, points in row["controllers"].items():
        by = {p["supply"]: p for p in points}
        assert list(by) == list(sl.SUPPLIES)
        for p in points:
            assert p["completed"] + p["failed"] == len(sl.QUICK_SEEDS) and p["completed"] > 0
        assert by["constant"]["ps_min_mpa"]["median"] is None  # no supply state
        for label in ("measured", "assumed"):
            assert by[label]["ps_min_mpa"]["median"] < sl.LOW * row["nominal_mpa"]  # the flow ran out
            assert by[label]["ps_low_frac"]["median"] > 0
        coord = row["coordinates"][0]
        assert by["measured"]["median"][coord] != by["assumed"]["median"][coord]
        assert by["constant"]["median"][coord] < by["measured"]["median"][coord]
    sl.print_table(res)
    assert f"\n{'backstepping':20} {'assumed':10} " in capsys.readouterr().out
    page = benchmarks_page({"supply_limits": res})
    assert "## Supply limits" in page and "| backstepping | assumed | " in page


def test_the_constant_supply_copy_drops_exactly_the_supply_table():
    import tomllib

    import supply_limits as sl
    from hydrogen.model import model_path
    text = model_path("excavator_arm").read_text()
    data = tomllib.loads(text)
    assert "supply" in data and {k: v for k, v in data.items() if k != "supply"} == tomllib.loads(sl.without_supply(text))
    body = 'name = "r"\n[supply]   # the pump\nkind = "pump"\n[supply.extra]\nx = 1\n[rig]\ndelay = 0.0\n'
    assert tomllib.loads(sl.without_supply(body)) == {"name": "r", "rig": {"delay": 0.0}}
    with pytest.raises(ValueError, match=r"\[supply\] table is not one block"):
        sl.without_supply('name = "r"\nsupply = { kind = "pump" }\n')


def test_a_study_script_writes_its_json_atomically_and_prints_its_table(tmp_path, capsys):
    """common.json_study_main: --workers reaches collect, the data is written sorted to --json, the
    Markdown of what was written is printed."""
    import common
    seen = {}

    def collect(workers):
        seen["workers"] = workers
        return {"rows": [{"b": 2, "a": 1}]}

    out = tmp_path / "study.json"
    assert common.json_study_main("A study.\n", collect, lambda d: f"| rows {len(d['rows'])} |",
                                  common.REPO / "docs" / "x.json", ["--workers", "3", "--json", str(out)]) == 0
    assert seen == {"workers": 3} and json.loads(out.read_text()) == {"rows": [{"a": 1, "b": 2}]}
    assert out.read_text().index('"a"') < out.read_text().index('"b"')  # sorted keys
    assert "| rows 1 |" in capsys.readouterr().out and not list(tmp_path.glob("*.tmp"))


def test_the_flags_benchmark_compiles_the_chains_largest_source_with_every_flag_set(monkeypatch, capsys):
    """bench_flags' chain part (a 2-link chain here): the adaptive-robust lean step compiled alone with
    each flag set, printed and on the page beside the robots' loops."""
    import bench_flags
    from hydrogen.pages import benchmarks_page

    monkeypatch.setattr(bench_flags, "CHAIN_N_QUICK", 2)
    chain = bench_flags.run_chain(quick=True)
    assert chain["n"] == 2 and chain["source"].endswith("_ctrl_adaptive_robust_lean_step.c") and chain["source_kb"] > 0
    sets = bench_flags.flag_sets()
    assert list(chain["compile_s"]) == list(sets)
    from hydrogen.runtime.compiler import Toolchain
    assert (bench_flags.GCC_DEFAULT in sets) == Toolchain().is_gcc() != (bench_flags.OTHER_DEFAULT in sets)
    assert Toolchain().flags() in sets.values()  # the compiler's defaults are measured, whichever it is
    assert all(v > 0 for v in chain["compile_s"].values())
    robots = {"r": {"model": "r", "scenario": "s", "flags": {
        k: {"cflags": list(f), "compile_s": 1.5, "loop_us_per_period": 2.5} for k, f in sets.items()}}}
    bench_flags.print_table({"robots": robots, "chain": chain})
    assert "planar chain, n = 2" in capsys.readouterr().out
    page = benchmarks_page({"bench_flags": {"robots": robots, "chain": chain}})
    assert "chain n = 2, s" in page and "| `-O2 -fPIC -std=c99 -fno-semantic-interposition` | 2.50 (1.50) |" in page
    assert "-O0" in sets[bench_flags.QUICK] and "-O2" not in sets[bench_flags.QUICK]  # a quick build's flags
    assert f"| `{' '.join(sets[bench_flags.QUICK])}` (a quick build's) | 2.50 (1.50) |" in page
    if bench_flags.GCC_DEFAULT in sets:
        assert f"| `{' '.join(sets[bench_flags.GCC_DEFAULT])}` (default) | 2.50 (1.50) |" in page
        assert "-ffp-contract=off -fno-tree-fre` (default)" in page
