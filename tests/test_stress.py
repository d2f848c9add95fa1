"""Stress-test bookkeeping against hand-worked cases: revolutions, per-revolution RMSE, break points, spread."""

import numpy as np
import pandas as pd
import pytest

from softflow.data.references import Reference
from softflow.rod.robots import DT
from softflow.studies import stress


def circle(turns=3.5, period=1.0, approach=10, radius=0.1):
    """A constant-speed circle about the origin after a straight approach from it."""
    t = np.arange(int(round(turns * period / DT)) + 1) * DT
    yz = radius * np.stack([np.cos(2 * np.pi * t / period), np.sin(2 * np.pi * t / period)], -1)
    yz = np.concatenate([np.linspace([0.0, 0.0], yz[0], approach, endpoint=False), yz])
    states = np.zeros((len(yz), 6))
    states[:, 1:3] = yz
    states[approach:, 4] = -2 * np.pi * radius / period * np.sin(2 * np.pi * t / period)
    states[approach:, 5] = 2 * np.pi * radius / period * np.cos(2 * np.pi * t / period)
    return Reference("circle", "burst", states, np.arange(len(yz)) >= approach)


def test_revolutions_count_whole_turns_from_the_start_point():
    reference = circle()
    turn = stress.revolutions(reference)
    assert (turn[:10] == -1).all()
    assert [int((turn == k).sum()) for k in range(4)] == [100, 100, 100, 51]  # 3.5 turns of 100 samples


def test_breakdown_scores_each_revolution_and_finds_the_break():
    reference = circle()
    achieved = reference.states.copy()
    turn = stress.revolutions(reference)
    achieved[turn == 1, 1] += 0.004  # 4 mm off during the second revolution only
    achieved[turn == 2, 2] += 0.010  # 10 mm off during the third
    runs = {"model": dict(states=achieved, u=np.zeros((len(achieved) - 1, 2)))}
    breakdown = stress.burst_breakdown(reference, runs, length=0.2)
    np.testing.assert_allclose(breakdown.rmse_yz_mm, [0.0, 4.0, 10.0], atol=1e-9)  # the unfinished turn is left out
    np.testing.assert_allclose(breakdown.period_s, 1.0)
    np.testing.assert_allclose(breakdown.reference_speed, 2 * np.pi * 0.1, rtol=1e-9)
    first = stress.break_points(breakdown, fraction=0.03).loc["model"]  # 6 mm on a 0.2 m rod
    assert first.breaks_at_revolution == 2 and first.period_s == pytest.approx(1.0)
    assert np.isnan(stress.break_points(breakdown, fraction=0.2).loc["model"].period_s)
    other = breakdown.assign(model="other", rmse_yz_mm=[1.0, 1.0, 1.0])
    table = stress.per_revolution(pd.concat([breakdown, other]), ["model", "other"])
    assert table["lower"].tolist() == ["model", "other", "other"]


def test_burst_summary_reports_speed_rmse_and_saturation():
    reference = circle()
    achieved = reference.states.copy()
    achieved[:, 2] += 0.003
    u = np.zeros((len(achieved) - 1, 2))
    u[:10, 0] = 4.0  # 10 of 2 x 360 samples at the limit
    summary = stress.burst_summary(reference, {"m": dict(states=achieved, u=u)}, length=0.3, u_limit=4.0).loc["m"]
    assert summary.rmse_yz_mm == pytest.approx(3.0)
    assert summary.rmse_pct_L == pytest.approx(1.0)
    assert summary.peak_speed == pytest.approx(2 * np.pi * 0.1)
    assert summary.saturated == pytest.approx(10 / u.size)


def test_spread_and_its_correlation_with_error():
    samples = np.array([[[1.0, 0.0]], [[3.0, 0.0]]])  # two draws of one step: std 1 N on u_1
    np.testing.assert_allclose(stress.actuation_spread(samples), [1.0])
    names = ["a", "b", "c", "d"]
    correlation = stress.spread_vs_error(
        pd.Series([0.1, 0.2, 0.3, 0.4], names), pd.Series([1.0, 4.0, 9.0, 16.0], names)
    )
    assert correlation["n"] == 4 and correlation["spearman"] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="shape"):
        stress.actuation_spread(samples[:1])
    with pytest.raises(ValueError, match="at least 3"):
        stress.spread_vs_error(pd.Series([0.1], ["a"]), pd.Series([1.0], ["a"]))
