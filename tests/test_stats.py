"""Bootstrap intervals on hand-worked grids: a constant has no width, the width of a mean
of normal draws is 1.96 sigma / sqrt(n), seeds are resampled, and pairing over references
removes what both models share."""

import numpy as np
import pandas as pd
import pytest

from softflow.studies import stats


def test_a_constant_has_a_zero_width_interval():
    interval = stats.bootstrap(np.full((3, 10), 2.5))
    assert (interval.estimate, interval.low, interval.high) == (2.5, 2.5, 2.5)
    assert interval.excludes_zero


def test_one_seed_gives_the_normal_interval_of_a_mean():
    values = np.random.default_rng(1).normal(0.0, 1.0, (1, 400))
    interval = stats.bootstrap(values)
    half_width = (interval.high - interval.low) / 2
    assert half_width == pytest.approx(1.96 / np.sqrt(400), rel=0.1)
    assert interval.low < values.mean() < interval.high


def test_seeds_are_resampled():
    """Three seeds at -1, 0, 1 and no reference variation: three draws of the same seed have
    probability 1/27 = 3.7 % > 2.5 %, so the interval of the mean spans all of [-1, 1]."""
    interval = stats.bootstrap(np.repeat([[-1.0], [0.0], [1.0]], 8, axis=1))
    assert (interval.estimate, interval.low, interval.high) == (0, -1, 1)
    assert not interval.excludes_zero


def test_a_difference_is_paired_over_references():
    shared = np.random.default_rng(2).normal(0.0, 5.0, (1, 30))  # large, shared by both models
    a, b = np.repeat(shared + 1.0, 2, axis=0), np.repeat(shared, 3, axis=0)
    difference = stats.bootstrap(a, b)
    assert (difference.low, difference.high) == pytest.approx((1.0, 1.0))
    assert stats.bootstrap(a).high - stats.bootstrap(a).low > 2  # unpaired, the references' spread shows


def test_rows_become_grids_summaries_and_differences():
    rows = pd.DataFrame(
        [
            dict(model=m, seed=s, reference=f"R{r}", family="random", rmse_mm=v + r + 0.1 * s)
            for m, v in (("mlp", 1.0), ("rf", 3.0))
            for s in range(2)
            for r in range(4)
        ]
    )
    grid = stats.seed_reference_grid(rows[rows.model == "mlp"], "rmse_mm")
    np.testing.assert_allclose(grid, [[1, 2, 3, 4], [1.1, 2.1, 3.1, 4.1]])
    table = stats.summarise(rows)
    assert table[["model", "seeds", "references"]].values.tolist() == [["mlp", 2, 4], ["rf", 2, 4]]
    assert table["mean"].tolist() == pytest.approx([2.55, 4.55])
    difference = stats.difference(rows, "rf", "mlp", "random")
    assert difference.estimate == pytest.approx(2.0) and difference.low > 1.8 and difference.high < 2.2


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="finite"):
        stats.bootstrap([[1.0, np.nan]])
    with pytest.raises(ValueError, match="same references"):
        stats.bootstrap(np.ones((2, 3)), np.ones((2, 4)))
    with pytest.raises(ValueError, match="level"):
        stats.bootstrap(np.ones((2, 3)), level=95)
    rows = pd.DataFrame([dict(seed=0, reference="R1", rmse_mm=1.0), dict(seed=1, reference="R2", rmse_mm=1.0)])
    with pytest.raises(ValueError, match="every seed"):
        stats.seed_reference_grid(rows, "rmse_mm")


def t_rows():
    """Model a: two seeds, seed means 3, 5, 8 on R1-R3; model b: one seed, 2, 3, 5, its rows in
    another order. Paired differences 1, 2, 3: mean 2, sd 1, n = 3."""
    a = [(0, "R1", 2.0), (0, "R2", 5.0), (0, "R3", 7.0), (1, "R1", 4.0), (1, "R2", 5.0), (1, "R3", 9.0)]
    b = [(0, "R3", 5.0), (0, "R1", 2.0), (0, "R2", 3.0)]
    return pd.DataFrame(
        [
            dict(model=m, seed=s, reference=r, family="random", rmse_mm=v)
            for m, cells in (("a", a), ("b", b))
            for s, r, v in cells
        ]
    )


def test_paired_t_interval_by_hand():
    """t(0.975, 2 dof) = 4.302653 and t(0.75, 2 dof) = 0.816497 (t tables): 2 -+ t / sqrt(3)."""
    interval = stats.paired_t(t_rows(), "a", "b", "random")
    assert interval.estimate == pytest.approx(2.0)
    assert (interval.low, interval.high) == pytest.approx((2 - 4.302653 / np.sqrt(3), 2 + 4.302653 / np.sqrt(3)))
    assert not interval.excludes_zero  # -0.484: three references leave room for 0
    narrow = stats.paired_t(t_rows(), "a", "b", level=0.5)  # family None: every row
    assert (narrow.low, narrow.high) == pytest.approx((2 - 0.816497 / np.sqrt(3), 2 + 0.816497 / np.sqrt(3)))
    flipped = stats.paired_t(t_rows(), "b", "a", "random")
    assert (flipped.estimate, flipped.low) == pytest.approx((-2.0, -interval.high))
    assert (
        stats.difference(t_rows(), "a", "b", "random").low > 0
    )  # the bootstrap ranks it (paired by name, not row order)


def test_paired_t_needs_two_shared_references():
    one = t_rows()[t_rows().reference == "R1"]
    interval = stats.paired_t(one, "a", "b")
    assert interval.estimate == pytest.approx(1.0) and np.isnan(interval.low) and not interval.excludes_zero
    with pytest.raises(ValueError, match="same references"):
        stats.paired_t(t_rows().drop(index=6), "a", "b")  # b lacks R3
    with pytest.raises(ValueError, match="the rows score"):
        stats.difference(t_rows().drop(index=6), "a", "b", "random")
    with pytest.raises(ValueError, match="level"):
        stats.paired_t(t_rows(), "a", "b", level=95)


def test_a_ranking_needs_every_interval_on_one_side_of_zero():
    below, above, across = stats.Interval(-1, -2, -0.5), stats.Interval(1, 0.5, 2), stats.Interval(-1, -3, 1)
    assert stats.ranking(below) == -1 and stats.ranking(above, above) == 1
    assert stats.ranking(below, across) == 0 and stats.ranking(below, above) == 0
    assert stats.ranking(below, stats.Interval(-1, np.nan, np.nan)) == 0  # no t-interval: no ranking
    with pytest.raises(ValueError, match="at least one"):
        stats.ranking()


def test_paired_t_p_value_by_hand():
    """Differences 1, 2, 3: t = 2 / (1 / sqrt 3) = sqrt 12 on 2 dof, whose two-sided p-value is
    1 - t / sqrt(t^2 + 2) = 1 - sqrt(6 / 7) (the t distribution with 2 dof in closed form)."""
    assert stats.paired_t(t_rows(), "a", "b", "random").p == pytest.approx(1 - np.sqrt(6 / 7))
    assert np.isnan(stats.paired_t(t_rows()[t_rows().reference == "R1"], "a", "b").p)  # one reference: no test


def test_holm_by_hand():
    """Sorted 0.01, 0.03, 0.04 of three tests: x3, x2, x1 = 0.03, 0.06, 0.04, then non-decreasing."""
    np.testing.assert_allclose(stats.holm([0.01, 0.04, 0.03, np.nan]), [0.03, 0.06, 0.06, np.nan])
    np.testing.assert_allclose(stats.holm([0.5, 0.9]), [1.0, 1.0])  # capped at 1
    with pytest.raises(ValueError, match="probabilities"):
        stats.holm([0.2, 5.0])


def comparison(low, high, t_low, t_high, p, a="rf", b="mlp", family="shape") -> dict:
    return dict(family=family, a=a, b=b, estimate=(low + high) / 2, low=low, high=high, t_low=t_low, t_high=t_high, p=p)


def test_a_family_of_verdicts_is_adjusted_together():
    """Two comparisons, each ranked by both intervals at 95 %, with t-test p-values 0.03 and
    0.04: alone each holds; as one family Holm makes them 0.06 and 0.06, so neither is kept."""
    both = [comparison(-2.0, -1.0, -2.0, -0.1, 0.03), comparison(-2.0, -1.0, -2.0, -0.1, 0.04, family="random")]
    table = stats.judged(both)
    assert list(table.columns) == list(stats.COMPARISON)
    np.testing.assert_allclose(table.holm_p, [0.06, 0.06])
    assert list(table.lower) == ["rf", "rf"] and not table.kept_after_holm.any()
    alone = stats.judged(both[:1])
    assert alone.lower.tolist() == ["rf"] and alone.kept_after_holm.tolist() == [True]


def test_a_ranking_needs_both_intervals_and_the_family():
    """The higher side is named where both intervals lie above zero; one interval across zero, or
    a comparison left out of the family, ranks nothing and is not adjusted."""
    rows = [
        comparison(1.0, 2.0, 0.5, 2.5, 0.01),  # b lower
        comparison(-2.0, -1.0, -2.5, 0.5, 0.2),  # the t-interval crosses zero
        comparison(-2.0, -1.0, -2.5, -0.5, 0.001),  # ranked, but out of the family
    ]
    table = stats.judged(rows, in_family=[True, True, False])
    assert table.lower[0] == "mlp" and table.lower[1:].isna().all()
    np.testing.assert_allclose(table.holm_p[:2], [0.02, 0.2])
    assert np.isnan(table.holm_p[2]) and table.kept_after_holm.tolist() == [True, False, False]
    with pytest.raises(ValueError, match="in_family"):
        stats.judged(rows, in_family=[True])


def test_best_against_best_picks_each_groups_lowest_mean():
    """Per family the lowest-mean model of each group, picked on ``by`` where given; a family
    where one group has no model is left out."""
    rows = pd.DataFrame(
        [
            dict(model=m, seed=0, reference=f"R{r}", family=f, rmse_mm=base + r, other=o)
            for f in ("shape", "random")
            for m, base, o in (("rf", 1.0, 9.0), ("rf-fwd", 2.0, 0.0), ("mlp", 3.0, 5.0), ("lstm", 4.0, 1.0))
            for r in range(3)
        ]
    )
    picked = stats.best_against_best(rows, (("rf", "rf-fwd"), ("mlp", "lstm")), observation="tip")
    assert [(c["observation"], c["family"], c["a"], c["b"]) for c in picked] == [
        ("tip", "shape", "rf", "mlp"),
        ("tip", "random", "rf", "mlp"),
    ]
    assert picked[0]["estimate"] == pytest.approx(-2.0)
    by_other = stats.best_against_best(rows, (("rf", "rf-fwd"), ("mlp", "lstm")), ("shape",), by="other")
    assert (by_other[0]["a"], by_other[0]["b"], by_other[0]["estimate"]) == ("rf-fwd", "lstm", pytest.approx(-2.0))
    assert stats.best_against_best(rows[rows.model != "mlp"], (("rf",), ("mlp",))) == []


def test_a_ratio_of_means_is_paired_over_references():
    shared = np.random.default_rng(4).uniform(1.0, 10.0, (1, 30))  # what both models share
    a, b = np.repeat(1.05 * shared, 2, axis=0), np.repeat(shared, 3, axis=0)
    interval = stats.ratio(a, b)
    assert (interval.estimate, interval.low, interval.high) == pytest.approx((1.05, 1.05, 1.05))
    assert stats.within(interval, (0.9, 1.1)) == "within"
    assert stats.within(stats.ratio(1.2 * a, b), (0.9, 1.1)) == "outside"
    noisy = a * np.random.default_rng(5).uniform(0.7, 1.5, a.shape)  # a model 0.7 to 1.5 times as far off
    assert stats.within(stats.ratio(noisy, b), (0.9, 1.1)) == "undecided"
    with pytest.raises(ValueError, match="same references"):
        stats.ratio(a, b[:, :5])
