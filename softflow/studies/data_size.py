"""data_size: is it the prior or being generative that helps? Four models against the training-set size."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from softflow import data, training
from softflow.control.planning import Controller, evaluate
from softflow.profiles import FIXED_BUDGET, get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT
from softflow.studies.study import Grid, held_out_plan, training_spec, unnamed
from softflow.studies.table1 import table1_references


@dataclass(frozen=True, kw_only=True)
class DataSizeGrid(Grid):
    sizes: tuple[int, ...]  # episodes: the first of the profile's dataset


DATA_SIZE = {
    "ci": DataSizeGrid(
        sizes=(25, 100),
        models=("mlp", "mlp-physical"),
        seeds=(0,),
        train=FIXED_BUDGET["ci"],
    ),
    "paper": DataSizeGrid(
        sizes=(100, 300, 1000, 3000),
        models=("mlp", "mlp-physical", "rf", "rf-physical"),
        seeds=(0, 1, 2),
        train=FIXED_BUDGET["paper"],
    ),  # 20 000 steps, no early stop
}


def cells(profile_name: str) -> list[dict]:
    grid = DATA_SIZE[profile_name]
    return [
        dict(study="data_size", model=model, seed=seed, episodes=size)
        for size in grid.sizes
        for model in grid.models
        for seed in grid.seeds
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model trained on the first ``episodes`` episodes of the profile's dataset with the
    study's fixed budget, scored open loop on Table I's references and per step on the
    held-out test episodes (the same for every size)."""
    profile, sim = get_profile(profile_name), Simulator(SIM_ROBOT)
    dataset = data.subset(data.load_dataset(profile, progress=False), cell["episodes"])
    config = replace(DATA_SIZE[profile_name].train, seed=cell["seed"])
    path = workdir / "models" / profile_name / f"{cell['model']}-n{cell['episodes']}-seed{cell['seed']}.pt"
    model, checkpoint = training.train(cell["model"], dataset, config, path, device=device, progress=False)
    controller = Controller(model, cell["model"], workspace_margin=None)  # few episodes: extrapolation is measured
    _, per_step = held_out_plan(controller, dataset)
    results, _ = evaluate(controller, table1_references(sim, profile_name), sim)
    return [
        unnamed(row, u_rmse_test=per_step, best_val=float(checkpoint["best_val"])) for row in results.to_dict("records")
    ]


def models(cell: dict, profile_name: str) -> dict:
    return training_spec(cell["model"], DATA_SIZE[profile_name].budget(profile_name), seed=cell["seed"])
