"""The command line (hydrogen/cli.py): options shared by the commands that build the model."""
import json
from concurrent.futures import ThreadPoolExecutor

import pytest

import hydrogen
from hydrogen.cli import main as cli
from hydrogen.errors import HydrogenError
from hydrogen.runtime.build import DEFAULT_DYNAMICS

#: Every command that builds the model, with the arguments it needs to reach the build.
BUILDING = [["simulate", "--duration", "0.1"], ["simulate", "--duration", "0.1", "--seeds", "2"],
            ["figures", "--out", "{tmp}/figs"], ["tune", "--controller", "p"], ["tune-p"], ["margins"],
            ["export", "--out", "{tmp}/c"], ["export", "--format", "fmu", "--part", "plant", "--out", "{tmp}/p.fmu"],
            ["identify", "{tmp}/log.csv"]]


@pytest.mark.parametrize("argv", BUILDING, ids=lambda a: " ".join(a[:3]))
@pytest.mark.parametrize("numbers", ["constants", "inputs", None])
def test_numbers_reaches_the_build_of_every_command(argv, numbers, tmp_path, monkeypatch, capsys):
    """``--numbers`` is an option of every command that builds, and the build gets it (default: the
    build's own default); the build is stopped at once here, before any run."""
    import hydrogen.runtime.build as build_mod
    from hydrogen.codegen.generate import DEFAULT_NUMBERS

    (tmp_path / "log.csv").write_text("t,l0,pc0\n0,1,1\n0.001,1,1\n")
    asked = []

    def stop(model=None, **kw):
        asked.append(kw.get("numbers", DEFAULT_NUMBERS))
        raise HydrogenError("build stopped by the test")
    monkeypatch.setattr(build_mod, "build", stop)
    DEFAULT_DYNAMICS.clear()
    args = [a.format(tmp=tmp_path) for a in argv] + ([] if numbers is None else ["--numbers", numbers])
    assert cli(args) == 2
    assert "build stopped by the test" in capsys.readouterr().err
    assert asked == [numbers or DEFAULT_NUMBERS]


def test_simulate_numbers_constants_builds_a_folded_library(tmp_path, monkeypatch, capsys):
    """``simulate --numbers constants`` runs on a library with the numbers folded: its cache folder is
    keyed by the baked model, its manifest has no numbers list; runs over seeds build as it did."""
    from hydrogen.codegen.generate import read_manifest
    from hydrogen.runtime.build import generated_dir_for

    model = hydrogen.load_model()
    monkeypatch.setattr("hydrogen.runtime.build.repo_generated_dir", lambda: tmp_path / "no-committed-code")
    cache = tmp_path / "cache"
    monkeypatch.setenv("HYDROGEN_CACHE_DIR", str(cache))
    out = tmp_path / "m.json"
    assert cli(["simulate", "--scenario", "z-1hz", "--controller", "p", "--duration", "0.1", "--numbers",
                "constants", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["sim_time_s"] > 0
    folded = generated_dir_for(model, cache, "constants")
    assert folded.name.startswith(f"{model.name}-{model.baked_hash()[:16]}-")
    assert "numbers" not in read_manifest(folded)
    assert [p.name for p in (cache / "generated").iterdir() if not p.name.startswith(".")] == [folded.name]

    # runs over seeds: the workers build the way the dynamics they were given were built
    dyn = hydrogen.build(model, cache=cache, numbers="constants")
    assert dyn.library.numbers is None
    DEFAULT_DYNAMICS.clear()
    with ThreadPoolExecutor(1) as pool:  # in this process: its per-process builds can be read
        res = hydrogen.simulate("z-1hz", "p", dyn=dyn, duration=0.1, seeds=2, executor=pool)
    assert not res.failures and set(DEFAULT_DYNAMICS) == {(model.baked_hash(), "constants")}
    assert DEFAULT_DYNAMICS[(model.baked_hash(), "constants")].numbers is None


def test_generate_writes_your_own_description_beside_it_not_into_the_package(tmp_path, capsys):
    """Without --out, a shipped robot's folder is the package's generated/<name>; your own description's
    is generated/<name> beside it (on an installed package the former default wrote into site-packages)."""
    import shutil

    from hydrogen.cli import main
    from hydrogen.model import model_path
    from hydrogen.runtime.build import repo_generated_dir

    mine = tmp_path / "mine.toml"
    shutil.copy(model_path("ubc_stewart"), mine)
    assert main(["generate", "--model", str(mine), "--check"]) == 1  # nothing generated there yet
    assert f"generated code in {tmp_path / 'generated' / 'ubc_stewart'} is stale" in capsys.readouterr().err
    assert main(["generate", "--model", "ubc_stewart", "--check"]) == 0
    assert f"{repo_generated_dir() / 'ubc_stewart'}: up to date" in capsys.readouterr().out


@pytest.mark.parametrize("extra, quick", [((), True), (("--optimized",), False), (("--seeds", "2"), False)])
def test_simulate_builds_quick_for_one_run_only(monkeypatch, extra, quick):
    """One run builds quick (what is not compiled yet at -O0, the optimized compile in the background);
    --optimized and --seeds (many runs) wait for the optimized build."""
    seen = {}

    class Built(Exception):
        pass

    def build(model, **kwargs):
        seen.update(kwargs)
        raise Built

    monkeypatch.setattr(hydrogen, "build", build)
    with pytest.raises(Built):
        cli(["simulate", "--duration", "0.1", *extra])
    assert seen["quick"] is quick


def test_an_interrupt_is_one_line_and_status_130(monkeypatch, capsys):
    """Ctrl-C during a build (here: the build raises KeyboardInterrupt) ends with one line, no traceback."""
    def build(model, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(hydrogen, "build", build)
    assert cli(["simulate", "--duration", "0.1"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "hydrogen simulate: interrupted"


@pytest.mark.parametrize("extra", [(), ("--format", "fmu", "--part", "plant")])
def test_export_reports_its_build(monkeypatch, tmp_path, extra):
    """hydrogen export builds (or waits for a compile) with its stages on stderr, never in silence."""
    from hydrogen.progress import print_event
    seen = {}

    class Built(Exception):
        pass

    def default_dynamics(model=None, **kwargs):
        seen.update(kwargs)
        raise Built

    import hydrogen.runtime.build as build
    monkeypatch.setattr(build, "default_dynamics", default_dynamics)
    with pytest.raises(Built):
        cli(["export", "--out", str(tmp_path / "out.fmu" if extra else tmp_path / "out"), *extra])
    assert seen["progress"] is print_event


def test_generate_never_rewrites_the_installed_packages_own_code(monkeypatch, tmp_path, capsys):
    """Installed from a wheel, a shipped robot's generated code is the package's (hydrogen/_generated):
    ``generate --force`` there is refused (status 2, naming --out), and without it a current folder is
    reported up to date with nothing written (no lock file either)."""
    import shutil

    import hydrogen.cli as cli_module
    import hydrogen.runtime.build as build
    import hydrogen.resources as resources

    package = tmp_path / "site-packages" / "hydrogen"  # an installed copy: its generated code inside it
    installed = package / "_generated"
    shutil.copytree(build.repo_generated_dir() / "excavator_arm", installed / "excavator_arm")
    before = {p: p.read_bytes() for p in installed.rglob("*") if p.is_file()}
    monkeypatch.setattr(resources, "package_dir", lambda: package)
    monkeypatch.setattr(build, "repo_generated_dir", lambda: installed)
    assert cli_module._in_installed_package(installed / "excavator_arm")
    for args in (["--force"], ["--out", str(installed / "excavator_arm"), "--force"]):
        assert cli(["generate", "--model", "excavator_arm", *args]) == 2
        err = capsys.readouterr().err
        assert "installed package's own generated code" in err and "--out DIR" in err and "Traceback" not in err
    assert cli(["generate", "--model", "excavator_arm"]) == 0
    assert "up to date" in capsys.readouterr().out
    assert {p: p.read_bytes() for p in installed.rglob("*") if p.is_file()} == before
