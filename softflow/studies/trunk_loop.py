"""What the loop's parts (``control.loop``) do on the ASL trunk's held-out run, random_2, with
every model part fitted on the training run, random_1: how far the loop's filter (the offline
smoother's forward pass) lies from the smoother's states, how its estimate drifts while a point
goes without fresh frames, how far each predictor's state d periods ahead lies from the
smoother's, and the per-step input error of the trunk study's MLP (trunk_v2, paper, seed 0,
trained on the smoother's states) and of the same trained on the filter's, each fed either. ``make
loop-parts`` writes the tables (``figures/bench/loop_parts_trunk.csv``)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from softflow.control.loop import Estimator, Predictor, point_matrix, track
from softflow.control.planning import Controller
from softflow.data import recordings
from softflow.data.dataset import Dataset
from softflow.machine import description
from softflow.studies import trunk_v2
from softflow.studies.study import recorded_cell_model
from softflow.studies.sweep import SWEEPS_DIR
from softflow.studies.trunk import DT, MAX_GAP, OBSERVATIONS, TRAINING_RUN, _file, study_delay

HELD_OUT = "random_2"
HORIZONS = (0, 5, 10, 15, 20, 22, 25, 30)  # periods
STALE = tuple(range(8))  # periods since a point's last fresh frame
SETTLE = 100  # periods left out at the start of the run, while the filter settles


def filtered(estimator: Estimator, same_point, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The loop's estimate (T, 2k) over frames (T, k), as ``loop.Period`` makes it, and each
    column's periods since its last fresh frame (T, k)."""
    k = frames.shape[1]
    x, P = torch.full((1, k, 3), torch.nan, dtype=torch.float64), torch.zeros(1, k, 3, 3, dtype=torch.float64)
    last, stale = torch.full((1, k), torch.nan, dtype=torch.float64), torch.zeros(1, k, dtype=torch.int64)
    states, staleness = [], []
    with torch.no_grad():
        for frame in torch.as_tensor(frames)[:, None]:
            x, P, last, stale = track(estimator, same_point, frame, x, P, last, stale)
            states.append(torch.cat([x[0, :, 0], x[0, :, 1]]).numpy())
            staleness.append(stale[0].numpy())
    return np.array(states), np.array(staleness)


def measure(observation: str) -> pd.DataFrame:
    """The tables for one observation ("tip" or "disks"): rows of (table, what, periods, value, unit)."""
    columns = list(OBSERVATIONS[observation])
    train = recordings.read(_file(TRAINING_RUN), tip=columns, max_gap=MAX_GAP)
    test = recordings.read(_file(HELD_OUT), tip=columns, max_gap=MAX_GAP, delay=train.delay)
    k, d = len(columns), train.delay_steps
    u, X = train.pairs()
    data = Dataset(u[None], X[None], np.array([0]), np.array([0]), np.array([0]), robot=None, gravity=None, dt=DT)
    frames = pd.read_csv(_file(HELD_OUT))[columns].to_numpy()[: len(test.states)]  # as the tracker gave them
    estimator = Estimator(DT, train.noise, train.jerk)
    estimate, staleness = filtered(estimator, point_matrix(recordings.tip_points(columns), k), frames)
    smoothed, inputs = test.states, test.inputs  # (T+1, 2k), (T, m)
    rows = []
    mm = lambda e: float(1e3 * np.sqrt(np.mean(e**2)))  # noqa: E731
    later = slice(SETTLE, None)
    rows += [
        ("filter", "position", 0, mm(estimate[later, :k] - smoothed[later, :k]), "mm"),
        ("filter", "velocity", 0, mm(estimate[later, k:] - smoothed[later, k:]), "mm/s"),
        ("filter", "velocity of the smoother", 0, mm(smoothed[later, k:]), "mm/s"),
    ]
    error = (estimate[later, :k] - smoothed[later, :k])[staleness[later] < max(STALE) + 1]
    stale = staleness[later][staleness[later] < max(STALE) + 1]
    rows += [("drift", "position", s, mm(error[stale == s]), "mm") for s in STALE if (stale == s).any()]
    starts = np.arange(max(SETTLE, d), len(inputs) - max(HORIZONS))  # (N,) periods t with x_{t+h} known
    now = estimate[starts]
    for h in HORIZONS:
        truth = smoothed[starts + h, :k]
        flight = np.stack([inputs[starts + i - d] for i in range(h)], 1) if h else np.zeros((len(starts), 0, 6))
        linear = Predictor.fit(data, h)(torch.as_tensor(now), torch.as_tensor(flight)).numpy()
        rows += [
            ("predictor", "hold", h, mm(now[:, :k] - truth), "mm"),
            ("predictor", "constant velocity", h, mm(now[:, :k] + h * DT * now[:, k:] - truth), "mm"),
            ("predictor", "linear forward model", h, mm(linear[:, :k] - truth), "mm"),
        ]
    rows += input_errors(observation, test, estimate)
    table = pd.DataFrame(rows, columns=["table", "what", "periods", "value", "unit"])
    return table.assign(observation=observation, delay_steps=d, machine=description())


def input_errors(observation: str, test: recordings.Recording, estimate: np.ndarray) -> list[tuple]:
    """The trunk study's seed-0 MLP (trained where missing), and the same trained on the filter's
    states (``causal``), on random_2's steps (``test``, the loop's ``estimate`` (T+1, 2k) of it),
    each paired with the input sent the study's delay before it: RMS error per input (degrees)
    fed the smoother's states and fed the filter's."""
    workdir, grid = SWEEPS_DIR / "trunk_v2", trunk_v2.GRID["paper"]
    delay = study_delay("paper", workdir)
    u, smoothed = test.pairs(delay)  # (T-d, 6), (T-d+1, 2k)
    filtered_states = estimate[delay : delay + len(smoothed)]
    steps = slice(SETTLE, None)
    out = []
    for trained_on, causal in (("smoother", False), ("filter", True)):
        dataset = trunk_v2.training_set(observation, delay, grid, "paper", workdir, causal=causal)
        model, _ = recorded_cell_model(dict(model="mlp", seed=0), grid, "paper", dataset, workdir, "cpu")
        controller = Controller(model, "mlp", robot=None, gravity=None, workspace_margin=None)
        for fed, states in (("smoother", smoothed), ("filter", filtered_states)):
            planned = controller.step(states[:-1], states[1:], clip=False)  # (T-d, 6)
            error = float(np.sqrt(np.mean((planned[steps] - u[steps]) ** 2)))
            out.append(("input error", f"trained on the {trained_on}'s states, fed the {fed}'s", 0, error, "deg"))
    return out


def main(out="figures/bench/loop_parts_trunk.csv") -> None:
    pd.concat([measure(observation) for observation in OBSERVATIONS]).to_csv(out, index=False, float_format="%.4g")
    print(out)


if __name__ == "__main__":
    main()
