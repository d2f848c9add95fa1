"""The small dataset and training budgets the tests use, and how a ci cell recomputed here is
compared with its shipped rows. A module of its own, not conftest.py: notebooks/ has a conftest.py
too, and a test session that collects both holds only one module named conftest."""

import dataclasses

import numpy as np
import pandas as pd

from softflow import profiles
from softflow.profiles import Profile, TrainConfig

SMALL = Profile("small", n_episodes=24, episode_seconds=2.0)
QUICK = TrainConfig(epochs=3, steps_per_epoch=100, batch_size=256, warmup_steps=20, val_samples=2000, patience=3)
# The sequence models' steps cost 4x an MLP's per window: a quarter of the batch learns the held-out
# transitions as well here (LSTM 0.018, Transformer 0.014 of their variance, against 0.016 and 0.012
# at 256) in a third of the CPU time (14 s against 45 s).
QUICK_SEQUENCE = dataclasses.replace(QUICK, batch_size=64)
RUN_FACTS = ("cell_seconds", "train_minutes", "machine")  # wall times and the CPU: the run's, not the result


def assert_like_shipped(rows: pd.DataFrame, shipped: pd.DataFrame) -> None:
    """A ci cell's rows, recomputed with its models trained here, against its shipped rows:
    text columns equal, numbers at 1e-3 (a model's weights differ in the last bits across CPUs
    and training carries that on; 1e-3 is what the ci notebooks print, which agrees across
    machines), wall times and the machine left out."""
    assert len(rows) == len(shipped)
    for column in rows.columns.difference(RUN_FACTS):
        if pd.api.types.is_numeric_dtype(rows[column]):
            np.testing.assert_allclose(
                rows[column].to_numpy(float), shipped[column].to_numpy(float), rtol=1e-3, atol=1e-6, err_msg=column
            )
        else:
            assert rows[column].astype(str).tolist() == shipped[column].astype(str).tolist(), column


def report_profile(tmp_path, monkeypatch) -> Profile:
    """A profile whose figures folder is under ``tmp_path``: the report reads its files and rows there."""
    monkeypatch.setattr(profiles, "REPO", tmp_path)
    profile = Profile("report-test", n_episodes=1)
    profile.output_dir.mkdir(parents=True)
    return profile


def write_sweep(profile: Profile, study: str, rows: pd.DataFrame) -> None:
    """A study's rows where the report reads them (as figures/sweeps/<study>-paper.csv ships)."""
    (profile.output_dir / "sweeps").mkdir(exist_ok=True)
    rows.to_csv(profile.output_dir / "sweeps" / f"{study}-{profile.name}.csv", index=False)
