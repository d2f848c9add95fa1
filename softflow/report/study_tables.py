"""The studies' rows (notebooks 08-11) turned into tables: intervals, differences, verdicts."""

from __future__ import annotations

import numpy as np
import pandas as pd

from softflow.report.tables import BASELINES, LABELS, MODELS, RF_FAMILY
from softflow.studies import stats
from softflow.studies.study import FLOOR

# ---------------------------------------------------------------------------- the sweeps (notebook 08)


def table_order(names) -> list:
    """The models among ``names`` in Table I order, the floor last."""
    return [m for m in (*MODELS, FLOOR) if m in set(names)]


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
    over seeds and references; models in Table I order, the floor last."""
    part = rows[(rows["family"] == family) & rows[value].notna()]
    table = stats.summarise(part, value, by=("model",)).set_index("model")
    return table.reindex(table_order(table.index))


def table1_ci(rows: pd.DataFrame) -> pd.DataFrame:
    """Table I from the table1 sweep: "mean [low, high]" in mm per model and family, and the
    seeds and references behind each."""
    columns = {}
    for family, label in (("shape", "shape_mm"), ("random", "random_mm")):
        summary = with_ci(rows, "rmse_mm", family)
        columns[label] = interval_text(summary)
        columns[f"{family}_seeds x refs"] = summary.apply(lambda r: f"{r.seeds:.0f} x {r.references:.0f}", axis=1)
    return pd.DataFrame(columns).rename_axis("model")


def best_against_best(rows: pd.DataFrame, value: str = "rmse_mm") -> pd.DataFrame:
    """Per family: the best RF variant minus the best baseline (best: lowest mean), with its
    interval, paired over references; a ranking is stated only where the interval excludes 0.
    (Picking the best of each group from the same rows biases the difference towards 0.)"""
    out = []
    for family in ("shape", "random"):
        means = with_ci(rows, value, family)["mean"]
        rf, baseline = means.reindex(RF_FAMILY).idxmin(), means.reindex(BASELINES).idxmin()
        interval = stats.difference(rows, rf, baseline, family, value)
        verdict = (
            f"{LABELS[rf]} {'lower' if interval.high < 0 else 'higher'}"
            if interval.excludes_zero
            else "no ranking (interval contains 0)"
        )
        out.append(
            dict(
                family=family,
                best_rf=rf,
                best_baseline=baseline,
                difference_mm=interval.estimate,
                low=interval.low,
                high=interval.high,
                verdict=verdict,
            )
        )
    return pd.DataFrame(out).set_index("family")


def protocol_table(rows: pd.DataFrame, family: str = "shape") -> pd.DataFrame:
    """Mean RMSE (mm) on a family per protocol condition (rows, the study's order) and model
    (columns, the floor last), with the references' mean coverage by the training states."""
    part = rows[rows["family"] == family]
    table = part.pivot_table(index="condition", columns="model", values="rmse_mm", sort=False)
    table = table[table_order(table.columns)]
    table["coverage"] = part.groupby("condition", sort=False)["coverage"].mean()
    return table


# ---------------------------------------------------------------------------- where a flow wins (notebook 09)
FLOWS = ("rf", "rf-fwd")  # against the MLP, fixed before the ambiguity study ran


def data_size_table(rows: pd.DataFrame, value: str = "rmse_mm") -> pd.DataFrame:
    """Mean of ``value`` with its interval per model, training episodes and reference family."""
    return stats.summarise(rows, value, by=("model", "episodes", "family"))


def per_step_table(rows: pd.DataFrame, by, values) -> pd.DataFrame:
    """Per-step measurements (one per trained model, repeated on its reference rows): the mean
    over seeds of each of ``values`` per group of ``by``."""
    per_model = rows.drop_duplicates(subset=[*by, "seed"])
    return per_model.groupby(list(by), sort=False)[list(values)].mean()


def regime_map(rows: pd.DataFrame) -> pd.DataFrame:
    """Per ambiguity variant: the conditional spread of u (and the estimator's floor) and each
    flow minus the MLP, z = 0 plans: tracking RMSE (mm) per family, paired over references,
    and the per-step u error (N), over seeds; a verdict only where an interval excludes 0."""
    out = []
    plans = rows[rows["plan"] == "zero"]
    for variant, part in plans.groupby("variant", sort=False):
        spread = part.iloc[0]
        for flow in (f for f in FLOWS if f in set(part["model"])):
            row = dict(
                variant=variant,
                flow=flow,
                conditional_spread=spread.conditional_spread,
                spread_floor=spread.conditional_spread_floor,
            )
            for family in ("shape", "random"):
                interval = stats.difference(part, flow, "mlp", family)
                row.update(
                    {
                        f"{family}_mm": interval.estimate,
                        f"{family}_low": interval.low,
                        f"{family}_high": interval.high,
                        f"{family}_verdict": _verdict(interval, flow),
                    }
                )
            # one number per trained model: the interval is over seeds alone, so it needs several
            steps = part.drop_duplicates(subset=["model", "seed"]).assign(reference="per step", family="step")
            interval = stats.difference(steps, flow, "mlp", "step", "u_rmse_test")
            several = steps.groupby("model").seed.nunique().min() > 1
            row.update(
                step_N=interval.estimate,
                step_low=interval.low if several else np.nan,
                step_high=interval.high if several else np.nan,
                step_verdict=_verdict(interval, flow) if several else "one seed: no interval",
            )
            out.append(row)
    return pd.DataFrame(out).set_index(["variant", "flow"])


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
    regression with the same prior), tracking RMSE in mm paired over references; the effects
    whose models the grid lacks are left out."""
    out = []
    for episodes, part in rows.groupby("episodes"):
        for effect, (model, other) in SIZE_EFFECTS.items():
            if not {model, other} <= set(part["model"]):
                continue  # a grid without one of them (the ci profile's)
            for family in ("shape", "random"):
                interval = stats.difference(part, model, other, family)
                out.append(
                    dict(
                        episodes=episodes,
                        effect=effect,
                        family=family,
                        difference_mm=interval.estimate,
                        low=interval.low,
                        high=interval.high,
                        verdict=_verdict(interval, model, other),
                    )
                )
    return pd.DataFrame(out).set_index(["episodes", "effect", "family"])


def lambda_decision(rows: pd.DataFrame, default: float = 1.0) -> tuple[pd.DataFrame, float]:
    """RF-FWD's consistency weight, the rule fixed before fwd_lambda ran: each weight minus the
    default (tracking RMSE, mm, paired over references) per family; the default changes only to
    a weight whose intervals exclude zero in its favour on both families (of several, the one
    lowest on the random references). Returns the table (``chosen`` marks the new default, if
    any) and the weight chosen."""
    weights = rows.assign(model=rows["consistency"].astype(float))
    out = []
    for weight in sorted(set(weights["model"]) - {default}):
        row = dict(consistency=weight)
        for family in ("shape", "random"):
            interval = stats.difference(weights, weight, default, family)
            row.update(
                {f"{family}_mm": interval.estimate, f"{family}_low": interval.low, f"{family}_high": interval.high}
            )
        row["better_on_both"] = row["shape_high"] < 0 and row["random_high"] < 0
        out.append(row)
    table = pd.DataFrame(out).set_index("consistency")
    better = table[table["better_on_both"]]
    chosen = float(better["random_mm"].idxmin()) if len(better) else default
    return table.assign(chosen=table.index == chosen), chosen


def _verdict(interval: stats.Interval, model: str, other: str = "mlp") -> str:
    if not interval.excludes_zero:
        return "no ranking"
    return f"{LABELS[model]} lower" if interval.high < 0 else f"{LABELS[other]} lower"
