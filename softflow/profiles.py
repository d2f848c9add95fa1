"""Named run sizes: "ci" finishes in minutes on 2 cores, "quick" trains a usable model of your
own runs in minutes on a laptop, "paper" is the real experiment."""

from __future__ import annotations

import os
import random
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softflow.checks import check_choice
from softflow.store import REPO

SEQUENCE_MODELS = ("lstm", "transformer")  # models that read a window of past transitions


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation budget of one model (shared by every model of a profile: a fair budget)."""

    epochs: int = 30
    steps_per_epoch: int = 500
    batch_size: int = 512
    lr: float = 1e-3
    weight_decay: float = 1e-4
    warmup_steps: int = 500
    ema_decay: float | None = 0.999  # None: no EMA
    patience: int = 6  # epochs without a better validation loss before stopping
    val_samples: int = 20000
    seed: int = 0


@dataclass(frozen=True)
class Profile:
    """Every size knob of a run in one place; notebooks take only its name."""

    name: str
    n_episodes: int  # training-data episodes
    episode_seconds: float = 5.0  # s, length of one excitation episode
    bench_episodes: int = 64  # episodes timed in notebook 01's speed summary
    validation_seconds: float = 5.0  # s, notebook 01's convergence episode and energy release
    seed: int = 0
    train: TrainConfig = TrainConfig()
    # Budget of the per-step models (MLP, RF family), which run an epoch ~10x faster than the
    # sequence models: the same data, a similar wall time. None: the same as ``train``.
    per_step_train: TrainConfig | None = None
    identification_seconds: float = 3.0  # s of excitation filmed for system identification (notebook 10)
    # (rod name, budget) pairs: a rod whose models are all trained with one budget of its own
    rod_train: tuple[tuple[str, TrainConfig], ...] = ()
    # What the notebooks run beyond the studies (a study's own sizes are in its grid):
    # notebook 03's size sweep, (model, argument, values)
    baseline_sizes: tuple[tuple[str, str, tuple[int, ...]], ...] = (
        ("mlp", "hidden", (128, 256, 512)),
        ("lstm", "hidden", (64, 128, 256)),
        ("transformer", "d_model", (32, 64)),
    )
    complex3d_per_seed: int = 5  # notebook 05: random 3-D references per seed
    spread_draws: int = 32  # notebook 05: noise draws per reference for RF-FWD's spread
    stroboscope: tuple[str, ...] = ("star", "burst_circle")  # notebook 06's pictures
    frictions: tuple[float, ...] = (0.0, 0.05, 0.15, 0.3)  # notebook 13's hysteresis loops, mu
    held_out_delays: bool = True  # notebook 14: every run's delay estimate, not only the training run's
    # Notebooks 12-15 compute a study's missing cells (ci: minutes), or show its shipped rows as
    # far as computed (paper: hours of cells, which `softflow sweep` runs).
    computes_studies: bool = False

    def train_config(self, model: str, robot: str | None = None) -> TrainConfig:
        """The training budget of ``model`` in this profile; for the rod named ``robot``, its own
        budget where ``rod_train`` gives one."""
        own = dict(self.rod_train).get(robot)
        if own is not None:
            return own
        if model in SEQUENCE_MODELS or self.per_step_train is None:
            return self.train
        return self.per_step_train

    @property
    def data_spec(self) -> dict:
        """The fields that decide the dataset (its cache key): not the training budget."""
        return dict(n_episodes=self.n_episodes, episode_seconds=self.episode_seconds, seed=self.seed)

    @property
    def ships(self) -> bool:
        """The paper run: its figures, tables, results page and seed-0 models are the committed ones."""
        return self.name == "paper"

    @property
    def output_dir(self) -> Path:
        """Figures and tables: committed figures/ for the paper run, build/ci otherwise."""
        return REPO / "figures" if self.ships else REPO / "build" / self.name


# One budget for every model, RF-FWD's surrogate too (the paper's: 40 epochs of 500 steps, no early
# stop): the studies that compare models at equal optimiser steps (data_size, ambiguity,
# two_segment, recorded) and so every model of the two-segment rod, whose study trains them so.
FIXED_BUDGET = {
    "ci": TrainConfig(epochs=3, steps_per_epoch=100, batch_size=256, warmup_steps=20, val_samples=2000, patience=3),
    "paper": TrainConfig(epochs=40, steps_per_epoch=500, patience=40),
}

# The profiles the studies' grids are sized for ("quick" is for a user's own models, not studies).
STUDY_PROFILES = ("ci", "paper")

PROFILES = {
    "ci": Profile(
        "ci",
        n_episodes=100,
        bench_episodes=16,
        validation_seconds=1.0,
        identification_seconds=1.5,
        train=TrainConfig(epochs=2, steps_per_epoch=150, batch_size=256, warmup_steps=50, val_samples=5000, patience=3),
        rod_train=(("two", FIXED_BUDGET["ci"]),),
        baseline_sizes=(("mlp", "hidden", (128, 256)),),  # two sizes exercise the code every model's sizes run
        complex3d_per_seed=2,
        spread_draws=8,
        stroboscope=("star",),  # the committed notebooks stay under 1.5 MB
        frictions=(0.15,),  # FRICTION_GAP's (tests/test_friction.py checks the others)
        held_out_delays=False,
        computes_studies=True,
    ),
    "quick": Profile(
        "quick",
        n_episodes=600,
        train=TrainConfig(epochs=10, steps_per_epoch=250, warmup_steps=200, val_samples=10000, patience=4),
        per_step_train=TrainConfig(epochs=20, steps_per_epoch=250, warmup_steps=200, val_samples=10000, patience=5),
    ),
    "paper": Profile(
        "paper",
        n_episodes=3000,
        bench_episodes=3000,
        per_step_train=TrainConfig(epochs=240, patience=30),
        rod_train=(("two", FIXED_BUDGET["paper"]),),
    ),
}


def get_profile(name: str) -> Profile:
    check_choice(name, "profile", PROFILES)
    return PROFILES[name]


def set_threads(n: int) -> None:
    """Use ``n`` threads in torch and in numpy's BLAS from now on. Setting OMP_NUM_THREADS does
    nothing once numpy and torch are loaded (a notebook imports them before ``setup``), so the
    running thread pools are limited instead."""
    import torch
    from threadpoolctl import threadpool_limits

    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"threads must be a positive integer; got {n!r}")
    threadpool_limits(limits=n)
    torch.set_num_threads(n)


def setup(name: str) -> Profile:
    """One call at the top of every notebook: seeds, threads (OMP_NUM_THREADS, else 2) and plot
    style fixed, so outputs are deterministic (nbval compares them)."""
    profile = get_profile(name)
    random.seed(profile.seed)
    np.random.seed(profile.seed)
    np.set_printoptions(precision=4, suppress=True)
    set_threads(int(os.environ.get("OMP_NUM_THREADS", "2")))
    import matplotlib

    # inline figures at 56 dpi keep the committed notebooks under 1.5 MB (tests/test_notebooks_clean.py);
    # figures/ is saved at 150
    matplotlib.rcParams.update(
        {
            "figure.dpi": 56,
            "savefig.dpi": 150,
            "figure.figsize": (6.4, 4.0),
            "axes.grid": True,
            "grid.alpha": 0.3,
            "savefig.bbox": "tight",
        }
    )
    profile.output_dir.mkdir(parents=True, exist_ok=True)
    return profile
