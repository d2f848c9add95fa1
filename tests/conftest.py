"""Fixtures shared across test files: one small dataset and each model trained once per
session (with ``--dist loadfile`` once per worker), never in the repository's folders."""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from softflow import data, training
from softflow.models.registry import model_spec
from softflow.profiles import SEQUENCE_MODELS, Profile, TrainConfig

SMALL = Profile("small", n_episodes=24, episode_seconds=2.0)
QUICK = TrainConfig(epochs=3, steps_per_epoch=100, batch_size=256, warmup_steps=20, val_samples=2000, patience=3)
# The sequence models' steps cost 4x an MLP's per window: a quarter of the batch learns the held-out
# transitions as well here (LSTM 0.018, Transformer 0.014 of their variance, against 0.016 and 0.012
# at 256) in a third of the CPU time (14 s against 45 s).
QUICK_SEQUENCE = dataclasses.replace(QUICK, batch_size=64)
TIMES = ("cell_seconds", "train_minutes")  # wall times: the machine's, not the cell's result


def assert_like_shipped(rows: pd.DataFrame, shipped: pd.DataFrame) -> None:
    """A ci cell's rows, recomputed with its models trained here, against its shipped rows:
    text columns equal, numbers at 1e-3 (a model's weights differ in the last bits across CPUs
    and training carries that on; 1e-3 is what the ci notebooks print, which agrees across
    machines), wall times left out."""
    assert len(rows) == len(shipped)
    for column in rows.columns.difference(TIMES):
        if pd.api.types.is_numeric_dtype(rows[column]):
            np.testing.assert_allclose(
                rows[column].to_numpy(float), shipped[column].to_numpy(float), rtol=1e-3, atol=1e-6, err_msg=column
            )
        else:
            assert rows[column].astype(str).tolist() == shipped[column].astype(str).tolist(), column


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
