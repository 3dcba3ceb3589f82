import os
from pathlib import Path

import numpy as np
import pytest

import hydrogen

#: Every robot the toolkit ships: tests that take ``robot_model``/``robot_dyn`` run on each.
MODELS = tuple(hydrogen.models())


@pytest.fixture(scope="session")
def model():
    """The Stewart platform (the paper's demonstration)."""
    return hydrogen.load_model()


def plant_inputs(model, friction=(0.0, 0.0, 1e-3), valve=(0.0, 0.0, 0.7)):
    """The plant function's inputs ``friction`` and ``valve`` for ``model``, every actuator alike:
    ``friction`` (F_c, b, v_s) without seal terms, as long as the robot's input is (six numbers per
    actuator with seal friction, else three); ``valve`` (lag s, ω rad/s, ζ) with each actuator's
    datasheet geometry (overlap, full opening m), none without one."""
    from hydrogen.plant import friction as law
    per = law.row(*friction)[:len(law.parameters_of(model.seal_friction))]
    geometry = [(c.valve["overlap"], c.valve["full_opening"]) if c.valve else (0.0, 0.0) for c in model.cylinders]
    return np.tile(per, model.n_cylinders), np.concatenate([[*valve, *g] for g in geometry])


#: Table I's orifice constant and underlap of the Stewart platform's valves (the shipped description
#: rates them as a datasheet valve that gives back these).
TABLE_I_VALVE = {"flow_gain": 1.5e-4, "underlap": 55.4e-6}


def plain_stewart_data() -> dict:
    """ubc_stewart's description data with Table I's valve constants in [hydraulics] instead of its
    datasheet valve, and without its legs' seal friction table: the plant to which the valve and seal
    tests add one part at a time."""
    import tomllib

    from hydrogen.model import model_path
    data = tomllib.loads(model_path("ubc_stewart").read_text())
    data["hydraulics"].pop("valve", None)
    data["hydraulics"].pop("friction", None)
    data["hydraulics"].update(TABLE_I_VALVE)
    return data


@pytest.fixture(scope="session")
def plain_stewart():
    """:func:`plain_stewart_data` as a Model."""
    from hydrogen.model import model_from_dict
    return model_from_dict(plain_stewart_data(), "plain_stewart.toml")


@pytest.fixture(scope="session")
def plain_stewart_dyn(plain_stewart, cache):
    return hydrogen.build(plain_stewart)


@pytest.fixture(scope="session")
def cache(tmp_path_factory):
    """The run's one build cache, new each run: every library and extension is built once per run.
    Under pytest-xdist (``-n``) the workers share it: each worker's base folder is a child of the
    run's, and the build locks let one worker build while another waits for that build."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    folder = root / "hydrogen-cache"
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(scope="session", autouse=True)
def _one_cache_per_run(cache):
    """``$HYDROGEN_CACHE_DIR`` is the session cache for the whole run: ``build()`` without ``cache=``,
    ``simulate(model=...)``, the CLI and child processes find the libraries the fixtures built,
    instead of building each again into the user's default cache. Tests of cache behaviour pass
    their own folder (or set the variable themselves)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HYDROGEN_CACHE_DIR", str(cache))
        yield


def warm_copy(cache, folder):
    """``folder`` as a private cache holding a copy of the session cache's builds: a test of cache
    behaviour that needs a warm cache of its own gets one without compiling again."""
    import shutil

    for part in ("build", "extension"):
        if (cache / part).is_dir():
            shutil.copytree(cache / part, folder / part, dirs_exist_ok=True,
                            ignore=shutil.ignore_patterns("*.lock", "*-lock.owner", "tmp*"))
    return folder


@pytest.fixture(scope="session")
def shared_fmu(cache):
    """``shared_fmu(dyn, part, scenario, controller, **kw)``: the FMU ``export_fmu`` writes for these
    arguments, exported once per run into the run's cache (the workers share it: the first exports
    under a lock, the others find the file). Tests only read it."""
    import hashlib
    import json

    from hydrogen.fileio import locked
    from hydrogen.fmu import export_fmu

    def get(dyn, part, scenario, controller, **kw):
        key = json.dumps([dyn.model.name, dyn.model.baked_hash(), repr(dyn.model.gains), str(dyn.library.path),
                          part, scenario, controller, sorted(kw.items())], default=repr)
        folder = cache / "fmu" / hashlib.sha256(key.encode()).hexdigest()[:24]
        path = folder / f"{part}.fmu"
        with locked(folder):
            if not path.exists():
                export_fmu(path, part, scenario, controller, dyn=dyn, **kw)
        return path
    return get


@pytest.fixture(scope="session")
def pump_dyn(cache, tmp_path_factory):
    """The mixed arm (a three-way shoulder, a four-way elbow) on a small pump with an accumulator
    (tests/test_supply.py's PUMP_TABLE): a robot whose supply pressure is a plant state."""
    from test_model import mixed_arm_text
    from test_supply import PUMP_TABLE
    path = tmp_path_factory.mktemp("pump") / "pump_arm.toml"
    path.write_text(mixed_arm_text("four_way") + PUMP_TABLE)
    return hydrogen.build(hydrogen.load_model(path), cache=cache)


@pytest.fixture(scope="session")
def dyn(model, cache):
    return hydrogen.build(model, cache=cache)


@pytest.fixture(scope="session", params=MODELS)
def robot_model(request):
    return hydrogen.load_model(request.param)


@pytest.fixture(scope="session")
def robot_dyn(robot_model, cache):
    return hydrogen.build(robot_model, cache=cache)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def coordinate_scale(model) -> np.ndarray:
    """Half-width of the test workspace per coordinate: 5 cm for lengths, 0.15 rad for angles."""
    return np.array([0.05 if u == "m" else 0.15 for u in model.coordinate_units])


def workspace_poses(model, n, rng, scale=1.0):
    """Random poses around neutral (±5 cm, ±0.15 rad, times ``scale``)."""
    dq = rng.uniform(-1, 1, (n, model.n)) * coordinate_scale(model) * scale
    return model.neutral_pose + dq


def random_theta(model, rng, spread=0.5):
    """The true adapted parameters, each scaled by a factor in [1 − spread, 1 + spread]."""
    return model.theta * rng.uniform(1 - spread, 1 + spread, model.n_theta)


@pytest.fixture
def package_copy(tmp_path, monkeypatch):
    """hydrogen's derivation code copied under ``tmp_path/package``, which the derivation hashes then
    read: an edit of the copy is an edit of hydrogen as far as staleness goes (the code run stays
    the installed one)."""
    import shutil

    import hydrogen.codegen.generate as gen

    pkg = Path(gen.__file__).resolve().parent.parent
    copy = tmp_path / "package"
    copy.mkdir()
    for name in (*gen.DERIVATION_FILES, *gen.DRIVER_FILES):
        shutil.copy(pkg / name, copy / name)
    for sub in (*gen.DERIVATION_DIRS, *gen.DRIVER_DIRS):
        shutil.copytree(pkg / sub, copy / sub)
    monkeypatch.setattr(gen, "_PACKAGE", copy)
    return copy


def run_in_a_copy(cache, root, files: dict, script: str, args=(), parts=("hydrogen", "templates")) -> dict:
    """hydrogen's ``parts`` copied under ``root`` with ``files`` written into the copy (path relative to
    ``root``: text), then ``script`` run there in a fresh process (the copy's package first on the path,
    then tests/; a private cache warm with the session's builds: :func:`warm_copy`) with ``args`` (a
    "{cache}" in them: that cache's path); returns the JSON its last line prints."""
    import json
    import shutil
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[1]
    ignore = shutil.ignore_patterns("__pycache__", "*.so", "_templates")
    for part in parts:
        shutil.copytree(repo / part, root / part, ignore=ignore)
    for rel, text in files.items():
        (root / rel).write_text(text)
    (root / "run.py").write_text(script)
    own = warm_copy(cache, root / "cache")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(repo / "tests")]), "HYDROGEN_CACHE_DIR": str(own)}
    proc = subprocess.run([sys.executable, str(root / "run.py"), *(a.format(cache=own) for a in args)], cwd=root,
                          env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])
