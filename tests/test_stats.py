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
