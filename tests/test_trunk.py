"""The trunk study's parts that decide its verdicts: the naive planners, the judge's windows and
the rule, on hand-made inputs whose answers are worked out by hand; and its shipped ci rows."""

import numpy as np
import pandas as pd
import pytest

from softflow.studies import STUDIES, stats, sweep, trunk


def test_naive_planners():
    u = np.arange(12.0).reshape(4, 3)
    np.testing.assert_array_equal(trunk.naive_plan("recorded", u, None), u)
    np.testing.assert_array_equal(trunk.naive_plan("persistence", u, None), u[[0, 0, 1, 2]])
    np.testing.assert_array_equal(trunk.naive_plan("training-mean", u, np.ones(3)), np.ones((4, 3)))
    with pytest.raises(ValueError, match="naive planner must be one of"):
        trunk.naive_plan("oracle", u, None)


class AddToTip:
    """A judge whose tip (state 6:9, m) moves by the first three inputs (mm) each step."""

    def predict_next(self, x, u):  # torch (W, 18), (W, 6)
        x = x.clone()
        x[:, 6:9] += 1e-3 * u[:, :3]
        return x


def test_the_judge_scores_each_window_from_its_recorded_start():
    T, length = 1500, 50  # 15 s at 100 Hz: windows start at 0, 5 and 10 s
    plan = np.zeros((T, 6))
    plan[:, :3] = np.random.default_rng(0).normal(size=(T, 3))
    states = np.zeros((T + 1, 18))
    states[1:, 6:9] = 1e-3 * np.cumsum(plan[:, :3], 0)  # what the recorded inputs did
    errors = trunk.judged_errors(AddToTip(), states, plan, length, delay=0)
    np.testing.assert_allclose(errors, 0.0, atol=1e-4)  # the recorded inputs reach the recorded tip
    offset = plan.copy()
    offset[:, :3] += 0.5  # 0.5 mm more on each of three axes every step: k steps off by 0.5 k sqrt(3) mm
    k = np.arange(1, length + 1)
    expected = 0.5 * np.sqrt(3) * np.sqrt(np.mean(k**2))
    np.testing.assert_allclose(trunk.judged_errors(AddToTip(), states, offset, length, 0), expected, rtol=1e-4)
    assert len(errors) == 3


def rows_of(model, observation, family, values, seeds=(0,)):
    return [
        dict(model=model, observation=observation, family=family, seed=s, reference=f"w{i}", tip_mm=v + 0.01 * s)
        for s in seeds
        for i, v in enumerate(values)
    ]


def made_rows(naive_gap: float) -> pd.DataFrame:
    """Eight windows; the training mean ``naive_gap`` mm above the recorded inputs, persistence on
    them; with the tip alone RF 1 mm below the MLP, with all disks the two within noise."""
    noise = np.random.default_rng(1).normal(0, 0.3, 8)
    base = 5 + noise
    rows = rows_of("recorded", "disks", "f", base)
    rows += rows_of("training-mean", "disks", "f", base + naive_gap + 0.1 * noise)
    rows += rows_of("persistence", "disks", "f", base - 0.01 * noise)
    rows += rows_of("mlp", "tip", "f", base + 3, seeds=(0, 1))
    rows += rows_of("rf", "tip", "f", base + 2 + 0.05 * noise, seeds=(0, 1))
    rows += rows_of("mlp", "disks", "f", base + 2, seeds=(0, 1))
    rows += rows_of("rf", "disks", "f", base + 2 + np.random.default_rng(2).normal(0, 0.3, 8), seeds=(0, 1))
    return pd.DataFrame(rows)


def test_the_rule_ranks_where_both_intervals_agree_and_the_judge_tells_naive_from_recorded():
    rule = trunk.flow_rule(made_rows(naive_gap=4.0)).set_index("observation")
    assert rule.loc["tip", "lower"] == "rf" and rule.loc["tip", "estimate"] == pytest.approx(-1, abs=0.05)
    assert pd.isna(rule.loc["disks", "lower"]) and rule.judge_passes.all()
    check = trunk.judge_check(made_rows(naive_gap=4.0)).set_index("a")
    assert check.tells_apart["training-mean"] and not check.tells_apart["persistence"]  # persistence gates nothing


def test_the_answer_to_notebook_12_reads_the_rule_registered_before_any_row_not_the_later_holm_family():
    assert trunk.notebook_12_answer(trunk.flow_rule(made_rows(naive_gap=4.0))) == "confirms"  # rf lower at the tip
    assert trunk.notebook_12_answer(trunk.flow_rule(made_rows(naive_gap=0.0))) == "neither"  # the judge ranks nothing

    def rule(tip, disks):  # (bootstrap high, t high, holm p) of the best flow's difference per observation
        made = [
            dict(family="f", a="rf", b="mlp", estimate=-0.5, low=-1.0, high=high, t_low=-1.0, t_high=t_high, p=p)
            for high, t_high, p in (tip, disks)
        ]
        return stats.judged(made, in_family=[np.isfinite(p) for *_, p in (tip, disks)]).assign(
            observation=["tip", "disks"]
        )

    lower, not_after_holm, t_straddles = (-0.3, -0.7, 0.01), (-0.3, -0.7, 0.0517), (-0.3, 0.05, 0.1)
    unjudged = (-0.3, -0.7, np.nan)  # a family the judge does not pass: never ranked
    assert trunk.notebook_12_answer(rule(not_after_holm, lower)) == "both"  # the post-hoc family decides nothing
    assert trunk.notebook_12_answer(rule(t_straddles, lower)) == "reverses"
    assert trunk.notebook_12_answer(rule(lower, t_straddles)) == "confirms"
    assert trunk.notebook_12_answer(rule(unjudged, unjudged)) == "neither"


def test_a_judge_that_cannot_tell_the_training_mean_from_its_floor_ranks_nothing():
    rule = trunk.flow_rule(made_rows(naive_gap=0.0)).set_index("observation")
    assert pd.isna(rule.loc["tip", "lower"]) and not rule.judge_passes.any()
    assert not trunk.judge_check(made_rows(naive_gap=0.0)).tells_apart.any()


def test_the_shipped_ci_rows_are_the_grid_and_the_recorded_inputs_are_the_judges_floor():
    rows = sweep.shipped_rows("trunk", "ci")
    cells = STUDIES["trunk"].cells("ci")
    assert rows.key.nunique() == len(cells)
    recorded = rows[rows.model == "recorded"]
    assert (recorded.u_rmse_deg == 0).all()
    judged = trunk.judged_table(rows).set_index(["model", "family"])["mean"]
    for family in dict.fromkeys(rows.family):
        assert judged[("recorded", family)] <= judged[("training-mean", family)]
    assert set(trunk.spread(rows).index) == {"tip", "disks"}


def test_the_trunk_section_answers_by_its_registered_rule_and_says_it_is_withdrawn(tmp_path, monkeypatch):
    from small_runs import report_profile, write_sweep

    from softflow.report import sections

    profile = report_profile(tmp_path, monkeypatch)
    rows = made_rows(naive_gap=4.0).assign(key=lambda r: r.model + r.observation + r.seed.astype(str), run="random_2")
    rows = rows.assign(conditional_spread=2.0, conditional_spread_floor=1.0)
    write_sweep(profile, "trunk", rows)
    section = sections.trunk_section(profile)
    answer = sections.words(section, "answer")  # RF lower from the tip alone only: the registered "confirms"
    assert answer.startswith(f"Withdrawn: by its registered rule {trunk.ANSWERS['confirms']}, but its judge")
    assert "| tip f | rf | mlp |" in sections.table_text(section) and "RF lower" in sections.table_text(section)
    write_sweep(profile, "trunk", rows.iloc[:0])
    assert sections.words(sections.trunk_section(profile), "answer") == "0 cells have rows: no answer yet."
