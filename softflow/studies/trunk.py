"""The trunk study: a real robot. The Stanford ASL trunk (datasets/asl_trunk/: three disks on a
hanging backbone, six servo motors pulling twelve tendons, motion capture at 100 Hz) learnt from
one recorded run and judged on two held-out runs, with the tip alone observed or all three disks.

Fixed before any row (docs/assumptions.md, "The trunk study"):
- Data: ``random_1`` trains (its first 85 % of 2-s episodes; the last 15 % validate), ``random_2``
  (the same excitation) and ``circles`` (another: out of distribution) are held out. Every run
  read with ``max_gap`` 0.6 s (the only longer losses are of disks 1-2: 0.33 s in random_2, 0.29
  and 0.50 s at the start of circles; the tip has none) and one input-to-motion delay for the
  study, the training run's estimate from all three disks (``estimate_delay``), so every model and
  the judge pair step t with the same input.
- Models MLP, LSTM, Transformer, RF, RF-FWD (RF-Physical needs a rod model: none here), seeds 0-2,
  on ``tip`` (x3, y3, z3 and their velocities) or ``disks`` (all nine and theirs), each 5 000
  optimiser steps (batch 512, no early stop; the best validation checkpoint).
- Scores on each held-out run: (a) per step, the u error (degrees, RMS per input) against the
  recorded inputs; (b) a forward judge of the trunk (the forward surrogate on all disks, trained on
  every run, held-out ones included, 10 000 steps) rolls each planner's inputs out over windows of
  0.5 s and 1 s starting every 5 s from the recorded state, and the tip it predicts is compared
  with the recorded tip (mm, RMS over the window); beside the models: the recorded inputs (the
  judge's floor), the training run's mean input, and persistence (the input sent one period
  before: the judge's resolution); (c) the spread of u given (x_t, x_t+1) on the training run,
  tip alone and all disks, over the estimator's floor; (d) for the flows, the spread of 16 draws against their error.
- Rule: a ranking only where the bootstrap interval (over seeds and windows) and the paired
  t-interval (over windows) of a difference both exclude zero; the judge ranks nothing on a family
  unless it tells the training mean from the recorded inputs by that rule. Best flow (RF, RF-FWD) against
  best baseline (MLP, LSTM, Transformer) per observation, run and window: does the tip alone give
  the flows a win that all disks take away, as on the simulated two-segment rod (notebook 12)?
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from softflow import data, training
from softflow.control.planning import Controller, recorded_range
from softflow.data import recordings
from softflow.models.specs import BASELINES, FLOWS
from softflow.profiles import FIXED_BUDGET, TrainConfig
from softflow.store import REPO, cached_arrays
from softflow.studies import ambiguity, stats
from softflow.studies.study import Grid, fixed_budget, recorded_cell_model, training_spec

TRUNK = REPO / "datasets" / "asl_trunk"
TRAINING_RUN, HELD_OUT = "random_1", ("random_2", "circles")
INPUTS = tuple(f"u{i}" for i in range(1, 7))
DISKS = tuple(f"{axis}{disk}_m" for disk in (1, 2, 3) for axis in "xyz")
OBSERVATIONS = {"tip": DISKS[6:], "disks": DISKS}
MAX_GAP = 0.6  # s
DT = 0.01  # s: the trunk's motion capture and commands, 100 Hz (datasets/asl_trunk/README.md)
EPISODE_STEPS = 200  # 2 s
VALIDATION = 0.15  # the last share of the training run's episodes
WINDOW_EVERY = 5.0  # s between the starts of the judge's windows
JUDGE = "forward"
PLANNERS = ("mlp", "lstm", "transformer", "rf", "rf-fwd")  # the models the grid trains (their groups: models.specs)
NAIVE = ("recorded", "training-mean", "persistence")  # planners that learn nothing: the judge's checks
# The judge is trusted on a family where it tells the training mean from the recorded inputs.
# Persistence is 0.05-0.5 degrees RMS from them per step (the inputs are smooth at 100 Hz): no
# judge of motion should tell it apart, so it measures the judge's resolution and gates nothing.
GATE = "training-mean"


@dataclass(frozen=True, kw_only=True)
class TrunkGrid(Grid):
    observations: tuple[str, ...]  # of OBSERVATIONS
    windows: tuple[float, ...]  # s: the judge's window lengths
    draws: int  # a flow's spread
    judge: TrainConfig  # the forward judge's budget
    seconds: float | None  # of each run (None: whole runs)


TRUNK_GRID = {
    "ci": TrunkGrid(
        models=("mlp", "rf"),
        seeds=(0,),
        observations=("tip", "disks"),
        windows=(0.5,),
        draws=4,
        train=FIXED_BUDGET["ci"],
        judge=FIXED_BUDGET["ci"],
        seconds=30.0,  # of each run
    ),
    "paper": TrunkGrid(
        models=PLANNERS,
        seeds=(0, 1, 2),
        observations=("tip", "disks"),
        windows=(0.5, 1.0),
        draws=16,
        train=TrainConfig(epochs=10, steps_per_epoch=500, patience=10),
        judge=TrainConfig(epochs=20, steps_per_epoch=500, patience=20),
        seconds=None,  # whole runs
    ),
}


def cells(profile_name: str) -> list[dict]:
    grid = TRUNK_GRID[profile_name]
    trained_cells = [
        dict(study="trunk", model=model, seed=seed, observation=observation)
        for observation in grid.observations
        for model in grid.models
        for seed in grid.seeds
    ]
    return [dict(study="trunk", model=name, seed=0, observation="disks") for name in NAIVE] + trained_cells


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One planner's rows: per held-out run and judge window, the judged tip error; each row also
    carries the cell's per-step scores on that run."""
    grid = TRUNK_GRID[profile_name]
    delay = study_delay(profile_name, workdir)
    seconds = grid.seconds
    runs = {name: paired_run(name, cell["observation"], delay, seconds, workdir) for name in HELD_OUT}
    judge = judge_model(profile_name, delay, device, workdir)
    full = {name: paired_run(name, "disks", delay, seconds, workdir) for name in HELD_OUT}
    if cell["model"] in NAIVE:
        training_mean = paired_run(TRAINING_RUN, "disks", delay, seconds, workdir)[0].mean(0)  # (6,)
        plans = {name: naive_plan(cell["model"], u, training_mean) for name, (u, _) in runs.items()}
        per_step = {name: dict(u_rmse_deg=_rms(plans[name] - runs[name][0])) for name in HELD_OUT}
        measured = {}
    else:
        dataset = training_set(cell["observation"], delay, TRUNK_GRID[profile_name].seconds, workdir)
        model, checkpoint = recorded_cell_model(cell, grid, profile_name, dataset, workdir, device)
        u_range = recorded_range(checkpoint["recorded"])  # as load_controller clips a model of recordings
        controller = Controller(model, cell["model"], robot=None, gravity=None, u_range=u_range, workspace_margin=None)
        plans = {name: controller.plan(states) for name, (_, states) in runs.items()}  # (T, 6): step t's input
        per_step = {
            name: dict(
                u_rmse_deg=_rms(plans[name] - runs[name][0]),
                **_flow_scores(controller, runs[name], grid.draws),
            )
            for name in HELD_OUT
        }
        measured = dict(
            **ambiguity.cached_spread(dataset, workdir),
            best_val=float(checkpoint["best_val"]),
            train_minutes=float(checkpoint["wall_seconds"]) / 60,
        )
    rows = []
    for name in HELD_OUT:
        u, states = full[name]
        for seconds in grid.windows:
            errors = judged_errors(judge, states, plans[name], round(seconds / DT), delay)
            rows += [
                dict(
                    run=name,
                    window_s=seconds,
                    family=f"{name}, {seconds:g} s",
                    reference=f"{name}-{seconds:g}s-{i:02d}",
                    tip_mm=float(error),
                    delay_steps=delay,
                    **per_step[name],
                    **measured,
                )
                for i, error in enumerate(errors)
            ]
    return rows


def _rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def _flow_scores(controller: Controller, pair, draws: int) -> dict:
    """For a flow, its draws' spread and how it ranks their error (``ambiguity.per_step_scores``)."""
    if not controller.generative:
        return {}
    u, states = pair
    held_out = data.Dataset(
        u=u[None],
        states=states[None],
        train=np.zeros(0, int),
        val=np.zeros(0, int),
        test=np.array([0]),
        robot=None,
        gravity=None,
        dt=DT,
    )
    scores = ambiguity.per_step_scores(controller, held_out, draws)
    return {k: v for k, v in scores.items() if k != "u_rmse_test"}


def naive_plan(name: str, u: np.ndarray, training_mean: np.ndarray) -> np.ndarray:
    """(T, 6) inputs of a planner that learns nothing: the recorded inputs themselves (the judge's
    floor), the training run's mean input, or persistence (each step given the input before it)."""
    if name == "recorded":
        return u
    if name == "training-mean":
        return np.broadcast_to(training_mean, u.shape).copy()
    if name == "persistence":
        return np.concatenate([u[:1], u[:-1]])
    raise ValueError(f"naive planner must be one of {list(NAIVE)}; got {name!r}")


def judged_errors(judge, states: np.ndarray, plan: np.ndarray, length: int, delay: int) -> np.ndarray:
    """The judge's tip error (mm, RMS over the window) for windows of ``length`` steps starting
    every WINDOW_EVERY s: from the recorded state (all disks, (T+1, 18)) at each window's start,
    step t advanced by the planned input paired with it (plan (T, 6)), the disk-3 position against
    the recorded one."""
    every = int(round(WINDOW_EVERY / DT))
    starts = np.arange(0, len(plan) - length + 1, every)  # (W,)
    x = torch.as_tensor(states[starts], dtype=torch.float32)  # (W, 18)
    tips = []
    with torch.inference_mode():
        for k in range(length):
            u = torch.as_tensor(plan[starts + k], dtype=torch.float32)  # (W, 6)
            x = judge.predict_next(x, u)
            tips.append(x[:, 6:9].numpy())
    predicted = np.stack(tips, 1)  # (W, length, 3)
    recorded = np.stack([states[s + 1 : s + 1 + length, 6:9] for s in starts])  # (W, length, 3)
    return 1e3 * np.sqrt(np.mean(np.sum((predicted - recorded) ** 2, -1), axis=1))


# ---------------------------------------------------------------------------- data
def _file(name: str) -> Path:
    return TRUNK / f"{name}.csv.gz"


def study_delay(profile_name: str, workdir: Path) -> int:
    """The study's delay in periods: the training run's estimate from all three disks (cached)."""

    def compute():
        run = recordings.read(_file(TRAINING_RUN), inputs=list(INPUTS), tip=list(DISKS), max_gap=MAX_GAP)
        tip = recordings.read(_file(TRAINING_RUN), inputs=list(INPUTS), tip=list(DISKS[6:]), max_gap=MAX_GAP)
        return dict(delay_steps=np.int64(run.delay_steps), tip_delay_steps=np.int64(tip.delay_steps))

    spec = dict(file=_file(TRAINING_RUN).name, version=recordings.LOADER_REVISION)
    return int(cached_arrays(workdir, "trunk-delay", spec, compute)["delay_steps"])


def paired_run(name: str, observation: str, delay: int, seconds: float | None, workdir: Path, causal: bool = False):
    """Inputs (T, 6) and states (T+1, 2k) of one run, step t paired with the input sent ``delay``
    periods before it (its first ``seconds`` only, None: all of it; ``causal``: the filter's
    states, as ``recordings.read`` makes them; cached)."""

    def compute():
        columns = dict(inputs=list(INPUTS), tip=list(OBSERVATIONS[observation]))
        run = recordings.read(_file(name), **columns, max_gap=MAX_GAP, delay=delay * DT, causal=causal)
        u, states = run.pairs()
        if run.dt != DT:
            raise ValueError(f"{name}: a period of {run.dt} s; the trunk's runs are at {DT} s")
        if seconds is not None:
            n = int(round(seconds / run.dt))
            u, states = u[:n], states[: n + 1]
        return dict(u=u, states=states)

    spec = dict(run=name, observation=observation, delay=delay, seconds=seconds, version=recordings.LOADER_REVISION)
    spec |= {"causal": True} if causal else {}  # the smoother's states keep their keys
    arrays = cached_arrays(workdir, "trunk-run", spec, compute)
    return arrays["u"], arrays["states"]


def episodes(u: np.ndarray, states: np.ndarray, n_steps: int = EPISODE_STEPS):
    """A run's (T, m) inputs and (T+1, d) states cut into episodes of ``n_steps``: (E, n, m), (E, n+1, d)."""
    cuts = recordings.episodes([len(u)], n_steps)
    return np.stack([u[s : s + n_steps] for _, s in cuts]), np.stack([states[s : s + n_steps + 1] for _, s in cuts])


def training_set(observation: str, delay: int, profile_name: str, workdir: Path) -> data.Dataset:
    """The training run cut into 2-s episodes, the last VALIDATION of them validating; the held-out
    random run's episodes as its test split (for the per-step scores of the training loop only)."""
    u, states = episodes(
        *paired_run(TRAINING_RUN, observation, delay, TRUNK_GRID[profile_name].seconds, workdir), EPISODE_STEPS
    )
    n_val = max(1, round(VALIDATION * len(u)))
    key = f"trunk-{observation}-{profile_name}-d{delay}-r{recordings.LOADER_REVISION}"
    return data.Dataset(
        u=u,
        states=states,
        train=np.arange(len(u) - n_val),
        val=np.arange(len(u) - n_val, len(u)),
        test=np.zeros(0, int),
        key=key,
        robot=None,
        gravity=None,
        dt=DT,
        delay_steps=delay,
        input_columns=INPUTS,
        tip_columns=OBSERVATIONS[observation],
    )


def judge_model(profile_name: str, delay: int, device: str, workdir: Path):
    """The forward judge: the forward surrogate on all disks, trained on every run (held-out ones
    included; the inverse models never see them), the last 15 % of each run's episodes validating."""
    pieces = [
        episodes(*paired_run(name, "disks", delay, TRUNK_GRID[profile_name].seconds, workdir), EPISODE_STEPS)
        for name in (TRAINING_RUN, *HELD_OUT)
    ]
    u, states = (np.concatenate(parts) for parts in zip(*pieces))
    owner = np.concatenate([np.full(len(p[0]), i) for i, p in enumerate(pieces)])
    position = np.concatenate([np.arange(len(p[0])) / len(p[0]) for p in pieces])
    judged = data.Dataset(
        u=u,
        states=states,
        train=np.flatnonzero(position < 1 - VALIDATION),
        val=np.flatnonzero(position >= 1 - VALIDATION),
        test=np.zeros(0, int),
        key=f"trunk-judge-{profile_name}-d{delay}-r{recordings.LOADER_REVISION}-{len(owner)}",
        robot=None,
        gravity=None,
        dt=DT,
        delay_steps=delay,
    )
    model, _ = training.ensure_trained(
        JUDGE,
        fixed_budget(profile_name, TRUNK_GRID[profile_name].judge),
        judged,
        None,
        None,
        root=workdir / "judge" / profile_name,
        device=device,
    )
    return model.eval()


def models(cell: dict, profile_name: str) -> dict:
    """What a cell's rows depend on: its model's arguments and budget, the judge's, the data."""
    grid = TRUNK_GRID[profile_name]
    judge = training_spec(JUDGE, fixed_budget(profile_name, grid.judge))
    planner = (
        {} if cell["model"] in NAIVE else training_spec(cell["model"], grid.budget(profile_name), seed=cell["seed"])
    )
    return dict(planner=planner, judge=judge, loader=recordings.LOADER_REVISION, max_gap=MAX_GAP, windows=grid.windows)


def run_facts(names=(TRAINING_RUN, *HELD_OUT), delays_of=(TRAINING_RUN,)) -> pd.DataFrame:
    """What each run is, read as the study reads it: rows, the lost frames per disk (held and
    one-frame jumps, on the raw table), and for the runs ``delays_of`` the estimated delay in
    periods from the tip alone and from all disks (those read and smooth the run: tens of seconds)."""
    out = []
    for name in names:
        table = pd.read_csv(_file(name))
        tip = table[list(DISKS)].to_numpy(float)  # (R, 9)
        _, held, jumps = recordings.lost_frames(table.time_s.to_numpy(float), tip, DISKS)
        row = dict(run=name, rows=len(table), seconds=float(table.time_s.iloc[-1]))
        row.update({f"held_disk{d}": int(held[3 * (d - 1)]) for d in (1, 2, 3)})
        row.update({f"jumps_disk{d}": int(jumps[3 * (d - 1)]) for d in (1, 2, 3)})
        if name in delays_of:
            for observation, columns in OBSERVATIONS.items():
                run = recordings.read(_file(name), inputs=list(INPUTS), tip=list(columns), max_gap=MAX_GAP)
                row[f"delay_{observation}"] = run.delay_steps
        out.append(row)
    return pd.DataFrame(out).set_index("run")


# ---------------------------------------------------------------------------- the study's tables
def judged_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Mean judged tip error (mm) [bootstrap interval] per observation, planner and family."""
    return stats.summarise(rows, "tip_mm", by=("observation", "model", "family"))


def judge_check(rows: pd.DataFrame) -> pd.DataFrame:
    """Per family: can the judge tell each naive planner from the recorded inputs (its floor)? Each
    planner minus the recorded inputs in judged tip error (``stats.compared``); only where both
    intervals put the GATE planner higher (``tells_apart``) is anything ranked on the judge."""
    naive = rows[rows.model.isin(NAIVE)]
    table = pd.DataFrame(
        [
            stats.compared(naive, name, "recorded", family, "tip_mm")
            for family in dict.fromkeys(naive.family)
            for name in NAIVE[1:]
        ],
        columns=stats.COMPARED,
    )
    return table.assign(tells_apart=[stats.interval_side(row) > 0 for row in table.itertuples()])


def flow_rule(rows: pd.DataFrame) -> pd.DataFrame:
    """The study's question per observation and family: the best flow minus the best baseline
    (best: lowest mean judged error, picked on these rows, ``stats.best_against_best``), ranked
    only where both intervals exclude zero and the judge tells the training mean from its floor
    on that family (``judge_passes``); the families the judge passes are one Holm family."""
    judged = judge_check(rows)
    passed = judged.family[(judged.a == GATE) & judged.tells_apart]
    planners = rows[~rows.model.isin(NAIVE)]
    out = []
    for observation, part in planners.groupby("observation", sort=False):
        out += stats.best_against_best(
            part, (FLOWS, BASELINES), dict.fromkeys(part.family), "tip_mm", observation=observation
        )
    table = stats.judged(out, ("observation",), in_family=[row["family"] in set(passed) for row in out])
    return table.assign(judge_passes=table.family.isin(set(passed)))


ANSWERS = {  # notebook_12_answer in words, for the README and the results page (its answer is withdrawn)
    "confirms": "the real robot confirms notebook 12: a flow is lower from the tip alone, and on no family once "
    "every disk is seen",
    "reverses": "the real robot does not confirm notebook 12: no flow is lower from the tip alone, while one is "
    "lower once every disk is seen",
    "both": "the real robot does not show notebook 12's contrast: a flow is lower from the tip alone and also once "
    "every disk is seen",
    "neither": "the real robot neither confirms nor contradicts notebook 12: no flow is lower from either observation",
}


def notebook_12_answer(rule: pd.DataFrame) -> str:
    """Does the trunk show notebook 12's pattern, a flow lower from the tip alone and not once
    every disk is seen? By the rule registered before any row: a flow is lower on a family where
    both intervals of ``flow_rule``'s difference lie below zero and the judge passed that family
    (``lower`` is the flow there). No Holm family was registered: the one over all eight
    comparisons was added with 22 of the 33 paper cells computed (docs/assumptions.md), so it
    decides nothing here. "confirms" (a flow lower on some family from the tip alone, on none with
    every disk), "reverses" (the other way round), "both" (a flow lower either way) or "neither"."""
    flow_lower = rule.lower == rule.a
    flows_lower = flow_lower.groupby(rule.observation).any()
    tip, disks = flows_lower.get("tip", False), flows_lower.get("disks", False)
    return {(True, False): "confirms", (False, True): "reverses", (True, True): "both"}.get((tip, disks), "neither")


def per_step(rows: pd.DataFrame) -> pd.DataFrame:
    """Per observation, planner and held-out run: the u error (degrees, RMS), for the flows the
    draws' spread and its rank correlation with the error, mean over seeds (and their count)."""
    columns = [c for c in ("u_rmse_deg", "u_rmse_draw", "draw_spread", "spread_error_spearman") if c in rows]
    once = rows.drop_duplicates(["observation", "model", "seed", "run"])
    table = once.groupby(["observation", "model", "run"], sort=False)[columns].mean()
    table["seeds"] = once.groupby(["observation", "model", "run"], sort=False).seed.nunique()
    return table


def spread(rows: pd.DataFrame) -> pd.DataFrame:
    """Per observation: the spread of u given (x_t, x_t+1) on the training run, over its floor."""
    trained_rows = rows[~rows.model.isin(NAIVE)].drop_duplicates("observation")
    table = trained_rows.set_index("observation")[["conditional_spread", "conditional_spread_floor"]]
    return table.assign(**{"spread / floor": table.conditional_spread / table.conditional_spread_floor})


def summarise(rows: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The study's tables from its rows, what notebook 14, the results page and the README read:
    (b) the judged tip error (``judged``), the judge's check (``judge_check``) and the flows'
    rule (``flow_rule``); (a) and (d) per step (``per_step``); (c) the spread (``spread``)."""
    return dict(
        judged=judged_table(rows),
        judge_check=judge_check(rows),
        flow_rule=flow_rule(rows),
        per_step=per_step(rows),
        spread=spread(rows),
    )
