"""smoke: a tiny study that trains and scores in seconds, for the runner's tests."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from softflow import data, training
from softflow.profiles import Profile, TrainConfig
from softflow.studies.study import training_spec

SMOKE_DATA = Profile("smoke", n_episodes=20, episode_seconds=1.0)  # 16 / 2 / 2 episodes: train / val / test


def cells(profile_name: str) -> list[dict]:
    return [dict(study="smoke", model="mlp", hidden=16, seed=seed, condition="tiny") for seed in (0, 1)]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> dict:
    """A tiny MLP on a tiny dataset, scored per step on the test episodes: seconds per cell,
    the same for every profile (it tries the machinery, not the science)."""
    dataset = data.load_dataset(SMOKE_DATA, data_dir=workdir / "data", progress=False)  # shared; safe to race
    config = _config(cell["seed"])
    model, checkpoint = training.train(
        cell["model"],
        dataset,
        config,
        workdir / "models" / f"{key}.pt",
        model_kwargs={"hidden": cell["hidden"]},
        device=device,
        progress=False,
    )
    n_steps = dataset.u.shape[1]
    episodes, steps = np.repeat(dataset.test, n_steps), np.tile(np.arange(n_steps), len(dataset.test))
    window = torch.as_tensor(data.gather_windows(dataset.states, episodes, steps, model.context), dtype=torch.float32)
    with torch.no_grad():
        u_hat = model.predict(window).numpy()
    return dict(
        best_val=float(checkpoint["best_val"]),
        epochs_run=int(checkpoint["epochs_run"]),
        u_rmse=float(np.sqrt(np.mean((u_hat - dataset.u[episodes, steps]) ** 2))),
    )


def _config(seed: int) -> TrainConfig:
    return TrainConfig(epochs=2, steps_per_epoch=20, batch_size=64, warmup_steps=5, val_samples=200, seed=seed)


def models(cell: dict, profile_name: str) -> dict:
    return training_spec(
        cell["model"], replace(SMOKE_DATA, train=_config(cell["seed"])), {"hidden": cell["hidden"]}, cell["seed"]
    )
