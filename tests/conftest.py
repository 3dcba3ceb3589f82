import numpy as np
import pytest

import hydrogen


@pytest.fixture(scope="session")
def model():
    return hydrogen.load_model()


@pytest.fixture(scope="session")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("hydrogen-cache")


@pytest.fixture(scope="session")
def dyn(model, cache):
    return hydrogen.build(model, cache=cache)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def workspace_poses(model, n, rng, scale=1.0):
    """Random poses around neutral within the paper's trajectories' range (±5 cm, ±0.15 rad)."""
    dq = rng.uniform(-1, 1, (n, 6)) * np.array([0.05, 0.05, 0.05, 0.15, 0.15, 0.15]) * scale
    return model.neutral_pose + dq
