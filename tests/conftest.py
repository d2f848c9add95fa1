"""Fixtures shared across test files: one small dataset and each model trained once per
session (with ``--dist loadfile`` once per worker), never in the repository's folders."""

import pytest
from small_runs import QUICK, QUICK_SEQUENCE, SMALL

from softflow import data, training
from softflow.models.specs import model_spec
from softflow.profiles import SEQUENCE_MODELS


@pytest.fixture(scope="session")
def dataset(tmp_path_factory):
    """24 episodes of 2 s on the simulation rod: enough to learn, seconds to make."""
    return data.load_dataset(SMALL, data_dir=tmp_path_factory.mktemp("data"), progress=False)


@pytest.fixture(scope="session")
def trained(dataset, tmp_path_factory):
    """trained(name) -> (model, checkpoint) of a model trained on ``dataset`` with QUICK
    (QUICK_SEQUENCE for the sequence models); the models it requires are trained first, each
    model once per session."""
    folder = tmp_path_factory.mktemp("models")

    def get(name):
        dependencies = {dep: get(dep)[0] for dep in model_spec(name).requires}
        config = QUICK_SEQUENCE if name in SEQUENCE_MODELS else QUICK
        return training.train(name, dataset, config, folder / f"{name}.pt", dependencies=dependencies, progress=False)

    return get
