"""What notebooks 03 (baselines) and 04 (RF family) report about the models they train: the
training log, the Table I/II rows, the planning latency and the tracking and input grids.
Written once, so that both families are trained, scored, timed and drawn the same way and their
tables and figures can be set side by side."""

from __future__ import annotations

import pandas as pd
import torch

from softflow import control, data, training
from softflow.control import metrics
from softflow.models.common import one_thread
from softflow.report import plots
from softflow.rod import DT

SHOWN = ["circle", "heart", "Rand2", "Rand3"]  # the references of the paper's figure grids
DECIMALS = {"rmse_shape_mm": 1, "rmse_random_mm": 1, "phase_lag_shape_s": 3, "input_energy_random": 1}
LATENCY_STEP = 100  # the control step whose input window is timed: past the approach segment
TRAINING_COLUMNS = ["model", "epochs", "best_val", "minutes"]  # training_*.csv, read by notebook 07


def train_models(names, profile, dataset) -> dict:
    """{name: checkpoint} of each model, trained now or reused from the cache (a finished
    checkpoint of the same data and budget). Only the checkpoints are returned, for the training
    log: planning loads the models through ``evaluate_models``, as every later notebook does."""
    return {name: training.ensure_trained(name, profile, dataset)[1] for name in names}


def training_log(checkpoints: dict) -> pd.DataFrame:
    """One row per model (epochs run, best validation loss, training minutes): the budget a
    table row was bought with, saved beside the results so a comparison can check it was fair."""
    rows = [
        dict(model=name, epochs=c["epochs_run"], best_val=c["best_val"], minutes=c["wall_seconds"] / 60)
        for name, c in checkpoints.items()
    ]
    return pd.DataFrame(rows, columns=TRAINING_COLUMNS)


def training_text(checkpoints: dict) -> str:
    """The training log as the notebooks print it, one line per model."""
    return "\n".join(
        f"{name:12s} {c['epochs_run']} epochs, best validation loss {c['best_val']:.4f}, "
        f"training {c['wall_seconds'] / 60:.1f} min"
        for name, c in checkpoints.items()
    )


def evaluate_models(names, profile, references, sim):
    """Load each trained model of the profile, plan every reference and run all plans open loop
    in one batched rollout. Returns ({name: Controller}, results DataFrame, runs); the runs feed
    the figure grids, the results the tables."""
    controllers = {name: control.load_controller(name, profile.name) for name in names}
    results, runs = control.evaluate_many(controllers.values(), references, sim)
    return controllers, results, runs


def table_text(table: pd.DataFrame) -> str:
    """Table I/II rows (``metrics.table_rows``) rounded as the paper prints them: mm to 0.1,
    the phase lag to 1 ms, the input energy to 0.1."""
    return table.round(DECIMALS).to_string()


def step_window(states, context: int, step: int = LATENCY_STEP) -> torch.Tensor:
    """The model input of one control step of a reference, (1, context + 1, d) float32: what one
    step of planning reads on the robot, so that its latency can be timed on its own."""
    return torch.as_tensor(data.gather_windows(states[None], [0], [step], context), dtype=torch.float32)


def step_latency(predict, *args, repeats: int = 1000) -> dict:
    """Median and p99 (s) of ``predict(*args)`` on one torch thread without autograd, as a
    controller runs one step at a time (``metrics.latency``)."""
    with torch.inference_mode(), one_thread():
        return metrics.latency(predict, *args, repeats=repeats)


def planning_latency(controllers: dict, states, step_repeats: int = 1000, plan_repeats: int = 20) -> pd.DataFrame:
    """Per model (rows): one control step's median and p99 (ms), and the reference ``states``
    planned whole in one batched call (ms, over ``trajectory_steps`` steps): the per-step cost
    bounds the control rate, the batched one the time to plan a trajectory offline."""
    latency = {}
    for name, controller in controllers.items():
        step = step_latency(
            controller.model.predict, step_window(states, controller.model.context), repeats=step_repeats
        )
        whole = metrics.latency(controller.plan, states, repeats=plan_repeats, warmup=2)
        latency[name] = dict(
            step_median_ms=1e3 * step["median"],
            step_p99_ms=1e3 * step["p99"],
            trajectory_ms=1e3 * whole["median"],
            trajectory_steps=len(states) - 1,
        )
    return pd.DataFrame(latency).T


def tracking_figure(runs: dict, references: dict, profile, name: str, shown=SHOWN):
    """The paper's tracking grid (y-z tip paths on ``shown``) of every model in ``runs``, saved
    under the profile's output folder as ``name``."""
    return plots.save(plots.tracking_grid(runs, references, shown), profile, name)


def inputs_figure(runs: dict, references: dict, profile, name: str, shown=SHOWN):
    """The paper's input grid (u_1, u_2 over time on ``shown``) of every model in ``runs``, saved
    under the profile's output folder as ``name``."""
    return plots.save(plots.inputs_grid(runs, references, shown, DT), profile, name)
