"""trunk_v2: the real robot asked notebook 12's question again, judged by referees that never saw
what they score (``judges``), validated by rows of their own before any planner row.

Fixed before any row (docs/assumptions.md, "The trunk study, asked again"):
- Data: every excited run that is not held out trains: ``random_1`` and its inputs replayed with
  100 g and 300 g at the tip (``payload_100g``, ``payload_300g``: the state alone cannot tell the
  load, so their inverse is many-valued, the flows' question), the last 15 % of each run's 2-s
  episodes validating. ``random_2`` (the same excitation) and ``circles`` (another) are held out,
  as in ``trunk``; ``rest`` excites nothing. One delay for the study, the training run's estimate
  from all disks (as ``trunk``), ``max_gap`` 0.6 s.
- Planners MLP, LSTM, Transformer, RF, RF-FWD, RF-1, RF-FWD-1; seeds 0-2; the tip alone or every
  disk observed; 5 000 optimiser steps each (batch 512, the best validation checkpoint).
- Judges (``judges``): ``ridge`` and ``kernel``, tip from inputs, anchored at each window's start.
  The judge that scores a held-out run is fitted on the unloaded runs other than it (``JUDGE_RUNS``:
  the plant the held-out runs record), so on the planners' training run ``random_1`` too (three
  unloaded runs allow no other choice). Windows of 0.5 s and 1 s every 5 s.
- Referee rows, computed and committed before any planner row: the recorded inputs (each judge's
  floor), the training runs' mean input, and the recorded inputs perturbed by known amounts
  (``judges.perturbations``; "delay 1" is persistence): each judge's resolution curve.
- Scores, judge-free first: (a) per-step input error (degrees, RMS per input) against the recorded
  inputs at the study's delay, and at the lag within +-5 periods that fits the run best; (e) the
  energy score of 16 draws (a regression model's: its error); (c) the spread of u given
  (x_t, x_t+1) on the training runs over its floor; then (b) each judge's tip error.
- Rule (``flow_rule``): per observation, held-out run and window, the best flow against the best
  baseline, best by the judge-free per-step error on that run. A difference is ranked only where,
  for every judge, the bootstrap interval (seeds and windows) and the paired t-interval (windows)
  exclude zero on the same side, its Holm-adjusted p is below 0.05 (one Holm family per judge: its
  comparisons on the judged families, below), and its size exceeds the larger of the judges' resolutions on that run and
  window; otherwise "not resolved by the judges". A planner either judge scores below the recorded
  inputs' floor is flagged.
- Added once the referee rows existed, before any planner row: a family (run and window) is judged
  only where every judge separates some perturbation from zero and rates none of them below the
  recorded inputs (``resolutions``' ``trusted``); the Holm family of each judge is its comparisons
  on the judged families. Why: on ``circles`` the ridge judge rates the recorded inputs delayed by
  1-10 periods better than the recorded ones (the kernel judge, delayed by 1 over 1-s windows), so
  there a judge would reward a planner's lag.
- Committed: the grid, scores and rule at 7f7d88d, the referee's rows and this gate at 1082574.
- The answer (``notebook_12_answer``): "confirms" notebook 12 (a flow lower on some family from the
  tip alone, on none with every disk), "reverses", "both", "neither" (families resolved, no flow
  lower) or "not resolved" (no family resolved).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from softflow import data
from softflow.control.planning import Controller, SaturationWarning, recorded_range
from softflow.data import recordings
from softflow.models.specs import BASELINES, FLOWS
from softflow.profiles import FIXED_BUDGET, TrainConfig
from softflow.store import cached_arrays
from softflow.studies import ambiguity, judges, stats, trunk
from softflow.studies.study import Grid, recorded_cell_model, training_spec

TRAINING_RUNS = ("random_1", "payload_100g", "payload_300g")
HELD_OUT = trunk.HELD_OUT  # random_2, circles
JUDGE_RUNS = ("random_1", *HELD_OUT)  # the unloaded runs: a judge of one is fitted on the others
# The models the grid trains (their groups: models.specs).
PLANNERS = ("mlp", "lstm", "transformer", "rf", "rf-fwd", "rf-1", "rf-fwd-1")
NAIVE = ("recorded", "training-mean")  # persistence is the perturbation "delay 1"
REFEREE = (*NAIVE, *judges.perturbations())  # the cells that validate the judges: no model trains
BLOCK = trunk.WINDOW_EVERY  # s: the judge-free scores per block of this length, one per window start
ALIGN = 5  # periods: the lags (a) is aligned over
LEVEL_P = 0.05  # Holm-adjusted p below which a judged difference may rank


@dataclass(frozen=True, kw_only=True)
class TrunkV2Grid(Grid):
    observations: tuple[str, ...]  # of trunk.OBSERVATIONS
    windows: tuple[float, ...]  # s: the judges' window lengths
    draws: int  # for the energy score
    seconds: float | None  # of each run (None: whole runs)


GRID = {
    "ci": TrunkV2Grid(
        models=("mlp", "rf"),
        seeds=(0,),
        observations=("tip", "disks"),
        windows=(0.5,),
        draws=4,
        train=FIXED_BUDGET["ci"],
        seconds=30.0,
    ),
    "paper": TrunkV2Grid(
        models=PLANNERS,
        seeds=(0, 1, 2),
        observations=("tip", "disks"),
        windows=(0.5, 1.0),
        draws=16,
        train=TrainConfig(epochs=10, steps_per_epoch=500, patience=10),
        seconds=None,
    ),
}


def cells(profile_name: str) -> list[dict]:
    """The referee's cells first (they run and ship before any planner's), then every planner's."""
    grid = GRID[profile_name]
    referee = [dict(study="trunk_v2", model=name, seed=0, observation="tip") for name in REFEREE]
    return referee + [
        dict(study="trunk_v2", model=model, seed=seed, observation=observation)
        for observation in grid.observations
        for model in grid.models
        for seed in grid.seeds
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One planner's (or referee input's) rows: per held-out run, judge window length and window,
    each judge's tip error and the judge-free scores of the block the window starts."""
    grid = GRID[profile_name]
    delay = trunk.study_delay(profile_name, workdir)
    runs = {name: _paired(name, cell["observation"], delay, grid, workdir) for name in HELD_OUT}
    tips = {name: _paired(name, "tip", delay, grid, workdir) for name in HELD_OUT}
    measured, draws = {}, {}
    if cell["model"] in REFEREE:
        mean_input = np.concatenate([_paired(n, "tip", delay, grid, workdir)[0] for n in TRAINING_RUNS]).mean(0)
        plans = {name: referee_plan(cell["model"], u, mean_input) for name, (u, _) in runs.items()}
    else:
        dataset = training_set(cell["observation"], delay, grid, profile_name, workdir)
        model, checkpoint = recorded_cell_model(cell, grid, profile_name, dataset, workdir, device)
        controller = Controller(
            model,
            cell["model"],
            robot=None,
            gravity=None,
            u_range=recorded_range(checkpoint["recorded"]),
            workspace_margin=None,
        )
        with warnings.catch_warnings():  # the clipped plan is what is scored
            warnings.simplefilter("ignore", SaturationWarning)
            plans = {name: controller.plan(states) for name, (_, states) in runs.items()}  # (T, 6): step t's input
        if controller.generative:  # (draws, T, 6): the flow's distribution, as sampled (not clipped)
            draws = {
                name: controller.sample(states, grid.draws, seed=cell["seed"]) for name, (_, states) in runs.items()
            }
        measured = dict(
            **ambiguity.cached_spread(dataset, workdir),
            best_val=float(checkpoint["best_val"]),
            train_minutes=float(checkpoint["wall_seconds"]) / 60,
        )
    rows = []
    for name in HELD_OUT:
        u, states = tips[name]
        tip = states[:, :3]  # (T+1, 3) m
        plan = plans[name]
        lag, per_input = aligned_error(plan, u, ALIGN)
        aligned = _shifted(plan, u, lag)  # (T, 6)
        energy = energy_score(draws.get(name, plan[None]), u)  # (T,)
        fitted = {kind: judge_of(kind, name, delay, grid, workdir) for kind in judges.KINDS}
        every = round(trunk.WINDOW_EVERY / trunk.DT)
        for seconds in grid.windows:
            length = round(seconds / trunk.DT)
            judged = {kind: judges.judged_errors(j, u, tip, plan, length, every) for kind, j in fitted.items()}
            for i, start in enumerate(judges.window_starts(len(u), length, every)):
                block = slice(start, start + every)
                rows.append(
                    dict(
                        run=name,
                        window_s=seconds,
                        family=f"{name}, {seconds:g} s",
                        reference=f"{name}-{seconds:g}s-{i:02d}",
                        u_error_deg=_rms(plan[block] - u[block]),
                        u_aligned_deg=_rms(aligned[block]),
                        energy_deg=float(energy[block].mean()),
                        **{f"{kind}_mm": float(judged[kind][i]) for kind in judges.KINDS},
                        **{f"{kind}_fitted_on": "+".join(fitted[kind].fitted_on) for kind in judges.KINDS},
                        run_u_error_deg=_rms(plan - u),
                        run_lag=lag,
                        **{f"run_{c}_aligned_deg": e for c, e in zip(trunk.INPUTS, per_input)},
                        run_energy_deg=float(energy.mean()),
                        delay_steps=delay,
                        **measured,
                    )
                )
    return rows


def _rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def _shifted(plan: np.ndarray, u: np.ndarray, lag: int) -> np.ndarray:
    """(T, m) plan[t] - u[t + lag], the ends past the run given zero error (a block's RMS then
    counts them as met: at most ALIGN of a run's steps)."""
    out = np.zeros_like(plan)
    t = np.arange(len(plan))
    valid = (t + lag >= 0) & (t + lag < len(u))
    out[valid] = plan[valid] - u[t[valid] + lag]
    return out


def aligned_error(plan: np.ndarray, u: np.ndarray, align: int) -> tuple[int, np.ndarray]:
    """The lag in -align..align at which plan[t] best meets the recorded u[t + lag] (RMS over the
    steps every lag can pair), and the per-input RMS error there: (lag, (m,))."""
    inner = np.arange(align, len(plan) - align)  # (T - 2 align,)
    errors = {lag: np.sqrt(np.mean((plan[inner] - u[inner + lag]) ** 2, 0)) for lag in range(-align, align + 1)}
    lag = min(errors, key=lambda k: float(np.sqrt(np.mean(errors[k] ** 2))))
    return lag, errors[lag]


def energy_score(samples: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The energy score per step of ``samples`` (n, T, m) against the recorded u (T, m): the mean
    distance of a draw to u minus half the mean distance between two draws, (T,). It is proper (a
    forecaster minimises it only by drawing from the true conditional law) and for one draw, a
    regression model's, it is that draw's error."""
    to_u = np.linalg.norm(samples - u, axis=-1).mean(0)  # (T,)
    between = np.linalg.norm(samples[:, None] - samples[None], axis=-1).mean((0, 1))  # (T,)
    return to_u - between / 2


def referee_plan(name: str, u: np.ndarray, mean_input: np.ndarray) -> np.ndarray:
    """(T, 6) inputs of a referee cell: a naive planner (``trunk.naive_plan``) or the recorded
    inputs perturbed by a known amount (``judges.perturbed``)."""
    if name in NAIVE:
        return trunk.naive_plan(name, u, mean_input)
    return judges.perturbed(u, name)


# ---------------------------------------------------------------------------- data and judges
def _paired(name: str, observation: str, delay: int, grid: TrunkV2Grid, workdir: Path, causal: bool = False):
    return trunk.paired_run(name, observation, delay, grid.seconds, workdir, causal)


def training_set(
    observation: str, delay: int, grid: TrunkV2Grid, profile_name: str, workdir: Path, causal: bool = False
) -> data.Dataset:
    """The training runs cut into 2-s episodes, the last 15 % of each run's validating (``causal``:
    the filter's states, for a model of the loop; not the study's)."""
    pieces = [trunk.episodes(*_paired(n, observation, delay, grid, workdir, causal)) for n in TRAINING_RUNS]
    u, states = (np.concatenate(parts) for parts in zip(*pieces))  # (E, 200, 6), (E, 201, 2k)
    position = np.concatenate([np.arange(len(p[0])) / len(p[0]) for p in pieces])  # within its run
    return data.Dataset(
        u=u,
        states=states,
        train=np.flatnonzero(position < 1 - trunk.VALIDATION),
        val=np.flatnonzero(position >= 1 - trunk.VALIDATION),
        test=np.zeros(0, int),
        key=f"trunk_v2-{observation}-{profile_name}-d{delay}-r{recordings.LOADER_REVISION}" + "-causal" * causal,
        robot=None,
        gravity=None,
        dt=trunk.DT,
        delay_steps=delay,
        input_columns=trunk.INPUTS,
        tip_columns=trunk.OBSERVATIONS[observation],
        causal=causal,
    )


def judge_of(kind: str, scored: str, delay: int, grid: TrunkV2Grid, workdir: Path) -> judges.Judge:
    """The judge of ``kind`` for the held-out run ``scored``, fitted on the other JUDGE_RUNS (cached)."""
    others = tuple(n for n in JUDGE_RUNS if n != scored)

    def compute():
        fitted_runs = {}
        for name in others:
            u, states = _paired(name, "tip", delay, grid, workdir)
            fitted_runs[name] = (u, states[:, :3])
        return judges.as_arrays(judges.fit(kind, fitted_runs, scored, trunk.DT))

    spec = dict(kind=kind, scores=scored, fitted_on=others, delay=delay, seconds=grid.seconds, **judges.settings())
    return judges.from_arrays(kind, scored, others, cached_arrays(workdir, "trunk-judge", spec, compute))


def models(cell: dict, profile_name: str) -> dict:
    """What a cell's rows depend on: its planner's arguments and budget, the judges' settings, the data."""
    grid = GRID[profile_name]
    planner = (
        {} if cell["model"] in REFEREE else training_spec(cell["model"], grid.budget(profile_name), seed=cell["seed"])
    )
    return dict(
        planner=planner,
        judges=dict(judges.settings(), runs=JUDGE_RUNS),
        training_runs=TRAINING_RUNS,
        loader=recordings.LOADER_REVISION,
        max_gap=trunk.MAX_GAP,
        windows=grid.windows,
        draws=grid.draws,
    )


# ---------------------------------------------------------------------------- the study's tables
JUDGED = tuple(f"{kind}_mm" for kind in judges.KINDS)
JUDGE_FREE = ("u_error_deg", "u_aligned_deg", "energy_deg")


def provenance(rows: pd.DataFrame) -> pd.DataFrame:
    """Every judge's fitted runs and the run it scored: one row per judge, scored run and fitted run."""
    out = {
        (kind, scored, fitted)
        for kind in judges.KINDS
        for scored, runs in rows[["run", f"{kind}_fitted_on"]].drop_duplicates().itertuples(index=False)
        for fitted in runs.split("+")
    }
    return pd.DataFrame(sorted(out), columns=["judge", "scores", "fitted_on"])


def _compare(rows: pd.DataFrame, model: str, other: str, family: str, value: str) -> dict:
    interval = stats.difference(rows, model, other, family, value)
    t = stats.paired_t(rows, model, other, family, value)
    return dict(difference=interval.estimate, low=interval.low, high=interval.high, t_low=t.low, t_high=t.high, p=t.p)


def floors(rows: pd.DataFrame) -> pd.DataFrame:
    """Each judge's floor, the recorded inputs' judged error (mm) [bootstrap interval], per family."""
    recorded = rows[rows.model == "recorded"]
    return pd.concat(
        [stats.summarise(recorded, column, by=("family",)).assign(judge=column[:-3]) for column in JUDGED]
    ).reset_index(drop=True)


def resolution(rows: pd.DataFrame) -> pd.DataFrame:
    """The resolution curves: per judge and family, each referee input minus the recorded inputs
    (mm, intervals over windows); ``separated`` where both intervals lie above zero, and whether
    the judged error grows with the size of each kind of perturbation (``monotone``)."""
    referee = rows[rows.model.isin(REFEREE)]
    out = []
    for column in JUDGED:
        for family in dict.fromkeys(referee.family):
            for name in REFEREE[1:]:
                compared = _compare(referee, name, "recorded", family, column)
                out.append(dict(judge=column[:-3], family=family, input=name, **compared))
    table = pd.DataFrame(out)
    if table.empty:
        return table
    table["separated"] = (table.low > 0) & (table.t_low > 0)
    kind = table.input.str.partition(" ")[0]
    larger = kind.isin(["delay", "noise"])  # their sizes ascend in order; the two scales are one size
    step_up = table.groupby([table.judge, table.family, kind], sort=False).difference.diff()
    rises = (table.difference > 0) & ~(larger & (step_up <= 0))
    table["monotone"] = rises.where(table.input.isin(judges.perturbations()))
    return table


def resolutions(curve: pd.DataFrame) -> pd.DataFrame:
    """Per judge and family: the smallest judged change among the perturbations it separates
    from zero (mm; NaN: it separates none), how many known-worse inputs it rates better than the
    recorded ones (both intervals below zero: ``reversed``), and whether it may judge there
    (``trusted``: it separates some and reverses none)."""
    perturbed = curve[curve.input.isin(judges.perturbations())]
    smallest = perturbed[perturbed.separated].groupby(["judge", "family"]).difference.min()
    table = perturbed.groupby(["judge", "family"], sort=False).size().rename("perturbations").to_frame()
    below = (perturbed.high < 0) & (perturbed.t_high < 0)
    table["reversed"] = below.groupby([perturbed.judge, perturbed.family]).sum().reindex(table.index)
    table["resolution_mm"] = smallest.reindex(table.index)
    table["smallest_separated"] = (
        perturbed[perturbed.separated]
        .sort_values("difference")
        .groupby(["judge", "family"])
        .input.first()
        .reindex(table.index)
    )
    table["trusted"] = table.resolution_mm.notna() & (table.reversed == 0)
    return table.reset_index()


def judged_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per judge, observation, planner and family: the mean judged tip error (mm) [bootstrap
    interval], flagged ``below_floor`` where it is below the recorded inputs' mean on that family."""
    tables = []
    for column in JUDGED:
        table = stats.summarise(rows, column, by=("observation", "model", "family")).assign(judge=column[:-3])
        floor = rows[rows.model == "recorded"].groupby("family")[column].mean()
        table["below_floor"] = (table["mean"] < table.family.map(floor)) & (table.model != "recorded")
        tables.append(table)
    return pd.concat(tables).reset_index(drop=True)


def judge_free(rows: pd.DataFrame) -> pd.DataFrame:
    """(a) and (e) per observation, planner and held-out run (degrees, mean [bootstrap interval]
    over seeds and 5-s blocks), from the first window length's rows (each block once)."""
    blocks = rows[rows.window_s == rows.window_s.min()].assign(family=lambda t: t.run)
    return pd.concat(
        [
            stats.summarise(blocks, column, by=("observation", "model", "family")).assign(score=column)
            for column in JUDGE_FREE
        ]
    ).reset_index(drop=True)


def per_input(rows: pd.DataFrame) -> pd.DataFrame:
    """Per observation, planner and held-out run: the lag (a) aligns at and the aligned per-input
    error (degrees), mean over seeds, and as a fraction of the training mean input's error."""
    columns = [f"run_{c}_aligned_deg" for c in trunk.INPUTS]
    once = rows.drop_duplicates(["observation", "model", "seed", "run"])
    table = once.groupby(["observation", "model", "run"], sort=False)[["run_lag", *columns]].mean()
    mean_input = once[once.model == "training-mean"].set_index("run")[columns]
    fraction = table[columns] / mean_input.reindex(table.index.get_level_values("run")).to_numpy()
    return table.join(fraction.rename(columns=lambda c: c.replace("_deg", "_fraction")))


def spread(rows: pd.DataFrame) -> pd.DataFrame:
    """(c) per observation: the spread of u given (x_t, x_t+1) on the training runs, over its floor."""
    trained_rows = rows[~rows.model.isin(REFEREE)].drop_duplicates("observation")
    table = trained_rows.set_index("observation")[["conditional_spread", "conditional_spread_floor"]]
    return table.assign(**{"spread / floor": table.conditional_spread / table.conditional_spread_floor})


def flow_rule(rows: pd.DataFrame) -> pd.DataFrame:
    """Per observation and family: the best flow against the best baseline (best by the judge-free
    per-step error on that run), as each judge scores them (one row per judge, ``stats.judged``,
    one Holm family per judge over the families it may judge, those with a ``resolution_mm``),
    and ``rule_lower``, the side the registered rule ranks lower on that comparison (module
    docstring: every judge ranks it lower, kept after Holm, by more than the resolution; NaN
    where it ranks none), the same on each judge's row."""
    curve = resolution(rows)
    if curve.empty:
        return pd.DataFrame()
    referee = resolutions(curve).groupby("family")
    limit = referee.resolution_mm.max().where(referee.trusted.all())  # NaN where a judge may not judge
    planners = rows[~rows.model.isin(REFEREE)]
    tables = []
    for column in JUDGED:
        out = []
        for observation, part in planners.groupby("observation", sort=False):
            picked = dict(by="u_error_deg", judge=column[:-3], observation=observation)
            out += stats.best_against_best(part, (FLOWS, BASELINES), dict.fromkeys(part.family), column, **picked)
        judged = [np.isfinite(limit.get(row["family"], np.nan)) for row in out]
        tables.append(stats.judged(out, ("judge", "observation"), in_family=judged, level=1 - LEVEL_P))
    table = pd.concat(tables, ignore_index=True)
    if table.empty:
        return table
    table["resolution_mm"] = table.family.map(limit)
    rule = {key: rule_lower(judges_rows) for key, judges_rows in table.groupby(["observation", "family"], sort=False)}
    return table.assign(rule_lower=[rule[key] for key in zip(table.observation, table.family)])


def rule_lower(judged: pd.DataFrame):
    """The registered rule on one comparison, from its judges' rows of ``flow_rule``: the side
    every judge ranks lower, kept after Holm, by more than the resolution; None where one does
    not, or where they disagree."""
    sides = judged.lower.where(judged.kept_after_holm & (judged.estimate.abs() > judged.resolution_mm))
    return sides.iloc[0] if sides.notna().all() and sides.nunique() == 1 else None


ANSWERS = {
    "confirms": "the trunk confirms notebook 12: a flow is lower from the tip alone, and on no family once every "
    "disk is seen",
    "reverses": "the trunk reverses notebook 12: no flow is lower from the tip alone, while one is once every disk is "
    "seen",
    "both": "the trunk does not show notebook 12's contrast: a flow is lower from the tip alone and also once every "
    "disk is seen",
    "neither": "the trunk shows no flow lower: the judges resolve differences, none of them a flow's win",
    "not resolved": "the judges resolve no difference between the best flow and the best baseline",
}


def notebook_12_answer(rule: pd.DataFrame) -> str:
    """The registered answer from ``flow_rule``'s verdicts (module docstring)."""
    if rule.empty:
        return "not resolved"
    flow_lower, resolved = rule.rule_lower == rule.a, rule.rule_lower.notna()
    tip, disks = (bool(flow_lower[rule.observation == o].any()) for o in ("tip", "disks"))
    if not resolved.any():
        return "not resolved"
    return {(True, False): "confirms", (False, True): "reverses", (True, True): "both"}.get((tip, disks), "neither")


def answer_sentence(rule: pd.DataFrame, computed: int, cells: int) -> str:
    """The answer in words with its rule, once every cell has rows; before, how far the study is."""
    if computed < cells:
        return f"{computed} of the study's {cells} cells have rows: no answer until every cell has."
    return (
        "By the rule fixed before any planner row (every judge agrees, both intervals, Holm within each judge, "
        f"beyond both judges' resolution, on the families both may judge), {ANSWERS[notebook_12_answer(rule)]}."
    )


def answer(rows: pd.DataFrame, profile_name: str) -> str:
    """``answer_sentence`` from the rows computed so far of the profile's grid: the README's and the page's."""
    rule = flow_rule(rows) if len(rows) else pd.DataFrame()
    return answer_sentence(rule, rows["key"].nunique() if len(rows) else 0, len(cells(profile_name)))


def summarise(rows: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The study's tables, judge-free first: (a), (e) ``judge_free`` and ``per_input``; (c)
    ``spread``; the referee's ``provenance``, ``floors`` and ``resolution``; (b) ``judged``; the
    question's ``flow_rule``."""
    planners = ~rows.model.isin(REFEREE)
    return dict(
        judge_free=judge_free(rows),
        per_input=per_input(rows),
        spread=spread(rows) if planners.any() else pd.DataFrame(),
        provenance=provenance(rows),
        floors=floors(rows),
        resolution=resolution(rows),
        judged=judged_table(rows),
        flow_rule=flow_rule(rows) if planners.any() else pd.DataFrame(),
    )
