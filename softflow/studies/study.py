"""What every study shares: the ``Study`` type, its ``Grid`` per profile, the ILC floor's rows
and the held-out per-step error.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from softflow import data, training
from softflow.control import floor
from softflow.control.planning import Controller, SaturationWarning, score
from softflow.models.specs import model_spec, resolved_kwargs
from softflow.profiles import Profile, TrainConfig, get_profile
from softflow.rod.dynamics import Simulator

FLOOR = "ilc-floor"  # the model name of the ILC floor's rows in the studies


@dataclass(frozen=True)
class Study:
    """A grid of cells and the function that turns one cell into measurements.

    ``cells(profile_name)``: JSON-able dicts, each naming its study, model, seed and condition.
    ``run_cell(cell, profile_name, device, workdir, key)``: a dict of JSON-able measurements,
    or a list of them (one row each, e.g. per reference), that depends on nothing but its
    arguments (its rows are cached by them). ``workdir`` is the study's folder, for files
    cells share (datasets) or own (name those by ``key``).
    ``models(cell, profile_name)``: what the cell's rows depend on of the models it trains or
    loads (``training_spec``: their resolved arguments and budgets), part of each row's key, so that a
    changed default or budget recomputes the rows instead of serving stale ones.
    ``version``: bump it when a change alters the numbers run_cell returns; every cached row
    of the study is then recomputed.
    ``notebook``: the notebook that runs the study and shows its rows ("" for none).
    ``fixed_in``: the commit that fixed its conditions (and its rule, where it has one) before
    its first row ("" for none).
    """

    cells: Callable[[str], list[dict]]
    run_cell: Callable[[dict, str, str, Path, str], dict | list[dict]]
    models: Callable[[dict, str], dict] = lambda cell, profile_name: {}
    version: int = 1
    notebook: str = ""
    fixed_in: str = ""


@dataclass(frozen=True, kw_only=True)
class Grid:
    """A study's conditions for one profile, fixed before its first row (each study adds its
    own fields): the models, the seeds, and the one training budget every model gets where the
    study compares models at equal optimiser steps (None: each model's budget in the profile)."""

    models: tuple[str, ...] = ()
    seeds: tuple[int, ...] = (0,)
    train: TrainConfig | None = None

    def budget(self, profile_name: str) -> Profile:
        """The profile the grid's models train with."""
        return get_profile(profile_name) if self.train is None else fixed_budget(profile_name, self.train)


def training_spec(name: str, profile: Profile, model_kwargs: dict | None = None, seed: int = 0) -> dict:
    """{model: its resolved arguments and training budget} for model ``name`` trained with the
    profile's budget and ``seed``, and for the models it requires (RF-FWD's surrogate)."""
    names = (name, *model_spec(name).requires)
    return {
        n: dict(
            kwargs=resolved_kwargs(n, **((model_kwargs or {}) if n == name else {})),
            train=asdict(replace(profile.train_config(n), seed=seed)),
        )
        for n in names
    }


def recorded_cell_model(cell: dict, grid: Grid, profile_name: str, dataset: data.Dataset, workdir: Path, device: str):
    """A cell's model of recorded runs (no rod): trained on ``dataset`` with the grid's budget and
    the cell's seed under the study's folder, or found trained there; (model, checkpoint)."""
    return training.ensure_trained(
        cell["model"],
        grid.budget(profile_name),
        dataset,
        None,
        None,
        seed=cell["seed"],
        root=workdir / "models" / profile_name,
        device=device,
    )


def fixed_budget(profile_name: str, train) -> Profile:
    """The profile with one fixed training budget for every model, RF-FWD's surrogate too: the
    studies that compare models at equal optimiser steps (ambiguity, two_segment, recorded)."""
    return replace(get_profile(profile_name), train=train, per_step_train=train, rod_train=())


def floor_rows(sim: Simulator, references, iterations: int, start_q=None):
    """The ILC floor's scored row for each reference, and the trial that gave it."""
    plans, reached, history = floor.ilc_plans(sim, references, iterations=iterations, start_q=start_q)
    return [score(FLOOR, r, u, X) for r, u, X in zip(references, plans, reached)], np.argmin(history, axis=0)


def held_out_plan(controller: Controller, dataset: data.Dataset) -> tuple[np.ndarray, float]:
    """The controller's plan for the dataset's held-out test episodes and its u error (N, RMS
    over steps and both inputs), the per-step error every study reports. Planned without the
    workspace check, whatever the controller's margin (a held-out paper episode lies 10 training
    standard deviations out: the studies measure extrapolation, they do not refuse it), and
    without the saturation warning (the clipped plan is what is judged)."""
    unchecked = copy.copy(controller)
    unchecked.workspace_margin = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)
        planned = unchecked.plan(dataset.states[dataset.test])
    return planned, float(np.sqrt(np.mean((planned - dataset.u[dataset.test]) ** 2)))


def unnamed(row: dict, **more) -> dict:
    """A scored row without its model name (the cell names it), with ``more`` columns."""
    return {**{k: v for k, v in row.items() if k != "model"}, **more}
