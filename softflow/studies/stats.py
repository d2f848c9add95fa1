"""Confidence intervals for results over training seeds and references.

A Table I number is a mean over two random samples at once: the training seeds (another
seed, another model) and the references (another reference, another error). The bootstrap
here resamples both, independently (two-way), so an interval covers what a rerun with new
seeds on new references of the same families would give. Differences between two models
are paired over references (both are scored on the same ones) and unpaired over seeds
(seed 1 of one model has nothing to do with seed 1 of another). It is written here because no
library resamples two crossed factors at once (scipy's ``bootstrap`` resamples one sample, or
paired samples together); the t-test is scipy's, Holm's adjustment statsmodels'.

The paired t-interval is a second, stricter check on a difference: it averages each model's
seeds per reference and treats the references alone as the sample, so a difference that rests
on a few references far from the rest stays unranked even where the bootstrap, which also sees
the seeds, calls it. A ranking is stated only where both exclude zero (``ranking``). A study
makes many comparisons at 95 % each: its verdict table (``judged``, one schema for every study)
is one family, and a ranking whose Holm-adjusted t-test p-value (``holm``) is not below 5 % is
marked as one the family-wise view removes. Words are made from these tables by the report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats as distributions

N_BOOT = 10_000
LEVEL = 0.95


@dataclass(frozen=True)
class Interval:
    estimate: float  # the mean over every seed and reference
    low: float
    high: float
    p: float = np.nan  # a t-interval's two-sided p-value of "no difference" (NaN for the bootstrap)

    @property
    def excludes_zero(self) -> bool:
        return self.low > 0 or self.high < 0


def _grid(values, name: str) -> np.ndarray:
    grid = np.asarray(values, float)
    if grid.ndim != 2 or grid.size == 0 or not np.all(np.isfinite(grid)):
        raise ValueError(
            f"{name} must be a finite (seeds, references) array with at least one entry; got shape {grid.shape}"
        )
    return grid


def _resampled_means(grid: np.ndarray, references: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    seeds = rng.integers(0, len(grid), (len(references), len(grid)))
    return grid[seeds[:, :, None], references[:, None, :]].mean(axis=(1, 2))


def bootstrap(a, b=None, *, n_boot: int = N_BOOT, level: float = LEVEL, seed: int = 0) -> Interval:
    """Percentile interval of mean(a), or of mean(a) - mean(b) when ``b`` is given; ``a`` and
    ``b`` are (seeds, references) arrays over the same references in the same order (their
    seed counts may differ)."""
    a = _grid(a, "a")
    if b is not None:
        b = _grid(b, "b")
        if b.shape[1] != a.shape[1]:
            raise ValueError(f"a and b must score the same references; got {a.shape[1]} and {b.shape[1]} columns")
    if not (0 < level < 1 and isinstance(n_boot, int) and n_boot >= 100):
        raise ValueError(f"need 0 < level < 1 and an integer n_boot >= 100; got {level!r}, {n_boot!r}")
    rng = np.random.default_rng(seed)
    references = rng.integers(0, a.shape[1], (n_boot, a.shape[1]))  # shared: the pairing
    means = _resampled_means(a, references, rng)
    estimate = a.mean()
    if b is not None:
        means = means - _resampled_means(b, references, rng)
        estimate -= b.mean()
    low, high = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return Interval(float(estimate), float(low), float(high))


def ratio(a, b, *, n_boot: int = N_BOOT, level: float = LEVEL, seed: int = 0) -> Interval:
    """Percentile interval of mean(a) / mean(b), paired over references as ``bootstrap`` pairs a
    difference: how many times the other's error a model's is."""
    a, b = _grid(a, "a"), _grid(b, "b")
    if b.shape[1] != a.shape[1]:
        raise ValueError(f"a and b must score the same references; got {a.shape[1]} and {b.shape[1]} columns")
    if not (0 < level < 1 and isinstance(n_boot, int) and n_boot >= 100):
        raise ValueError(f"need 0 < level < 1 and an integer n_boot >= 100; got {level!r}, {n_boot!r}")
    rng = np.random.default_rng(seed)
    references = rng.integers(0, a.shape[1], (n_boot, a.shape[1]))
    ratios = _resampled_means(a, references, rng) / _resampled_means(b, references, rng)
    low, high = np.quantile(ratios, [(1 - level) / 2, (1 + level) / 2])
    return Interval(float(a.mean() / b.mean()), float(low), float(high))


def within(interval: Interval, band: tuple[float, float]) -> str:
    """An equivalence in words: "within" where the interval lies inside ``band`` (low, high),
    "outside" where it lies wholly beyond one of its ends, else "undecided"."""
    low, high = band
    if low <= interval.low and interval.high <= high:
        return "within"
    if interval.high < low or interval.low > high:
        return "outside"
    return "undecided"


def seed_reference_grid(rows: pd.DataFrame, value: str, references=None) -> np.ndarray:
    """One model's rows (columns seed, reference, ``value``) as a (seeds, references) array,
    references in the order given (another model's, to pair with it), else of first appearance."""
    grid = rows.pivot_table(index="seed", columns="reference", values=value, sort=False)
    if grid.isna().any().any():
        raise ValueError(f"{value}: not every seed scored every reference")
    order = list(dict.fromkeys(rows["reference"])) if references is None else list(references)
    if set(order) != set(grid.columns):
        raise ValueError(f"{value}: the rows score {sorted(grid.columns)}, not {sorted(order)}")
    return grid[order].to_numpy()


def summarise(rows: pd.DataFrame, value: str = "rmse_mm", by=("model", "family"), **options) -> pd.DataFrame:
    """Mean of ``value`` with its two-way bootstrap interval for each group of ``by``, and
    the seeds and references it rests on."""
    out = []
    for group, part in rows.groupby(list(by), sort=False):
        grid = seed_reference_grid(part, value)
        interval = bootstrap(grid, **options)
        out.append(
            dict(
                zip(by, group),
                mean=interval.estimate,
                low=interval.low,
                high=interval.high,
                seeds=grid.shape[0],
                references=grid.shape[1],
            )
        )
    return pd.DataFrame(out)


def difference(rows: pd.DataFrame, model: str, other: str, family: str, value: str = "rmse_mm", **options) -> Interval:
    """mean(model) - mean(other) of ``value`` on a reference family, paired over references
    (the other model's grid in the model's reference order, whatever the order of its rows)."""
    part = rows[rows["family"] == family]
    references = dict.fromkeys(part.loc[part["model"] == model, "reference"])
    grids = [seed_reference_grid(part[part["model"] == name], value, references) for name in (model, other)]
    return bootstrap(*grids, **options)


def seed_means(rows: pd.DataFrame, value: str) -> pd.Series:
    """One model's mean of ``value`` over its seeds per reference (every seed must score every
    reference), indexed by reference in the order of first appearance."""
    references = list(dict.fromkeys(rows["reference"]))
    return pd.Series(seed_reference_grid(rows, value, references).mean(axis=0), index=references)


def paired_t(
    rows: pd.DataFrame, model: str, other: str, family: str | None = None, value: str = "rmse_mm", level: float = LEVEL
) -> Interval:
    """t-interval of mean(model) - mean(other) of ``value`` (on a reference family, or on every
    row): the seed means' differences per reference, mean +- t sd / sqrt(n) with n - 1 degrees
    of freedom. Fewer than two references give no interval (NaN bounds: it excludes nothing)."""
    if not 0 < level < 1:
        raise ValueError(f"need 0 < level < 1; got {level!r}")
    part = rows if family is None else rows[rows["family"] == family]
    a, b = (seed_means(part[part["model"] == name], value) for name in (model, other))
    if len(a) == 0 or set(a.index) != set(b.index):
        raise ValueError(f"{model} and {other} must score the same references; got {list(a.index)} and {list(b.index)}")
    differences = (a - b[a.index]).to_numpy()
    estimate = float(differences.mean())
    if len(differences) < 2:
        return Interval(estimate, np.nan, np.nan)
    if not differences.std() > 0:  # every reference the same difference: no spread to test against
        return Interval(estimate, estimate, estimate, float(estimate == 0))
    test = distributions.ttest_1samp(differences, 0.0)
    low, high = test.confidence_interval(level)
    return Interval(estimate, float(low), float(high), float(test.pvalue))


def ranking(*intervals: Interval) -> int:
    """-1 where every interval lies below zero, +1 where every one lies above, else 0: the rule
    for stating a ranking in words (an interval without bounds ranks nothing)."""
    if not intervals:
        raise ValueError("ranking needs at least one interval")
    if all(i.high < 0 for i in intervals):
        return -1
    if all(i.low > 0 for i in intervals):
        return 1
    return 0


def holm(p_values) -> np.ndarray:
    """Holm's step-down adjustment of a family's p-values (statsmodels' ``multipletests``), in the
    same order; NaN, a comparison without a t-test, stays NaN and is not counted in the family."""
    from statsmodels.stats.multitest import multipletests  # half a second to import: only verdict tables need it

    p = np.asarray(p_values, float)
    if p.ndim != 1 or np.any((p < 0) | (p > 1)):
        raise ValueError(f"p_values must be a 1-D array of probabilities (NaN allowed); got {p_values!r}")
    tested = np.isfinite(p)
    adjusted = np.full(p.shape, np.nan)
    if tested.any():
        adjusted[tested] = multipletests(p[tested], method="holm")[1]
    return adjusted


# One comparison of a verdict table, every study's: the reference family, the two sides (the
# difference is a - b), the difference's bootstrap interval and paired t-interval with the t-test's
# two-sided p, then the judgement over the table (``judged``): the Holm-adjusted p, the side both
# intervals put lower (NaN: neither) and whether that ranking is kept after Holm. Words are made
# from these columns when a page renders them (``report.sections.verdict``), never stored.
COMPARED = ("family", "a", "b", "estimate", "low", "high", "t_low", "t_high", "p")
JUDGEMENT = ("holm_p", "lower", "kept_after_holm")
COMPARISON = (*COMPARED, *JUDGEMENT)


def compared(rows: pd.DataFrame, a, b, family: str, value: str = "rmse_mm") -> dict:
    """mean(a) - mean(b) of ``value`` on a reference family as ``COMPARED``'s columns: the two-way
    bootstrap interval (``difference``) and the paired t-interval over references (``paired_t``)."""
    interval, t = difference(rows, a, b, family, value), paired_t(rows, a, b, family, value)
    return dict(
        family=family,
        a=a,
        b=b,
        estimate=interval.estimate,
        low=interval.low,
        high=interval.high,
        t_low=t.low,
        t_high=t.high,
        p=t.p,
    )


def interval_side(row) -> int:
    """``ranking`` of a comparison's (a row with ``COMPARED``'s columns) two intervals: -1 where
    both put a lower, +1 where both put b lower, else 0."""
    return ranking(Interval(np.nan, row.low, row.high), Interval(np.nan, row.t_low, row.t_high))


def lower_side(row) -> int:
    """A judged comparison's (``judged``) ranking as a side: -1 where a is lower, +1 where b, else 0."""
    return -1 if row.lower == row.a else 1 if row.lower == row.b else 0


def judged(comparisons, keys=(), in_family=None, level: float = LEVEL) -> pd.DataFrame:
    """A study's comparisons (dicts or a frame with ``keys`` and ``COMPARED``'s columns) as one
    verdict table: ``keys`` then ``COMPARISON``'s columns. The comparisons ``in_family`` (a boolean
    per row; all by default) form one Holm family over their t-tests' p (``holm``); each of them
    is ranked where both intervals exclude zero (``ranking``): ``lower`` names that side, and
    ``kept_after_holm`` says whether its Holm-adjusted p is below 1 - ``level``. A comparison out
    of the family gets neither."""
    table = pd.DataFrame(comparisons, columns=[*keys, *COMPARED]).reset_index(drop=True)
    member = np.ones(len(table), bool) if in_family is None else np.asarray(in_family, bool)
    if member.shape != (len(table),):
        raise ValueError(f"in_family must be one boolean per comparison ({len(table)}); got shape {member.shape}")
    table["holm_p"] = np.nan
    if member.any():
        table.loc[member, "holm_p"] = holm(table.loc[member, "p"].to_numpy(float))
    sides = [interval_side(row) if inside else 0 for inside, row in zip(member, table.itertuples())]
    table["lower"] = [
        row.a if side < 0 else row.b if side > 0 else None for side, row in zip(sides, table.itertuples())
    ]
    table["kept_after_holm"] = [bool(side) and p < 1 - level for side, p in zip(sides, table.holm_p)]
    return table


def best_against_best(
    rows: pd.DataFrame, groups, families=("shape", "random"), value: str = "rmse_mm", by: str | None = None, **keys
) -> list[dict]:
    """Per reference family: the best of the first group minus the best of the second (best: the
    lowest mean of ``by``, by default ``value``, on that family among the models the rows hold),
    ``compared`` on ``value``, with ``keys`` before it; a family where either group has no model
    in the rows is left out. (Picking the best of each group from the same rows biases the
    difference towards 0.)"""
    out = []
    for family in families:
        part = rows[rows["family"] == family]
        means = part.groupby("model", sort=False)[by or value].mean()
        best = [means.reindex(list(group)).dropna() for group in groups]
        if any(side.empty for side in best):
            continue
        out.append(dict(keys, **compared(part, best[0].idxmin(), best[1].idxmin(), family, value)))
    return out
