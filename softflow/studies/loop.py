"""loop: does the loop of a model of recorded runs (``control.loop``, run as its exported graph)
track a rig with a real rig's faults better than the same model's open-loop plan? Fixed before
any row ran (docs/assumptions.md, "The loop study").

The rig (``hardware.mocap.MocapRig``): the twin of the hardware rod, hanging, whose motor
commands act 0.2 s after they are sent, filmed by a 100 Hz motion-capture camera (0.2 mm noise,
1 % of frames held, 1 % lost). Runs of random actuation are recorded from it across the typical
gap, written and read as a user's recordings (the loader's own delay estimate and levels); MLP,
RF and RF-FWD learn the motor commands from them, 3 seeds at 20 000 steps. The rig then tracks
references it never ran, across the friction gap (cable friction the recordings never had):
Table III's shapes and the tip paths of held-out recorded runs, open loop (the model's plan,
advanced by its delay, clipped to the recorded range) and closed loop (the loop's graph in
onnxruntime, with the recordings' limits), each reference from rest, one row per reference
and loop.

The rule (``summarise``), per model over its seeds and the references: the closed loop's mean
RMSE over the open loop's (``stats.ratio``, two-way bootstrap) at most GOAL at the interval's
upper end, confirmed by a one-sided paired t-test of the per-reference ratios (seed means) below
GOAL with Holm's adjustment over the models (the family), and no reference with a ratio above 1.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats as distributions

from softflow.control.loop import GraphLoop, loop_of
from softflow.control.metrics import tracking_rmse
from softflow.control.planning import Controller, SaturationWarning, pad_plans, recorded_range
from softflow.data import recordings
from softflow.data.references import Reference, hardware_references
from softflow.hardware import mocap
from softflow.hardware.gap import FRICTION_GAP, TYPICAL_GAP
from softflow.hardware.recorder import motor_columns
from softflow.profiles import FIXED_BUDGET
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT
from softflow.store import content_key
from softflow.studies import stats
from softflow.studies.study import Grid, recorded_cell_model, training_spec

RECORDED_GAP, TRACKED_GAP = TYPICAL_GAP, FRICTION_GAP
GRAVITY = "vertical"
TRAINING_SEED, HELD_OUT_SEED = 0, 1  # recording seeds
TRACKING_SEED = 2  # the camera's draws while tracking
SHAPES = ("star", "spiral", "circle", "heart")  # Table III's; the burst circle is the twin_burst study's
LOOPS = ("open", "closed")
GOAL = 0.5  # the closed loop's RMSE at most this share of the open loop's


@dataclass(frozen=True, kw_only=True)
class LoopGrid(Grid):
    runs: int  # recorded for training
    seconds: float  # per recorded run
    held_out: int  # recorded runs whose tip paths are the random references
    shapes: tuple[str, ...]
    fractions: tuple[float, float]  # the loader's (train, validation) shares of the runs


LOOP = {
    "ci": LoopGrid(
        models=("mlp",),
        seeds=(0,),
        runs=8,
        seconds=3.0,
        held_out=1,
        shapes=("circle",),
        fractions=(0.5, 0.25),
        train=FIXED_BUDGET["ci"],
    ),
    "paper": LoopGrid(
        models=("mlp", "rf", "rf-fwd"),
        seeds=(0, 1, 2),
        runs=120,  # 10 minutes
        seconds=5.0,
        held_out=8,
        shapes=SHAPES,
        fractions=(0.8, 0.1),
        train=FIXED_BUDGET["paper"],  # 20 000 steps, no early stop
    ),
}


def cells(profile_name: str) -> list[dict]:
    grid = LOOP[profile_name]
    return [dict(study="loop", model=model, seed=seed) for model in grid.models for seed in grid.seeds]


def recording_settings(profile_name: str, seed: int, runs: int) -> dict:
    """What a folder of the study's runs was recorded with: it names the folder and keys the rows."""
    return dict(
        robot=HW_ROBOT.name,
        robot_parameters=HW_ROBOT.parameters(),
        gravity=GRAVITY,
        gap=RECORDED_GAP.parameters(),
        seconds=LOOP[profile_name].seconds,
        seed=seed,
        runs=runs,
        delay=mocap.DELAY,
        noise=mocap.NOISE,
        held=mocap.HELD,
        lost=mocap.LOST,
    )


def record(workdir: Path, profile_name: str, seed: int, runs: int) -> list[Path]:
    settings = recording_settings(profile_name, seed, runs)
    folder = workdir / "recordings" / profile_name / f"seed{seed}-{content_key(settings, 8)}"
    return mocap.record_runs(folder, runs, settings["seconds"], RECORDED_GAP, seed=seed, gravity=GRAVITY)


def dataset(profile_name: str, workdir: Path) -> recordings.Dataset:
    grid = LOOP[profile_name]
    files = record(workdir, profile_name, TRAINING_SEED, grid.runs)
    return recordings.load_dataset(
        files, inputs=motor_columns(HW_ROBOT), fractions=grid.fractions, data_dir=workdir / "datasets"
    )


def references(profile_name: str, workdir: Path, delay: float) -> list[Reference]:
    """The grid's shapes, then the smoothed tip paths of the held-out runs ("random1", ...)."""
    grid = LOOP[profile_name]
    shapes = [r for r in hardware_references(Simulator(HW_ROBOT, GRAVITY)) if r.name in grid.shapes]
    held = record(workdir, profile_name, HELD_OUT_SEED, grid.held_out)
    paths = [recordings.read(f, inputs=motor_columns(HW_ROBOT), delay=delay).states for f in held]
    return shapes + [Reference(f"random{i + 1}", "random", s, np.ones(len(s), bool)) for i, s in enumerate(paths)]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """The cell's model trained on the recordings, then every reference tracked open and closed
    loop on the rig across the tracking gap: one row per reference and loop."""
    grid, data = LOOP[profile_name], dataset(profile_name, workdir)
    model, checkpoint = recorded_cell_model(cell, grid, profile_name, data, workdir, device)
    scored = references(profile_name, workdir, data.delay_steps * data.dt)
    options = dict(robot=None, gravity=None, delay_steps=data.delay_steps, dt=data.dt)
    u_range = recorded_range(checkpoint["recorded"])
    planner = Controller(model, cell["model"], workspace_margin=None, u_range=u_range, **options)
    with warnings.catch_warnings():  # plans clipped to the recorded range are part of what is measured
        warnings.simplefilter("ignore", SaturationWarning)
        _, padded = pad_plans([planner.plan(r.states) for r in scored])  # (R, T_max, C) mm
    looped = loop_of(Controller(model, cell["model"], **options), data)  # the recordings' limits, the workspace check
    tracked = {"open": open_loop(padded, TRACKING_SEED), "closed": closed_loop(looped, scored, TRACKING_SEED)}
    rows = []
    for loop, (states, holding) in tracked.items():
        for r, reference in enumerate(scored):
            achieved = states[r, : reference.n_steps + 1]
            rows.append(
                dict(
                    reference=reference.name,
                    family=reference.family,
                    loop=loop,
                    rmse_mm=1e3 * tracking_rmse(achieved, reference.states, reference.mask),
                    holding_periods=int(holding[r, : reference.n_steps].sum()),
                    delay_steps=data.delay_steps,
                    train_minutes=float(checkpoint["wall_seconds"]) / 60,
                )
            )
    return rows


def open_loop(padded: np.ndarray, seed: int):
    """The rig's tip states (R, T+1, 6) across the tracking gap under the plans (R, T, C), row k
    sent at period k (``seed``: the camera's draws), and which periods held (none)."""
    rig = mocap.MocapRig(TRACKED_GAP, gravity=GRAVITY, batch=len(padded), seed=seed)
    for commands in padded.transpose(1, 0, 2):
        rig.read()
        rig.send(commands)
    return np.stack(rig.states, 1), np.zeros(padded.shape[:2], bool)


def closed_loop(loop, scored: list[Reference], seed: int):
    """The rig's tip states (R, T+1, 6) across the tracking gap under the loop's graph, each
    reference's states now, d and d + 1 periods ahead given every period (its last state once it
    ends), and which periods held (``seed``: the camera's draws)."""
    T = max(r.n_steps for r in scored)
    wanted = np.stack([r.states[np.minimum(np.arange(T + loop.period.delay + 2), r.n_steps)] for r in scored])
    rig = mocap.MocapRig(TRACKED_GAP, gravity=GRAVITY, batch=len(scored), seed=seed)
    graph = GraphLoop(loop, batch=len(scored))
    holding = []
    for t in range(T):
        rig.send(graph(rig.read(), wanted[:, [t, t + loop.period.delay, t + loop.period.delay + 1]]))
        holding.append(graph.holding)
    return np.stack(rig.states, 1), np.stack(holding, 1)


def models(cell: dict, profile_name: str) -> dict:
    """The model's arguments and budget, and how its runs were recorded and read."""
    grid = LOOP[profile_name]
    return dict(
        training_spec(cell["model"], grid.budget(profile_name), seed=cell["seed"]),
        recordings=dict(
            training=recording_settings(profile_name, TRAINING_SEED, grid.runs),
            held_out=recording_settings(profile_name, HELD_OUT_SEED, grid.held_out),
            tracked_gap=TRACKED_GAP.parameters(),
            tracking_seed=TRACKING_SEED,
            shapes=grid.shapes,
            fractions=grid.fractions,
            loader=recordings.LOADER_REVISION,
        ),
    )


def summarise(rows: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The study's tables: ``tracking``, each model's mean RMSE per loop and family with its
    two-way bootstrap interval; ``rule``, one row per model: the closed loop's mean RMSE over the
    open loop's with its interval, the one-sided t-test of the per-reference ratios below GOAL
    with Holm's adjustment over the models, the worst reference's ratio, and whether the goal is
    met."""
    tracking = stats.summarise(rows, by=("model", "loop", "family")) if len(rows) else pd.DataFrame()
    return dict(tracking=tracking, rule=_rule(rows))


def _rule(rows: pd.DataFrame) -> pd.DataFrame:
    out = []
    for model, own in rows.groupby("model", sort=False):
        opened, closed = (stats.seed_reference_grid(own[own.loop == loop], "rmse_mm") for loop in LOOPS)
        interval = stats.ratio(closed, opened)
        per_reference = closed.mean(0) / opened.mean(0)  # (references,)
        test = distributions.ttest_1samp(per_reference, GOAL, alternative="less")
        out.append(
            dict(
                model=model,
                references=len(per_reference),
                seeds=len(closed),
                ratio=interval.estimate,
                low=interval.low,
                high=interval.high,
                p=float(test.pvalue),
                worst_ratio=float(per_reference.max()),
                worst_reference=list(dict.fromkeys(own.reference))[int(np.argmax(per_reference))],
            )
        )
    table = pd.DataFrame(out)
    if table.empty:
        return table
    table["holm_p"] = stats.holm(table.p.to_numpy())
    table["met"] = (table.high <= GOAL) & (table.holm_p < 1 - stats.LEVEL) & (table.worst_ratio <= 1)
    return table
