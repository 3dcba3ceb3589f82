import numpy as np
import pytest

import hydrogen

#: Every robot the toolkit ships: tests that take ``robot_model``/``robot_dyn`` run on each.
MODELS = tuple(hydrogen.models())


@pytest.fixture(scope="session")
def model():
    """The Stewart platform (the paper's demonstration)."""
    return hydrogen.load_model()


@pytest.fixture(scope="session")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("hydrogen-cache")


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
