"""table1: Tables I and II with confidence intervals over seeds and references, and the ILC floor."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from softflow import data, training
from softflow.control.planning import Controller, evaluate
from softflow.data.references import (
    STRUCTURED,
    cached_references,
    evaluation_references,
    random_references,
)
from softflow.profiles import get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT
from softflow.studies.study import FLOOR, Grid, floor_rows, training_spec, unnamed


@dataclass(frozen=True, kw_only=True)
class Table1Grid(Grid):
    shapes: tuple[str, ...]  # the structured references scored, then Rand1..Rand<n_random>
    n_random: int
    ilc_iterations: int  # the floor's trials


TABLE1 = {
    "ci": Table1Grid(models=("mlp", "rf"), seeds=(0, 1), shapes=("circle", "char_S"), n_random=4, ilc_iterations=4),
    "paper": Table1Grid(
        models=("mlp", "lstm", "transformer", "rf", "rf-physical", "rf-fwd"),
        seeds=(0, 1, 2),
        shapes=STRUCTURED,
        n_random=24,
        ilc_iterations=40,
    ),
}
EXTRA_RANDOM_SEED = 1001  # Rand5.. (Rand1..Rand4 are the paper's, seed 1000)


def table1_references(sim: Simulator, profile_name: str):
    """The profile's Table I references: its shapes, then Rand1..Rand<n_random> (cached)."""
    grid = TABLE1[profile_name]
    paper_set = evaluation_references(sim)
    shapes = [r for r in paper_set if r.name in grid.shapes]
    random = [r for r in paper_set if r.family == "random"][: grid.n_random]
    extra = grid.n_random - len(random)
    if extra > 0:
        random += cached_references(sim, f"random-extra-{extra}", _more_random(extra, first=len(random) + 1))
    return shapes + random


def _more_random(n: int, first: int):
    def more_random(sim):
        made = random_references(sim, n, seed=EXTRA_RANDOM_SEED)
        return [replace(r, name=f"Rand{first + k}") for k, r in enumerate(made)]

    return more_random


def cells(profile_name: str) -> list[dict]:
    grid = TABLE1[profile_name]
    return [dict(study="table1", model=FLOOR, seed=0)] + [
        dict(study="table1", model=model, seed=seed) for model in grid.models for seed in grid.seeds
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model and seed trained (or the shipped model reused) and scored on every reference;
    or the ILC floor on every reference. One row per reference."""
    profile, sim = get_profile(profile_name), Simulator(SIM_ROBOT)
    references = table1_references(sim, profile_name)
    if cell["model"] == FLOOR:
        rows, trials = floor_rows(sim, references, TABLE1[profile_name].ilc_iterations)
        return [unnamed(row, ilc_best_trial=int(t)) for row, t in zip(rows, trials)]
    dataset = data.DatasetOnDemand(profile, progress=False)  # simulated only if a model must be trained
    model, checkpoint = training.ensure_trained(
        cell["model"], profile, dataset, seed=cell["seed"], root=workdir / "models" / profile_name, device=device
    )
    results, _ = evaluate(Controller(model, cell["model"]), references, sim)
    trained = dict(
        best_val=float(checkpoint["best_val"]),
        epochs_run=int(checkpoint["epochs_run"]),
        train_minutes=float(checkpoint["wall_seconds"]) / 60,
    )
    return [unnamed(row, **trained) for row in results.to_dict("records")]


def models(cell: dict, profile_name: str) -> dict:
    return {} if cell["model"] == FLOOR else training_spec(cell["model"], get_profile(profile_name), seed=cell["seed"])
