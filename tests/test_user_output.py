"""What a new user reads: no internal tracker numbers, per-coordinate units, estimates only of
controllers that adapt, a default scenario of the model's own, and progress on the long steps."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_no_output_names_an_internal_tracker_item():
    """Messages, templates, tests and benchmarks say what a thing is, never 'issue N'."""
    pattern = re.compile(r"issues? ?#?[0-9]", re.IGNORECASE)
    hits = []
    for folder in ("hydrogen", "tests", "benchmarks", "templates"):
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix not in (".py", ".j2", ".c", ".h", ".toml", ".txt", ".md") or not path.is_file():
                continue
            for no, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                if pattern.search(line) and path.name != Path(__file__).name:
                    hits.append(f"{path.relative_to(ROOT)}:{no}: {line.strip()}")
    assert not hits, "\n".join(hits)


# --- the simulate summary ----------------------------------------------------------------------

def test_error_lines_give_each_coordinate_its_unit_and_keep_the_columns_aligned():
    from hydrogen.summary import error_lines
    lines = error_lines(("x", "psi", "boom_angle_long"), ("m", "rad", "rad"),
                        {"x": 0.0012, "psi": 0.0345, "boom_angle_long": 0.5},
                        {"x": 2.5, "psi": None, "boom_angle_long": 123.456})
    assert lines[0].endswith(" mm") and lines[1].endswith(" mrad") and lines[2].endswith(" mrad")
    assert "1.2000 mm" in lines[0] and "34.5000 mrad" in lines[1] and "2.50 %" in lines[0]
    assert "(mm or mrad)" not in "".join(lines)
    # a coordinate the reference does not move: "-" in the % column, every column where it is elsewhere
    assert " - " in lines[1] and "%" not in lines[1]
    assert len({len(line) - len(line.split()[-1]) for line in lines}) == 1  # values end in one column
    assert len({line.index("%") for line in (lines[0], lines[2])}) == 1
    assert lines[1].index("-") == lines[0].index("%")


def _simulate_cli(capsys, *argv):
    from hydrogen.cli import main
    assert main(["simulate", "--duration", "0.05", *argv]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("controller, adapts", [("p", False), ("backstepping", False),
                                                ("adaptive-robust", True), ("adaptive-observer", True)])
def test_summary_reports_estimates_only_for_controllers_that_adapt(capsys, controller, adapts):
    out = _simulate_cli(capsys, "--controller", controller)
    assert ("theta_hat final" in out) == adapts and ("gamma_hat final" in out) == adapts
    assert "(mm or mrad)" not in out and " mm" in out and " mrad" in out


def test_estimated_blocks_come_from_the_controllers_declared_state():
    import hydrogen
    from hydrogen.controllers import controller
    model = hydrogen.load_model()
    for name, expected in (("p", ()), ("adaptive-robust", ("theta_hat", "gamma1_hat", "gamma2_hat"))):
        res = hydrogen.simulate("z-1hz", name, duration=0.02)
        blocks = [b for b, _ in controller(name).state_layout(model)]
        assert res.estimated == expected == tuple(b for b in expected if b in blocks)


def test_commands_default_to_the_models_own_first_scenario(capsys, tmp_path):
    import hydrogen
    from hydrogen.cli import build_parser
    from hydrogen.simulation.scenarios import default_scenario_name, scenario_names
    for name in hydrogen.models():
        model = hydrogen.load_model(name)
        assert default_scenario_name(model) == scenario_names(model)[0]
    assert default_scenario_name(hydrogen.load_model("excavator_arm")) == "arm-sim"
    assert build_parser().parse_args(["export", "--out", "x"]).scenario is None
    out = _simulate_cli(capsys, "--model", "excavator_arm", "--controller", "p")
    assert out.startswith("scenario arm-sim, controller p")


def test_export_defaults_to_the_models_first_scenario(tmp_path):
    import json

    from hydrogen.export import EXPORT_MANIFEST, export
    folder = export(tmp_path / "arm", controller="p", model="excavator_arm", duration=0.05)
    meta = json.loads((folder / EXPORT_MANIFEST).read_text())
    assert meta["scenario"] == "arm-sim"
