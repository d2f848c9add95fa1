"""Open-loop control: plan u_t = g(x*_t, x*_{t+1}) for a whole reference in one batched call,
run the plan in the simulator from rest, and score it."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from .checks import as_real_array, check_choice
from .data import DT, U_MAX, dataset_path
from .models.common import one_thread
from .models.flow import RectifiedFlow
from .metrics import actuation_mae, input_energy, phase_lag, tracking_rmse
from .profiles import REPO, Profile, get_profile
from .robots import SIM_ROBOT, Robot
from .sim import Simulator
from .train import gather_windows, load_checkpoint, model_from_checkpoint, resolved_kwargs, train

SHIPPED = REPO / "checkpoints"  # paper-profile weights, committed
TRAINED = REPO / "data" / "checkpoints"  # anything else, rebuilt on demand


def checkpoint_path(name: str, profile: str, robot: Robot = SIM_ROBOT, gravity: str = "vertical",
                    model_kwargs: dict | None = None) -> Path:
    """Where model ``name`` of a profile lives; models of another rod or configuration (the
    hardware twins) in a sub-folder named after them, and variants with other constructor
    arguments (a size sweep) in variants/, named after the arguments that differ."""
    folder = SHIPPED if profile == "paper" else TRAINED / profile
    if (robot, gravity) != (SIM_ROBOT, "vertical"):
        folder = folder / f"{robot.name}-{gravity}"
    default, chosen = resolved_kwargs(name), resolved_kwargs(name, **(model_kwargs or {}))
    changed = "-".join(f"{key}{value}" for key, value in chosen.items() if value != default[key])
    return folder / "variants" / f"{name}-{changed}.pt" if changed else folder / f"{name}.pt"


NOISE = ("zero", "seeded", "fresh")


class Controller:
    """A trained inverse model used open loop: ``plan`` maps references to actuation.

    A generative model starts every step from noise z: by default z = 0, the centre of the
    noise, which plans like the mean of many draws (notebook 05) and is deterministic;
    ``noise="seeded"`` draws one z per trajectory from ``seed`` and uses it at every step,
    ``noise="fresh"`` draws a new z for every step; ``sample`` gives independent draws."""

    def __init__(self, model: torch.nn.Module, name: str, seed: int = 0):
        self.model, self.name, self.seed = model.eval(), name, seed
        self.generative = isinstance(model, RectifiedFlow)

    def plan(self, reference, *, noise: str = "zero", seed: int | None = None, n_samples: int = 1,
             **options) -> np.ndarray:
        """(T+1, 6) or (B, T+1, 6) reference -> (T, 2) or (B, T, 2) actuation (N), every
        step predicted in one batched call (the plan depends on the reference only).
        ``n_samples`` > 1 plans with the mean of that many noise draws: a Monte-Carlo
        estimate of E[u | x_t, x_t+1], the plan of least squared actuation error."""
        check_choice(noise, "noise", NOISE)
        if n_samples == 1:
            return self._plan(reference, noise, seed, options)
        if noise == "zero":
            raise ValueError("n_samples > 1 averages random draws: use noise='seeded' or 'fresh'")
        return self.sample(reference, n_samples, noise=noise, seed=seed, **options).mean(0)

    def sample(self, reference, n: int, *, noise: str = "seeded", seed: int | None = None, **options) -> np.ndarray:
        """``n`` plans from independent noise draws: (n, T, 2) or (n, B, T, 2). Their spread is
        the flow's own uncertainty about the actuation; a regression returns n equal plans."""
        if not (isinstance(n, int) and n >= 1):
            raise ValueError(f"n must be a positive integer; got {n!r}")
        check_choice(noise, "noise", NOISE[1:])
        X, unbatched = as_real_array(reference, "reference", (None, None, 6), allow_unbatched=True)
        u = self._plan(np.tile(X, (n, 1, 1)), noise, seed, options).reshape(n, len(X), -1, 2)
        return u[:, 0] if unbatched else u

    def _plan(self, reference, noise, seed, options) -> np.ndarray:
        X, unbatched = as_real_array(reference, "reference", (None, None, 6), allow_unbatched=True)
        B, T = X.shape[0], X.shape[1] - 1
        if T < 1:
            raise ValueError("reference must have at least 2 samples")
        episodes, steps = np.repeat(np.arange(B), T), np.tile(np.arange(T), B)
        windows = torch.as_tensor(gather_windows(X, episodes, steps, self.model.context), dtype=torch.float32)
        extras = {k: torch.as_tensor(v.reshape(B * T, -1), dtype=torch.float32) for k, v in self.model.extras(X).items()}
        if self.generative:
            generator = torch.Generator().manual_seed(self.seed if seed is None else seed)
            z = torch.randn((B, T if noise == "fresh" else 1, 2), generator=generator)
            options["noise"] = (torch.zeros_like(z) if noise == "zero" else z).expand(B, T, 2).reshape(B * T, 2)
        with torch.inference_mode(), one_thread():
            u = self.model.predict(windows, **extras, **options).numpy().astype(np.float64).reshape(B, T, 2)
        return u[0] if unbatched else u


def ensure_trained(name: str, profile: Profile, dataset, robot: Robot = SIM_ROBOT, gravity: str = "vertical", *,
                   model_kwargs: dict | None = None, progress: bool = False):
    """Train model ``name`` on ``dataset`` with the profile's budget for it, into the checkpoint
    ``load_controller`` reads (``model_kwargs``: a variant, kept beside it); a finished checkpoint
    of the same arguments, budget and data returns at once. (A different budget would retrain
    and replace it: always go through here.)"""
    path = checkpoint_path(name, profile.name, robot, gravity, model_kwargs)
    return train(name, dataset, profile.train_config(name), path, model_kwargs=model_kwargs, progress=progress)


def load_controller(name: str, profile: str = "paper", robot: Robot = SIM_ROBOT, gravity: str = "vertical") -> Controller:
    """The trained model ``name`` ("mlp", "lstm", "transformer", ...) of a profile, for the rod
    and configuration it was trained on; paper-profile weights ship with the repository, so
    this works right after a clone."""
    path = checkpoint_path(name, profile, robot, gravity)
    if not path.exists():
        raise ValueError(f"no trained {name!r} for profile {profile!r} at {path}; "
                         f"rebuild it with: PROFILE={profile} make reproduce  (or run the notebook that trains it)")
    checkpoint = load_checkpoint(path)
    if "data_key" in checkpoint and checkpoint["data_key"] != expected_data_key(profile, robot, gravity):
        warnings.warn(f"{path} was trained on another dataset or simulator version; "
                      f"rebuild it with: PROFILE={profile} make reproduce", stacklevel=2)
    return Controller(model_from_checkpoint(checkpoint, path), name)


def expected_data_key(profile: str, robot: Robot = SIM_ROBOT, gravity: str = "vertical") -> str:
    return dataset_path(get_profile(profile), robot, gravity).stem


def plan_all(controller, references, u_limit: float = U_MAX, **plan_options):
    """Plan every reference and clip to the actuator range: the plans, and the same stacked
    (R, T_max, 2) with shorter plans padded by holding their last u, ready for one batched run."""
    plans = [np.clip(controller.plan(r.states, **plan_options), -u_limit, u_limit) for r in references]
    longest = max(len(u) for u in plans)
    return plans, np.stack([np.concatenate([u, np.repeat(u[-1:], longest - len(u), 0)]) for u in plans])


def evaluate(controller, references, sim: Simulator, u_limit: float = U_MAX, **plan_options):
    """Plan every reference (``plan_options`` go to ``plan``, e.g. steps=N), clip to the
    actuator range, run all plans open loop from rest in one batched rollout, and score
    them. Returns a DataFrame (one row per reference) and {name: dict(u, states)}."""
    plans, padded = plan_all(controller, references, u_limit, **plan_options)
    achieved = sim.rollout(padded)
    rows, runs = [], {}
    for r, u, X in zip(references, plans, achieved):
        X = X[: r.n_steps + 1]
        masked = r.mask
        row = dict(model=controller.name, reference=r.name, family=r.family,
                   rmse_mm=1e3 * tracking_rmse(X, r.states, masked),
                   phase_lag_s=phase_lag(X[masked, 1:3], r.states[masked, 1:3], DT),
                   input_energy=input_energy(u, DT))
        if r.u_true is not None:
            row["mae_u1"], row["mae_u2"] = actuation_mae(u, r.u_true)
        rows.append(row)
        runs[r.name] = dict(u=u, states=X)
    return pd.DataFrame(rows), runs


def table_rows(results: pd.DataFrame) -> pd.DataFrame:
    """Per model: Table I (RMSE mean over shapes / random) and Table II (phase lag on shapes,
    input energy on random references)."""
    shapes, random = results[results.family == "shape"], results[results.family == "random"]
    return pd.DataFrame({
        "rmse_shape_mm": shapes.groupby("model").rmse_mm.mean(),
        "rmse_random_mm": random.groupby("model").rmse_mm.mean(),
        "phase_lag_shape_s": shapes.groupby("model").phase_lag_s.mean(),
        "input_energy_random": random.groupby("model").input_energy.mean(),
    })
