"""The trunk asked again (softflow.studies.trunk_v2): its judge-free scores on closed forms, the
registered rule on hand-made comparisons, and the shipped rows' referee: no judge scores a run it
was fitted on, and the recorded inputs are every judge's floor."""

import numpy as np
import pandas as pd
import pytest

from softflow.studies import STUDIES, judges, stats, sweep, trunk_v2


def test_the_energy_score_of_one_draw_is_its_error_and_of_two_draws_half_their_distance():
    rng = np.random.default_rng(0)
    u = rng.normal(size=(5, 6))
    plan = u + np.array([3.0, 4.0, 0, 0, 0, 0])  # 5 degrees off at every step
    np.testing.assert_allclose(trunk_v2.energy_score(plan[None], u), 5.0)
    a = rng.normal(size=(5, 6))
    both = np.stack([u + a, u - a])  # two draws either side: E|X - u| = |a|, E|X - X'| = |a|
    np.testing.assert_allclose(trunk_v2.energy_score(both, u), np.linalg.norm(a, axis=-1) / 2)


def test_the_energy_score_prefers_the_law_that_made_the_inputs_to_its_mean():
    """Proper: where u given the state is two-valued (+-1), draws from that law score lower than
    the conditional mean (0), which a regression model would give."""
    rng = np.random.default_rng(1)
    u = rng.choice([-1.0, 1.0], size=(4000, 1))
    law = rng.choice([-1.0, 1.0], size=(16, 4000, 1))
    assert trunk_v2.energy_score(law, u).mean() < trunk_v2.energy_score(np.zeros((1, 4000, 1)), u).mean()


def test_the_aligned_error_finds_a_plan_sent_three_periods_early():
    u = np.cumsum(np.random.default_rng(2).normal(size=(300, 6)), 0)
    plan = np.concatenate([u[3:], u[-3:]])  # plan[t] = u[t + 3]
    lag, per_input = trunk_v2.aligned_error(plan, u, 5)
    assert lag == 3 and np.allclose(per_input, 0)
    assert trunk_v2.aligned_error(plan, u, 2)[0] == 2  # beyond the range: the nearest lag it may take


def comparison(ridge=-3.0, kernel=-2.0, resolution=1.0, holm_p=0.01, width=0.5) -> pd.DataFrame:
    """One comparison of ``flow_rule``, RF against the MLP: each judge's row, its difference with
    intervals of half-width ``width`` and the p of a family of one."""
    judged = [
        stats.judged(
            [
                dict(
                    family="random_2, 0.5 s",
                    a="rf",
                    b="mlp",
                    estimate=d,
                    low=d - width,
                    high=d + width,
                    t_low=d - width,
                    t_high=d + width,
                    p=holm_p,
                )
            ],
            in_family=[np.isfinite(resolution)],
        ).assign(judge=kind)
        for kind, d in (("ridge", ridge), ("kernel", kernel))
    ]
    return pd.concat(judged).assign(resolution_mm=resolution)


@pytest.mark.parametrize(
    "changes, lower",
    [
        ({}, "rf"),
        (dict(ridge=3.0, kernel=2.0), "mlp"),
        (dict(kernel=2.0), None),  # the judges disagree in sign
        (dict(resolution=2.5), None),  # the kernel's 2 mm is within a judge's resolution
        (dict(resolution=np.nan), None),  # a judge separates no perturbation there
        (dict(holm_p=0.06), None),
        (dict(width=2.5), None),  # the kernel's intervals cross zero
    ],
)
def test_a_difference_ranks_only_where_every_judge_agrees_beyond_its_resolution(changes, lower):
    assert trunk_v2.rule_lower(comparison(**changes)) == lower


def test_a_judge_that_rates_a_known_worse_input_better_than_the_recorded_ones_judges_nothing_there():
    def perturbation(judge, family, name, difference):
        return dict(
            judge=judge,
            family=family,
            input=name,
            difference=difference,
            low=difference - 0.1,
            high=difference + 0.1,
            t_low=difference - 0.1,
            t_high=difference + 0.1,
            separated=difference > 0.1,
        )

    curve = pd.DataFrame(
        [
            perturbation(judge, "a", name, d)
            for judge in ("ridge", "kernel")
            for name, d in (("delay 1", 0.5), ("noise 1", 2.0))
        ]
        + [perturbation("ridge", "b", "delay 1", -1.0), perturbation("ridge", "b", "noise 1", 2.0)]
        + [perturbation("kernel", "b", "delay 1", 0.05), perturbation("kernel", "b", "noise 1", 0.0)]
    )
    table = trunk_v2.resolutions(curve).set_index(["judge", "family"])
    assert table.loc[("ridge", "a"), "resolution_mm"] == 0.5 and table.loc[("ridge", "a"), "trusted"]
    assert table.loc[("ridge", "b"), "reversed"] == 1 and not table.loc[("ridge", "b"), "trusted"]
    assert np.isnan(table.loc[("kernel", "b"), "resolution_mm"]) and not table.loc[("kernel", "b"), "trusted"]


def test_the_answer_reads_the_verdicts_of_each_observation():
    def rule(tip, disks):
        return pd.DataFrame(dict(observation=["tip", "disks"], a="rf", b="mlp", rule_lower=[tip, disks]))

    assert trunk_v2.notebook_12_answer(rule("rf", None)) == "confirms"
    assert trunk_v2.notebook_12_answer(rule(None, "rf")) == "reverses"
    assert trunk_v2.notebook_12_answer(rule("rf", "rf")) == "both"
    assert trunk_v2.notebook_12_answer(rule("mlp", None)) == "neither"
    assert trunk_v2.notebook_12_answer(rule(None, None)) == "not resolved"


@pytest.mark.parametrize("profile", ["ci", "paper"])
def test_no_judge_scores_a_run_it_was_fitted_on(profile):
    rows = sweep.shipped_rows("trunk_v2", profile)
    if not len(rows):
        pytest.skip(f"no {profile} rows of trunk_v2 ship")
    made = trunk_v2.provenance(rows)
    assert set(made.judge) == set(judges.KINDS) and set(made.scores) == set(trunk_v2.HELD_OUT)
    assert not (made.scores == made.fitted_on).any()
    assert set(made.fitted_on) <= set(trunk_v2.JUDGE_RUNS)


@pytest.mark.parametrize("profile", ["ci", "paper"])
def test_the_referee_rows_ship_whole_before_any_planner_row_and_the_recorded_inputs_are_the_floor(profile):
    rows = sweep.shipped_rows("trunk_v2", profile)
    if not len(rows):
        pytest.skip(f"no {profile} rows of trunk_v2 ship")
    referee = [cell["model"] for cell in STUDIES["trunk_v2"].cells(profile) if cell["model"] in trunk_v2.REFEREE]
    assert set(rows.model) >= set(referee)  # no planner row without every referee row
    recorded = rows[rows.model == "recorded"]
    assert (recorded[list(trunk_v2.JUDGE_FREE)] == 0).all().all()
    means = rows.groupby(["model", "family"])[list(trunk_v2.JUDGED)].mean()
    for family in dict.fromkeys(rows.family):
        assert (means.loc[("recorded", family)] < means.loc[("training-mean", family)]).all()
