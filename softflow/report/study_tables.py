"""The studies' rows (notebooks 08-11) turned into tables: intervals, differences, verdicts.

A difference gets two intervals, the two-way bootstrap over seeds and references and the paired
t-interval over references on seed means (``stats.compared``); a ranking needs both to exclude
zero (``stats.ranking``). Each verdict table is one family of comparisons in one schema
(``stats.COMPARISON``, made by ``stats.judged``): every comparison carries its Holm-adjusted
p-value over the table, the side ranked lower and whether Holm keeps that ranking. No table
holds words: the results page makes them (``report.sections.verdict``)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from softflow.control.metrics import table_rows
from softflow.data import OBSERVATIONS
from softflow.hardware.gap import GAP_TERMS
from softflow.models.specs import BASELINES, FLOWS
from softflow.report.tables import TABLE1_MODELS
from softflow.studies import stats
from softflow.studies.closed_loop import CAMERA_LATENCY, GAP_MODES, LOOP_MODES
from softflow.studies.design import VARIANTS as DESIGN_VARIANTS
from softflow.studies.stress import break_points
from softflow.studies.study import FLOOR
from softflow.studies.two_segment import FLOOR_OBSERVATION

# ---------------------------------------------------------------------------- the sweeps (notebook 08)


def table_order(names) -> list:
    """The models among ``names`` in Table I order, the floor last."""
    return [m for m in (*TABLE1_MODELS, FLOOR) if m in set(names)]


def interval_text(summary: pd.DataFrame, digits: int = 2) -> pd.Series:
    """ "mean [low, high]" for each row of a summary (columns mean, low, high)."""
    return pd.Series(
        [
            f"{m:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"
            for m, lo, hi in zip(summary["mean"], summary["low"], summary["high"])
        ],
        index=summary.index,
    )


def with_ci(rows: pd.DataFrame, value: str, family: str) -> pd.DataFrame:
    """Mean of ``value`` on a reference family per model, with its 95 % bootstrap interval
    over seeds and references; models in Table I order, the floor last (no rows: no models)."""
    part = rows[(rows["family"] == family) & rows[value].notna()] if len(rows) else rows
    if part.empty:
        return pd.DataFrame(columns=["mean", "low", "high", "seeds", "references"]).rename_axis("model")
    table = stats.summarise(part, value, by=("model",)).set_index("model")
    return table.reindex(table_order(table.index))


def table1_ci(rows: pd.DataFrame, families=("shape", "random")) -> pd.DataFrame:
    """Table I from the table1 sweep: "mean [low, high]" in mm per model and family, and the
    seeds and references behind each (a model a family lacks: empty cells)."""
    columns = {}
    for family in families:
        summary = with_ci(rows, "rmse_mm", family)
        columns[f"{family}_mm"] = interval_text(summary)
        columns[f"{family}_seeds x refs"] = _seeds_by_references(summary)
    table = pd.DataFrame(columns)
    return table.reindex(table_order(table.index)).rename_axis("model")


def _seeds_by_references(summary: pd.DataFrame) -> pd.Series:
    """ "seeds x references" behind each row of a ``with_ci`` summary."""
    return pd.Series([f"{r.seeds:.0f} x {r.references:.0f}" for r in summary.itertuples()], index=summary.index)


def best_against_best(rows: pd.DataFrame, value: str = "rmse_mm", families=("shape", "random")) -> pd.DataFrame:
    """Per family: the best flow minus the best baseline (``stats.best_against_best``), the
    families one Holm family; a family without a flow or a baseline in the rows (a grid, or a
    sweep not finished, that lacks one) is left out."""
    return stats.judged(stats.best_against_best(rows, (FLOWS, BASELINES), families, value))


def table1_summaries(rows: pd.DataFrame, families=("shape", "random")) -> pd.DataFrame:
    """``with_ci`` of the tracking RMSE per family, stacked (index family, model): notebook 08's file."""
    return pd.concat({family: with_ci(rows, "rmse_mm", family) for family in families}, names=["family"])


# Table II's measures with intervals: (column, value, family, digits)
TABLE2_CI = (
    ("phase_lag_s (shape)", "phase_lag_s", "shape", 3),
    ("input_energy (random)", "input_energy", "random", 2),
    ("mae_u1 (random)", "mae_u1", "random", 3),
)


def table2_ci(rows: pd.DataFrame) -> pd.DataFrame:
    """Table II from the table1 sweep: "mean [low, high]" per model of each of its measures."""
    return pd.DataFrame(
        {name: interval_text(with_ci(rows, value, family), digits) for name, value, family, digits in TABLE2_CI}
    )


def speed_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Mean shape RMSE per model and speed with its interval, from the protocol study's rows of
    Table I's condition and of its speed conditions."""
    fast = rows[((rows.condition == "table1") | rows.condition.str.startswith("speed-")) & (rows.family == "shape")]
    return stats.summarise(fast, "rmse_mm", by=("model", "speed"))


def design_table(rows: pd.DataFrame) -> pd.DataFrame:
    """The design study's variants (in its order) with their mean RMSE on each family (notebook 04)."""
    table = table_rows(rows.assign(model=rows.variant))
    return table.loc[list(DESIGN_VARIANTS), ["rmse_shape_mm", "rmse_random_mm"]]


def protocol_table(rows: pd.DataFrame, family: str = "shape") -> pd.DataFrame:
    """Mean RMSE (mm) on a family per protocol condition (rows, the study's order) and model
    (columns, the floor last), with the references' mean coverage by the training states."""
    part = rows[rows["family"] == family]
    table = part.pivot_table(index="condition", columns="model", values="rmse_mm", sort=False)
    table = table[table_order(table.columns)]
    table["coverage"] = part.groupby("condition", sort=False)["coverage"].mean()
    return table


# ---------------------------------------------------------------------------- the twin's reality gap (notebook 06)


def gap_sensitivity(rows: pd.DataFrame) -> pd.DataFrame:
    """Mean open-loop RMSE through the camera (mm) over Table III's shapes under each reality gap
    (rows: no gap, the typical gap, each term doubled), per configuration: the closed_loop study's
    open cells at the nominal camera."""
    shown = rows[
        (rows["mode"] == "open") & (rows.family == "shape") & (rows.latency == CAMERA_LATENCY) & (rows.dropped == 0)
    ]
    table = shown.groupby(["gap", "gravity"]).rmse_mm.apply(pd.Series.mean).unstack()  # Series.mean: the notebook's sum
    labels = {"none": "no gap", "typical": "typical gap", **{f"2x {t}": f"2 x {t}" for t in GAP_TERMS}}
    table = table.reindex([g for g in labels if g in table.index]).rename(index=labels)
    table.index.name, table.columns.name = None, None
    return table[[g for g in ("vertical", "horizontal") if g in table.columns]]


def closed_loop_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Table III extended (notebook 10): RMSE through the camera (mm) per configuration and
    reference, one column per loop mode present (in ``LOOP_MODES`` order), under the typical gap
    at the nominal camera; a ``mean`` row per configuration over the shapes, as Table III."""
    typical = rows[rows.gap == "typical"]
    main = typical[(typical.latency == CAMERA_LATENCY) & (typical.dropped == 0)]
    table = main.pivot_table(index=["gravity", "reference"], columns="mode", values="rmse_mm", sort=False)
    table = table[[m for m in LOOP_MODES if m in table.columns]]
    shapes = main[main.family == "shape"].groupby(["gravity", "mode"], sort=False).rmse_mm.mean().unstack()
    shapes = shapes[table.columns].assign(reference="mean").set_index("reference", append=True)
    return pd.concat([table, shapes]).sort_index(level=0, sort_remaining=False)


def latency_table(rows: pd.DataFrame) -> pd.DataFrame:
    """The closed loop's mean RMSE (mm) over the shapes under the typical gap, per camera latency
    and share of dropped frames, one column per configuration (notebook 10's robustness)."""
    closed = rows[(rows.gap == "typical") & (rows["mode"] == "closed") & (rows.family == "shape")]
    return closed.groupby(["gravity", "latency", "dropped"]).rmse_mm.mean().unstack("gravity")


def gap_modes_table(rows: pd.DataFrame) -> pd.DataFrame:
    """RMSE (mm) on each shape under each reality gap, per configuration and each loop mode of
    ``GAP_MODES``, at the nominal camera (the no-gap rows are notebook 06's)."""
    shown = rows[
        (rows.family == "shape")
        & (rows.latency == CAMERA_LATENCY)
        & (rows.dropped == 0)
        & rows["mode"].isin(GAP_MODES)
        & (rows.gap != "none")
    ]
    return shown.pivot_table(index="gap", columns=["gravity", "mode"], values="rmse_mm", sort=False)


def burst_revolutions(rows: pd.DataFrame) -> pd.DataFrame:
    """The twin_burst study's y-z RMSE (mm) per configuration and revolution of the burst circle,
    one column per loop mode, with the reference's speed and the mode lowest there."""
    keys, modes = ["gravity", "revolution", "period_s"], list(dict.fromkeys(rows["mode"]))
    table = rows.pivot_table(index=keys, columns="mode", values="rmse_yz_mm", sort=False)[modes]
    table.insert(0, "reference_speed", rows.groupby(keys, sort=False).reference_speed.first())
    return table.assign(lower=table[modes].idxmin(axis=1))


def burst_models(rows: pd.DataFrame) -> pd.DataFrame:
    """The twin_burst rows with each loop mode and configuration as one "model" ("closed,
    vertical"), as ``stress.break_points`` and the break curve read them."""
    return rows.assign(model=rows["mode"] + ", " + rows.gravity)


def burst_breaks(rows: pd.DataFrame) -> pd.DataFrame:
    """Where each loop mode and configuration breaks on the burst (``stress.break_points``)."""
    return break_points(burst_models(rows))


# ---------------------------------------------------------------------------- where a flow wins (notebook 09)
def data_size_table(rows: pd.DataFrame, value: str = "rmse_mm") -> pd.DataFrame:
    """Mean of ``value`` with its interval per model, training episodes and reference family."""
    return stats.summarise(rows, value, by=("model", "episodes", "family"))


def data_size_per_step(rows: pd.DataFrame) -> pd.DataFrame:
    """The per-step u error on the held-out episodes (N, mean over seeds) per size, one column per model."""
    return per_step_table(rows, ("episodes", "model"), ("u_rmse_test",)).unstack("model")


# The ambiguity study's per-step measures, one per trained model (u in N).
AMBIGUITY_STEP = (
    "conditional_spread",
    "conditional_spread_floor",
    "u_rmse_test",
    "u_rmse_draw",
    "u_rmse_mean_of_draws",
    "draw_spread",
    "spread_error_spearman",
)


def ambiguity_per_step(rows: pd.DataFrame) -> pd.DataFrame:
    """The ambiguity study's per-step measures present (``AMBIGUITY_STEP``) per variant and model."""
    return per_step_table(rows, ("variant", "model"), [c for c in AMBIGUITY_STEP if c in rows])


def ambiguity_tracking(rows: pd.DataFrame) -> pd.DataFrame:
    """The ambiguity study's tracking RMSE with its interval per variant, family, model and plan."""
    return stats.summarise(rows, "rmse_mm", by=("variant", "family", "model", "plan"))


def per_step_table(rows: pd.DataFrame, by, values) -> pd.DataFrame:
    """Per-step measurements (one per trained model, repeated on its reference rows): the mean
    over seeds of each of ``values`` per group of ``by``."""
    per_model = rows.drop_duplicates(subset=[*by, "seed"])
    return per_model.groupby(list(by), sort=False)[list(values)].mean()


def _seed_means(rows: pd.DataFrame, by: list, values: list, spread_of: list) -> pd.DataFrame:
    """``per_step_table`` of ``values`` per group of ``by``, with the seed spread (standard
    deviation, NaN for one seed) of ``spread_of`` as <name>_sd and the number of seeds."""
    per_model = rows.drop_duplicates(subset=[*by, "seed"]).groupby(by, sort=False)
    spread = per_model[spread_of].std().add_suffix("_sd")
    return per_step_table(rows, by, values).join(spread).assign(seeds=per_model["seed"].nunique())


def two_segment_variants(rows: pd.DataFrame) -> pd.DataFrame:
    """The two_segment study's model rows as regime-map variants ("two segments, tip", "two
    segments, tip+disk"): the same measures (conditional spread and its floor, z = 0 tracking on
    shapes and random references, per-step u error) on a rod whose inverse is many-valued by
    construction, beside the ambiguity study's variants; the floor and the 3-D paths left out."""
    if rows.empty:
        return rows
    models = rows[(rows["model"] != FLOOR) & rows["family"].isin(["shape", "random"])]
    return models.assign(variant="two segments, " + models["observation"])


def regime_rows(ambiguity_rows: pd.DataFrame, two_segment_rows: pd.DataFrame) -> pd.DataFrame:
    """The regime map's variants: the ambiguity study's and, as far as its rows go, the
    two_segment study's two observations (``two_segment_variants``)."""
    two_segments = two_segment_variants(two_segment_rows)
    return pd.concat([ambiguity_rows, two_segments], ignore_index=True) if len(two_segments) else ambiguity_rows


def regime_map(rows: pd.DataFrame) -> pd.DataFrame:
    """Per ambiguity variant: the conditional spread of u (and the estimator's floor) and each
    flow minus the MLP of z = 0 plans (``stats.judged``, one row per comparison): tracking RMSE
    (mm) per reference family, paired over references, every one of the map's a Holm family; and
    the per-step u error (N, family "step"), over seeds alone, so no t-interval and no ranking
    (one number per model leaves no references to pair over; with one seed, no interval)."""
    out = []
    plans = rows[rows["plan"] == "zero"]
    for variant, part in plans.groupby("variant", sort=False):
        spread = dict(
            variant=variant,
            conditional_spread=part.iloc[0].conditional_spread,
            spread_floor=part.iloc[0].conditional_spread_floor,
        )
        steps = part.drop_duplicates(subset=["model", "seed"]).assign(reference="per step", family="step")
        several = steps.groupby("model").seed.nunique().min() > 1
        for flow in (f for f in FLOWS if f in set(part["model"])):
            out += [spread | stats.compared(part, flow, "mlp", family) for family in ("shape", "random")]
            step = stats.compared(steps, flow, "mlp", "step", "u_rmse_test")
            out.append(spread | step | ({} if several else dict(low=np.nan, high=np.nan)))
    keys = ("variant", "conditional_spread", "spread_floor")
    return stats.judged(out, keys, in_family=[row["family"] != "step" for row in out])


# What data_size separates (fixed with the study): effect -> (model, the model it is compared with).
SIZE_EFFECTS = {
    "prior, regression": ("mlp-physical", "mlp"),
    "prior, flow": ("rf-physical", "rf"),
    "generative, no prior": ("rf", "mlp"),
    "generative, with prior": ("rf-physical", "mlp-physical"),
}


def size_effects(rows: pd.DataFrame) -> pd.DataFrame:
    """Per training-set size and reference family: the physics prior's effect (each model with
    the prior minus the same model without) and being generative's (each flow minus the
    regression with the same prior), tracking RMSE in mm paired over references (``stats.judged``,
    one Holm family); the effects whose models the grid lacks are left out."""
    out = []
    for episodes, part in rows.groupby("episodes"):
        for effect, (model, other) in SIZE_EFFECTS.items():
            if not {model, other} <= set(part["model"]):
                continue  # a grid without one of them (the ci profile's)
            out += [
                dict(episodes=episodes, effect=effect, **stats.compared(part, model, other, family))
                for family in ("shape", "random")
            ]
    return stats.judged(out, ("episodes", "effect"))


def lambda_table(rows: pd.DataFrame) -> pd.DataFrame:
    """fwd_lambda's tracking RMSE with its interval per consistency weight and family."""
    return stats.summarise(rows, "rmse_mm", by=("consistency", "family"))


def lambda_decision(rows: pd.DataFrame, default: float = 1.0) -> tuple[pd.DataFrame, float]:
    """RF-FWD's consistency weight, the rule fixed before fwd_lambda ran: each weight minus the
    default (tracking RMSE, mm, paired over references) per family (``stats.judged``, one Holm
    family, reported beside the rule, which was fixed without it); the default changes only to
    a weight ranked lower than it (both intervals) on both families (of several, the one lowest
    on the random references). Returns the table (``chosen`` marks the new default's rows, if
    any) and the weight chosen."""
    weights = rows.assign(model=rows["consistency"].astype(float))
    out = [
        stats.compared(weights, weight, default, family)
        for weight in sorted(set(weights["model"]) - {default})
        for family in ("shape", "random")
    ]
    table = stats.judged(out)
    better = [weight for weight, row in table.groupby("a") if (row.lower == weight).all() and len(row) == 2]
    random = table[table.family == "random"].set_index("a").estimate
    chosen = float(random[better].idxmin()) if better else default
    return table.assign(better_on_both=table.a.isin(better), chosen=table.a == chosen), chosen


def floor_progress(rows: pd.DataFrame, iterations: int) -> tuple[int, int]:
    """On how many of the ILC floor's references its best trial was its last (trial
    ``iterations``; trial 0 is the quasi-static plan), of how many: there it was still improving
    when it stopped, so the floor is at most its number."""
    trials = rows.loc[rows["model"] == FLOOR, "ilc_best_trial"]
    return int((trials == iterations).sum()), len(trials)


# ---------------------------------------------------------------------------- two segments (notebook 12)
# Per-step measures of the two_segment study, one per trained model (u in N, RMS per input; tip in mm).
TWO_SEGMENT_STEP = (
    "u_rmse_test",
    "u_rmse_draw",
    "u_rmse_mean_of_draws",
    "draw_spread",
    "tip_step_mm",
    "tip_step_mm_draw",
    "tip_step_mm_mean_of_draws",
)
_RANKS = {  # the order of a two-segment table's rows: observations as the study lists them, models as Table I
    "observation": {name: k for k, name in enumerate((*OBSERVATIONS, FLOOR_OBSERVATION))},
    "model": {name: k for k, name in enumerate((*TABLE1_MODELS, FLOOR))},
}


def _ordered(table: pd.DataFrame) -> pd.DataFrame:
    return table.sort_index(key=lambda level: level.map(_RANKS[level.name])) if len(table) else table


def _zero_plans(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows of z = 0 plans, and the floor's (which has no plan): what Table I scores."""
    if rows.empty or "plan" not in rows:
        return rows
    return rows[rows["plan"].isna() | (rows["plan"] == "zero")]


def _families(rows: pd.DataFrame) -> list:
    return list(dict.fromkeys(rows["family"])) if len(rows) else []


# The two-segment ILC row: an upper bound on the achievable error, not a floor (still improving
# when its trials ran out on some references; the random references' own inputs track exactly).
ILC_BOUND = "ilc (an upper bound)"


def two_segment_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Table I of the two_segment study: per observation and model (ILC on the true simulator
    last, as the observation "simulator", named ``ILC_BOUND``, where the grid has it), "mean
    [low, high]" tracking RMSE in mm of the z = 0 plans per reference family present, and the
    seeds and references behind it; the rows of an unfinished sweep give the cells they hold,
    no rows an empty table."""
    zero = _zero_plans(rows)
    if zero.empty:
        return pd.DataFrame(index=pd.MultiIndex.from_tuples([], names=["observation", "model"]))
    families = _families(zero)
    parts = {obs: table1_ci(part, families) for obs, part in zero.groupby("observation", sort=False)}
    return _ordered(pd.concat(parts, names=["observation", "model"])).rename(index={FLOOR: ILC_BOUND}, level="model")


ROTATED_PATHS = "path3d"  # the study's three 3-D paths: one path in three rotations (docs/assumptions.md)


def two_segment_differences(rows: pd.DataFrame) -> pd.DataFrame:
    """The study's decision rule per observation and family: the best flow minus the best
    baseline in tracking RMSE of the z = 0 plans (``stats.best_against_best``), ranked only where
    both intervals exclude zero, Holm over every observation and family; an observation or
    family without both groups is left out. The 3-D paths are not ranked and stay out of the
    Holm family: their three references are one path in three rotations, so their t-interval's
    two degrees of freedom count one path three times."""
    zero = _zero_plans(rows)
    observations = (
        sorted(set(zero["observation"]) - {FLOOR_OBSERVATION}, key=_RANKS["observation"].get) if len(zero) else []
    )
    out = []
    for observation in observations:
        part = zero[zero["observation"] == observation]
        out += stats.best_against_best(part, (FLOWS, BASELINES), _families(part), observation=observation)
    return stats.judged(out, ("observation",), in_family=[row["family"] != ROTATED_PATHS for row in out])


def two_segment_per_step(rows: pd.DataFrame) -> pd.DataFrame:
    """Per observation and model: the per-step measures present (``TWO_SEGMENT_STEP``) as means
    over seeds, the seed spread (standard deviation, NaN for one seed) of the u error and of
    ``tip_step_mm``, and the number of seeds. No ranking: one number per trained model leaves
    nothing to pair over."""
    models = rows[rows["model"] != FLOOR] if len(rows) else rows
    values = [value for value in TWO_SEGMENT_STEP if value in models]
    if models.empty or not values:
        return pd.DataFrame(index=pd.MultiIndex.from_tuples([], names=["observation", "model"]))
    return _ordered(_seed_means(models, ["observation", "model"], values, ["u_rmse_test", "tip_step_mm"]))


def two_segment_spread(rows: pd.DataFrame) -> pd.DataFrame:
    """Per observation of the models' data: the conditional spread of u given (x_t, x_t+1) over
    the training transitions (N, all inputs together), its estimator floor and their ratio (1:
    no ambiguity measurable), as the study's rows carry them (one dataset per observation)."""
    table = _spread_table(rows, ["observation"])
    return table.sort_index(key=lambda level: level.map(_RANKS["observation"])) if len(table) else table


SPREAD = ["conditional_spread", "conditional_spread_floor"]


def _spread_table(rows: pd.DataFrame, by: list) -> pd.DataFrame:
    """The conditional spread and its floor per ``by`` (one dataset each), and their ratio."""
    measured = rows.dropna(subset=SPREAD) if len(rows) and set(SPREAD) <= set(rows) else pd.DataFrame()
    if measured.empty:
        empty = pd.DataFrame(columns=[*by, *SPREAD, "spread / floor"])
        return empty.set_index(by)
    table = measured.groupby(by, sort=False)[SPREAD].mean()
    return table.assign(**{"spread / floor": table["conditional_spread"] / table["conditional_spread_floor"]})


# Which comparisons of each study's verdict table each count is over: label -> (study, its
# reference families; None: all).
VERDICTS = {
    "best RF variant - best baseline (table1)": ("table1", None),
    "flow - MLP, tracking (ambiguity)": ("ambiguity", ("shape", "random")),
    "flow - MLP, per-step u error (ambiguity)": ("ambiguity", ("step",)),
    "prior and generative effects (data_size)": ("data_size", None),
    "each lambda - lambda = 1 (fwd_lambda)": ("fwd_lambda", None),
}


def verdict_counts(tables: dict) -> pd.DataFrame:
    """How many comparisons each study's verdict table holds (``tables``: study -> the table of
    best_against_best, regime_map, size_effects or lambda_decision), how many the bootstrap
    interval alone would rank and how many both intervals rank (what the words state), and all
    of them together; a comparison without a t-interval (none per step) is ranked by the
    bootstrap alone only."""
    out = {}
    for label, (study, families) in VERDICTS.items():
        if study not in tables:
            continue
        table = tables[study]
        table = table if families is None else table[table["family"].isin(families)]
        counts = np.zeros(3, int)
        for row in table.itertuples():
            counts += [1, stats.ranking(stats.Interval(np.nan, row.low, row.high)) != 0, stats.interval_side(row) != 0]
        out[label] = dict(zip(("comparisons", "bootstrap alone", "bootstrap and t"), counts))
    table = pd.DataFrame.from_dict(out, orient="index").rename_axis("verdicts")
    return pd.concat([table, table.sum().rename("all").to_frame().T.rename_axis("verdicts")])


# ---------------------------------------------------------------------------- the recorded study (notebook 13)


def recorded_conditions(rows: pd.DataFrame) -> pd.Series:
    """Each row's condition in words: what its model learned from, under which gap; "friction,
    720 runs" for a model of recordings, "friction, simulator, open" for the simulator-trained
    RF-FWD in a loop mode."""
    runs = rows["runs"] if "runs" in rows else np.full(len(rows), np.nan)  # simulator cells have none
    learned = [
        f"{gap}, {n:.0f} runs" if trained_on == "recordings" else f"{gap}, simulator, {mode}"
        for gap, trained_on, n, mode in zip(rows["gap"], rows["trained_on"], runs, rows["mode"])
    ]
    return pd.Series(learned, index=rows.index, name="condition")


def recorded_spread(rows: pd.DataFrame) -> pd.DataFrame:
    """Does friction make the inverse many-valued? Per configuration, gap and recording size: the
    conditional spread of the motor commands given (x_t, x_t+1) over the training transitions, its
    estimator floor and their ratio (1: no ambiguity measurable), as the training cells carry them."""
    learned = rows[rows["trained_on"] == "recordings"] if len(rows) else rows
    return _spread_table(learned, ["gravity", "gap", "runs"])


# Per-step measures of a model of recordings on the held-out runs (motor commands, mm): its
# error, and a flow's one draw, mean of draws, the draws' spread and its rank correlation with the error.
RECORDED_STEP = ("u_rmse_test", "u_rmse_draw", "u_rmse_mean_of_draws", "draw_spread", "spread_error_spearman")


def recorded_per_step(rows: pd.DataFrame) -> pd.DataFrame:
    """Per configuration, condition (``recorded_conditions``) and model of recordings: the per-step
    measures present (``RECORDED_STEP``) as means over seeds (a flow's draw measures; NaN for a
    regression), the seed spread of the error (standard deviation) and the number of seeds. No
    ranking: one number per trained model leaves nothing to pair over."""
    index = ["gravity", "condition", "model"]
    learned = rows[rows["trained_on"] == "recordings"] if len(rows) else rows
    values = [value for value in RECORDED_STEP if value in learned]
    if learned.empty or not values:
        return pd.DataFrame(index=pd.MultiIndex.from_tuples([], names=index))
    return _seed_means(learned.assign(condition=recorded_conditions(learned)), index, values, ["u_rmse_test"])


def recorded_table(rows: pd.DataFrame) -> pd.DataFrame:
    """The recorded study's table: per configuration, condition (``recorded_conditions``) and
    model, "mean [low, high]" tracking RMSE in mm through the camera and of the true tip per
    reference family, with the seeds and references behind it (bootstrap over both)."""
    index = ["gravity", "condition", "model"]
    if rows.empty:
        return pd.DataFrame(index=pd.MultiIndex.from_tuples([], names=index))
    parts = {}
    for (gravity, condition), part in rows.assign(condition=recorded_conditions(rows)).groupby(
        ["gravity", "condition"], sort=False
    ):
        columns = {}
        for family in _families(part):
            camera, true = (with_ci(part, value, family) for value in ("rmse_mm", "rmse_true_mm"))
            columns[f"{family}_mm"] = interval_text(camera)
            columns[f"{family}_true_mm"] = interval_text(true)
            columns[f"{family}_seeds x refs"] = _seeds_by_references(camera)
        parts[(gravity, condition)] = pd.DataFrame(columns)
    return pd.concat(parts, names=index)


def recording_rule(rows: pd.DataFrame, family: str = "shape", value: str = "rmse_mm") -> pd.DataFrame:
    """The recorded study's "how much recording" rule, per configuration and recording size under
    friction: the better of MLP and RF trained on that many runs (a) minus the better of the
    simulator-trained RF-FWD open and open-calibrated (b), open loop against open loop, each
    named "model | conditions" (``stats.judged``: ranked only where both intervals exclude 0, one
    Holm family over sizes and configurations). A size or a configuration without both sides in
    the rows is left out."""
    part = rows[(rows["gap"] == "friction") & (rows["family"] == family)] if len(rows) else rows
    out = []
    if len(part):
        part = part.assign(learner=part["model"], model=part["model"] + " | " + recorded_conditions(part))
    for gravity, config in part.groupby("gravity", sort=False) if len(part) else ():
        simulator = config[(config["trained_on"] == "simulator") & config["mode"].isin(("open", "open-calibrated"))]
        recorded = config[(config["trained_on"] == "recordings") & config["learner"].isin(("mlp", "rf"))]
        if simulator.empty:
            continue
        for runs, sized in recorded.groupby("runs"):
            groups = (sized["model"].unique(), simulator["model"].unique())
            out += stats.best_against_best(config, groups, (family,), value, gravity=gravity, runs=int(runs))
    return stats.judged(out, ("gravity", "runs"))


def recorded_model_rule(rows: pd.DataFrame, family: str = "shape", value: str = "rmse_mm") -> pd.DataFrame:
    """The recorded study's "which model is best" rule, per configuration and gap among the models
    of recordings on the most runs: the best flow minus the best baseline (under friction, all
    five models; under the typical gap, RF minus MLP), as ``best_against_best``, Holm over the
    whole table. Column ``friction_changes``: "yes" where the two gaps rank opposite sides (a flow
    lower under one, a baseline under the other), "no" where they rank the same side, "unanswered"
    where either gap ranks nothing (so a missing ranking is never read as "friction changes
    nothing")."""
    learned = rows[rows["trained_on"] == "recordings"] if len(rows) else rows
    out = []
    for (gravity, gap), part in learned.groupby(["gravity", "gap"], sort=False) if len(learned) else ():
        most = part[part["runs"] == part["runs"].max()]
        out += stats.best_against_best(most, (FLOWS, BASELINES), (family,), value, gravity=gravity, gap=gap)
    table = stats.judged(out, ("gravity", "gap"))
    sides = {(row.gravity, row.gap): stats.lower_side(row) for row in table.itertuples()}
    changes = {}
    for gravity in table.gravity:
        both = sides.get((gravity, "friction"), 0) * sides.get((gravity, "typical"), 0)
        changes[gravity] = "yes" if both < 0 else "no" if both > 0 else "unanswered"
    return table.assign(friction_changes=[changes[gravity] for gravity in table.gravity])
