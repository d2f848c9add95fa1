"""How many-valued is an inverse? The spread of u given the condition (x_t, x_t+1), measured
on data. A regression returns the conditional mean, so it loses exactly this spread; a flow
can only beat it where the spread is large against the regression's other errors.

Estimator: half the mean squared difference of u between each point and its nearest
neighbour in the standardised condition space (the nearest-neighbour form of the von
Neumann difference estimator). For a deterministic, smooth u it tends to zero as the data
get denser; at a finite density it is not zero, so every estimate comes with the same
estimator's value on a deterministic control: u replaced by its least-squares linear fit on
the condition (one u per condition by construction). A spread is meaningful only well above
that floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats as scipy_stats
from scipy.spatial import cKDTree

from softflow import data, training
from softflow.checks import as_real_array
from softflow.control.planning import Controller, evaluate
from softflow.data.variants import VARIANTS, variant_dataset
from softflow.profiles import FIXED_BUDGET
from softflow.rod.dynamics import Simulator
from softflow.store import cached_arrays
from softflow.studies.study import Grid, held_out_plan, training_spec, unnamed
from softflow.studies.table1 import table1_references


@dataclass(frozen=True)
class Spread:
    spread: float  # RMS spread of u given the condition (units of u), all channels together
    floor: float  # the estimator on the deterministic control: spreads near it mean "none measurable"
    points: int  # how many (condition, u) pairs it rests on


def conditional_spread(condition, u, *, max_points: int = 200_000, seed: int = 0) -> Spread:
    """RMS spread of ``u`` (N, m) given ``condition`` (N, d), and its deterministic floor."""
    condition, _ = as_real_array(condition, "condition", (None, None))
    u, _ = as_real_array(u, "u", (len(condition), None))
    if len(condition) < 3:
        raise ValueError(f"need at least 3 (condition, u) pairs; got {len(condition)}")
    if len(condition) > max_points:
        keep = np.random.default_rng(seed).choice(len(condition), max_points, replace=False)
        condition, u = condition[keep], u[keep]
    std = condition.std(0)
    scaled = (condition - condition.mean(0)) / np.where(std > 0, std, 1.0)
    _, index = cKDTree(scaled).query(scaled, k=2)
    neighbour = index[:, 1]  # the nearest other point
    design = np.column_stack([scaled, np.ones(len(scaled))])
    linear = design @ np.linalg.lstsq(design, u, rcond=None)[0]

    def estimate(values):
        return float(np.sqrt(np.mean(np.sum((values - values[neighbour]) ** 2, axis=1)) / 2))

    return Spread(estimate(u), estimate(linear), len(condition))


def transition_spread(states, u, episodes, **options) -> Spread:
    """The spread of u_t given (x_t, x_t+1) over the transitions of ``episodes`` of a dataset
    (states (E, T+1, S), u (E, T, m))."""
    states, u = np.asarray(states)[episodes], np.asarray(u)[episodes]
    condition = np.concatenate([states[:, :-1], states[:, 1:]], -1)  # (E, T, 2S)
    condition = condition.reshape(-1, condition.shape[-1])
    return conditional_spread(condition, u.reshape(-1, u.shape[-1]), **options)


@dataclass(frozen=True, kw_only=True)
class AmbiguityGrid(Grid):
    variants: tuple[str, ...]  # of ``variants.VARIANTS``
    episodes: int  # each variant's dataset
    draws: int  # a flow's mean-of-draws plan


# Fixed before any ran: every variant of ``variants.VARIANTS`` with its
# own 1000 episodes, the MLP against RF and RF-FWD, 3 seeds, data_size's 20 000 optimiser steps
# (RF-FWD's surrogate the same), scored on Table I's references (made on the variant's rod)
# and per step on the variant's held-out episodes; flows also planned with the mean of 16 draws.
AMBIGUITY = {
    "ci": AmbiguityGrid(
        variants=("paper", "position-only"),
        models=("mlp", "rf"),
        seeds=(0,),
        episodes=60,
        draws=8,
        train=FIXED_BUDGET["ci"],
    ),
    "paper": AmbiguityGrid(
        variants=tuple(VARIANTS),
        models=("mlp", "rf", "rf-fwd"),
        seeds=(0, 1, 2),
        episodes=1000,
        draws=16,
        train=FIXED_BUDGET["paper"],
    ),
}


def cells(profile_name: str) -> list[dict]:
    grid = AMBIGUITY[profile_name]
    return [
        dict(study="ambiguity", model=model, seed=seed, variant=variant)
        for variant in grid.variants
        for model in grid.models
        for seed in grid.seeds
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model and seed trained on one variant's data, scored per step on its held-out
    episodes (for a flow: also the spread of its draws and how it ranks their error) and open
    loop on Table I's references; one row per reference and plan (z = 0; flows: the mean of draws)."""
    grid, variant = AMBIGUITY[profile_name], VARIANTS[cell["variant"]]
    dataset = variant_dataset(variant, grid.episodes)
    budget = grid.budget(profile_name)
    model, _ = training.ensure_trained(
        cell["model"],
        budget,
        dataset,
        variant.robot,
        seed=cell["seed"],
        root=workdir / "models" / variant.name,
        device=device,
    )
    controller = Controller(
        model, cell["model"], robot=variant.robot, u_limit=variant.u_max, observe=variant.observe, workspace_margin=None
    )  # hidden channels shrink the training spread: measure, not refuse
    measured = dict(cached_spread(dataset, workdir), **per_step_scores(controller, dataset, grid.draws))
    sim = Simulator(variant.robot)
    references = table1_references(sim, profile_name)
    plans = {"zero": {}, f"mean-of-{grid.draws}": dict(noise="seeded", n_samples=grid.draws)}
    return [
        unnamed(row, plan=plan, **measured)
        for plan, options in plans.items()
        if controller.generative or not options
        for row in evaluate(controller, references, sim, variant.u_max, **options)[0].to_dict("records")
    ]


def cached_spread(dataset: data.Dataset, workdir: Path) -> dict:
    """The conditional spread of u given (x_t, x_t+1) over the dataset's training transitions
    and its estimator floor (all inputs together, ``transition_spread``), cached in ``workdir``
    per dataset (the cells that train on one dataset share it)."""

    def compute():
        measured = transition_spread(dataset.states, dataset.u, dataset.train)
        return dict(conditional_spread=measured.spread, conditional_spread_floor=measured.floor)

    cached = cached_arrays(workdir, "spread", dict(dataset=dataset.key, episodes=len(dataset.train)), compute)
    return {k: float(v) for k, v in cached.items()}


def per_step_scores(controller: Controller, dataset: data.Dataset, draws: int) -> dict:
    """u error (N, RMS) on the held-out transitions; for a flow also a single draw's and the
    mean of ``draws`` draws' error, the draws' spread, and the Spearman correlation of the
    spread with the z = 0 error per transition (does its uncertainty flag its mistakes?)."""
    X, u = dataset.states[dataset.test], dataset.u[dataset.test]
    planned, error_rms = held_out_plan(controller, dataset)

    def rms(a):  # per input, as held_out_plan's
        return float(np.sqrt(np.mean(np.square(a))))

    row = dict(u_rmse_test=error_rms)
    if controller.generative:
        samples = controller.sample(X, draws)  # (draws, E, T, m)
        spread = np.linalg.norm(samples.std(0), axis=-1)
        error = np.linalg.norm(planned - u, axis=-1)
        row.update(
            u_rmse_draw=rms(samples - u),
            u_rmse_mean_of_draws=rms(samples.mean(0) - u),
            draw_spread=rms(samples.std(0)),
            spread_error_spearman=float(scipy_stats.spearmanr(spread.ravel(), error.ravel())[0]),
        )
    return row


def models(cell: dict, profile_name: str) -> dict:
    return training_spec(cell["model"], AMBIGUITY[profile_name].budget(profile_name), seed=cell["seed"])
