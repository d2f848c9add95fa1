"""How much of the open loop's error can any feedback through the rig's delay remove? The loop
study's goal (closed loop at most half the open loop's RMSE) measured against what the delay
leaves, on the loop study's pilot (recording seed 10, held-out seed 11, tracking seed 12: none of
the study's), with the pilot's MLP (4 000 steps).

A command sent at t acts on the rod from t + d, so a correction of the error at t + d + 1 may
use what is known at t: the frames so far, the inputs sent, and the whole reference. Where the
rig is linear in the corrections, no feedback removes more of the open loop's error than the best
predictor of that error d + 1 periods ahead removes. Measured here with linear predictors fitted
on the other references' open-loop errors (leave one reference out; ridge on standardised
features): from the error's last ``LAGS`` periods alone ("history"), and from those with the
reference's state at t + d + 1 and the sign of its velocity there ("history and reference"). The
share of the open loop's RMSE each leaves is an estimate of the floor of the closed-over-open
ratio; beside it, the ratio the loop reaches with ``Feedback``'s integral gain at 0, 2 and 4 /s.
``make loop-bound`` writes ``figures/bench/loop_bound.csv`` (about 3 minutes)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from softflow import training
from softflow.control.loop import Feedback, loop_of
from softflow.control.metrics import tracking_rmse
from softflow.control.planning import Controller, SaturationWarning, pad_plans, recorded_range
from softflow.data import recordings
from softflow.data.references import Reference, hardware_references
from softflow.hardware import mocap
from softflow.hardware.recorder import motor_columns
from softflow.machine import description
from softflow.profiles import TrainConfig
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT
from softflow.studies import loop
from softflow.studies.study import fixed_budget
from softflow.studies.sweep import SWEEPS_DIR

RECORDING_SEED, HELD_OUT_SEED, TRACKING_SEED = 10, 11, 12  # the pilot's, none of the study's
RUNS, HELD_OUT, SECONDS = 40, 4, 5.0
BUDGET = TrainConfig(epochs=8, steps_per_epoch=500, patience=8)  # the pilot's 4 000 steps
LAGS = 5  # periods of the error's history a predictor reads
RIDGE = 1e-3  # share of the rows, on standardised features
GAINS = (0.0, 2.0, 4.0)  # Feedback.integral, 1/s


def predictor_residual(errors: list[np.ndarray], features: list[np.ndarray], horizon: int) -> np.ndarray:
    """Per reference r: the RMSE left of its error (T_r + 1, 3) once a linear predictor fitted on
    the other references predicts it ``horizon`` periods ahead from ``features`` (T_r + 1, f) at
    each period, over its RMSE; the first ``horizon`` periods, which nothing predicts, stay as
    they are."""
    pairs = [(x[:-horizon], e[horizon:]) for x, e in zip(features, errors)]
    left = []
    for r, error in enumerate(errors):
        X = np.concatenate([x for q, (x, _) in enumerate(pairs) if q != r])
        Y = np.concatenate([y for q, (_, y) in enumerate(pairs) if q != r])
        mean, spread = X.mean(0), X.std(0) + 1e-12
        A = np.column_stack([(X - mean) / spread, np.ones(len(X))])
        W = np.linalg.solve(A.T @ A + RIDGE * len(A) * np.eye(A.shape[1]), A.T @ Y)
        x, y = pairs[r]
        residual = error.copy()
        residual[horizon:] = y - np.column_stack([(x - mean) / spread, np.ones(len(x))]) @ W
        left.append(np.sqrt(np.mean(np.sum(residual**2, 1)) / np.mean(np.sum(error**2, 1))))
    return np.array(left)


def slow_share(error: np.ndarray, dt: float, hz: float) -> float:
    """The share of the error's (T + 1, 3) energy below ``hz``, its mean included."""
    power = np.abs(np.fft.rfft(error, axis=0)) ** 2
    return float(power[np.fft.rfftfreq(len(error), dt) < hz].sum() / power.sum())


def lagged(error: np.ndarray, lags: int = LAGS) -> np.ndarray:
    """(T + 1, 3 lags): the error at each period and the ``lags`` - 1 before it (the first
    period's repeated before the start)."""
    padded = np.concatenate([np.repeat(error[:1], lags - 1, 0), error])
    return np.concatenate([padded[lags - 1 - k : len(padded) - k] for k in range(lags)], 1)


def measure(workdir: Path = SWEEPS_DIR / "loop_bound") -> pd.DataFrame:
    """One row per reference: its open-loop RMSE, the shares of it the two predictors leave, and
    the loop's closed-over-open ratio at each gain of ``GAINS``."""
    read = dict(inputs=motor_columns(HW_ROBOT))
    files = mocap.record_runs(
        workdir / "training", RUNS, SECONDS, loop.RECORDED_GAP, seed=RECORDING_SEED, gravity=loop.GRAVITY
    )
    with warnings.catch_warnings():  # a short recording identifies the delay loosely: the median is used
        warnings.simplefilter("ignore", recordings.DelayWarning)
        data = recordings.load_dataset(files, fractions=(0.8, 0.1), data_dir=workdir / "datasets", **read)
    budget = fixed_budget("paper", BUDGET)
    model, checkpoint = training.ensure_trained("mlp", budget, data, None, None, seed=0, root=workdir / "models")
    held = mocap.record_runs(
        workdir / "held_out", HELD_OUT, SECONDS, loop.RECORDED_GAP, seed=HELD_OUT_SEED, gravity=loop.GRAVITY
    )
    paths = [recordings.read(f, delay=data.delay_steps * data.dt, **read).states for f in held]
    scored = [r for r in hardware_references(Simulator(HW_ROBOT, loop.GRAVITY)) if r.name in loop.SHAPES]
    scored += [Reference(f"random{i + 1}", "random", s, np.ones(len(s), bool)) for i, s in enumerate(paths)]
    options = dict(robot=None, gravity=None, delay_steps=data.delay_steps, dt=data.dt)
    planner = Controller(model, "mlp", workspace_margin=None, u_range=recorded_range(checkpoint["recorded"]), **options)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)
        _, padded = pad_plans([planner.plan(r.states) for r in scored])
    opened, _ = loop.open_loop(padded, TRACKING_SEED)
    errors = [opened[r, : ref.n_steps + 1, :3] - ref.states[:, :3] for r, ref in enumerate(scored)]  # (T+1, 3) m
    ahead = data.delay_steps + 1
    speed_scale = np.median(np.concatenate([np.abs(ref.states[:, 3:]) for ref in scored]))
    reference = [np.column_stack([ref.states, np.tanh(ref.states[:, 3:] / speed_scale)]) for ref in scored]
    shifted = [np.concatenate([x[ahead:], np.repeat(x[-1:], ahead, 0)]) for x in reference]  # the state at t + d + 1
    rows = pd.DataFrame(
        dict(
            reference=[r.name for r in scored],
            family=[r.family for r in scored],
            open_rmse_mm=[
                1e3 * tracking_rmse(opened[r, : ref.n_steps + 1], ref.states) for r, ref in enumerate(scored)
            ],
            delay_steps=data.delay_steps,
            share_below_1hz=[slow_share(e, data.dt, 1.0) for e in errors],
            left_by_history=predictor_residual(errors, [lagged(e) for e in errors], ahead),
            left_by_history_and_reference=predictor_residual(
                errors, [np.column_stack([lagged(e), s]) for e, s in zip(errors, shifted)], ahead
            ),
        )
    )
    for gain in GAINS:
        looped = loop_of(Controller(model, "mlp", **options), data, feedback=Feedback(integral=gain))
        closed, _ = loop.closed_loop(looped, scored, TRACKING_SEED)
        rmse = [1e3 * tracking_rmse(closed[r, : ref.n_steps + 1], ref.states) for r, ref in enumerate(scored)]
        rows[f"closed_over_open_integral_{gain:g}"] = np.array(rmse) / rows.open_rmse_mm
    return rows.assign(machine=description())


def main(out="figures/bench/loop_bound.csv") -> None:
    measure().to_csv(out, index=False, float_format="%.4g")
    print(out)


if __name__ == "__main__":
    main()
