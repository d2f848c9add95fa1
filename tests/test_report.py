"""Tables from result CSVs: the paper's numbers beside ours, Markdown, and clear errors."""

import pandas as pd
import pytest

from softflow import profiles, report
from softflow.studies.study import FLOOR


@pytest.fixture
def profile(tmp_path, monkeypatch):
    monkeypatch.setattr(profiles, "REPO", tmp_path)
    p = profiles.Profile("report-test", n_episodes=1)
    p.output_dir.mkdir(parents=True)
    return p


def write_results(profile):
    rows = []
    for k, model in enumerate(report.MODELS):
        rows += [
            dict(model=model, reference="circle", family="shape", rmse_mm=1.0 + k, phase_lag_s=0.01, input_energy=5.0),
            dict(model=model, reference="heart", family="shape", rmse_mm=3.0 + k, phase_lag_s=0.03, input_energy=5.0),
            dict(model=model, reference="Rand1", family="random", rmse_mm=10.0 + k, phase_lag_s=0.0, input_energy=18.0),
        ]
    frame = pd.DataFrame(rows)
    frame[frame.model.isin(["mlp", "lstm", "transformer"])].to_csv(
        profile.output_dir / "results_baselines.csv", index=False
    )
    frame[~frame.model.isin(["mlp", "lstm", "transformer"])].to_csv(profile.output_dir / "results_rf.csv", index=False)


def test_table1_averages_per_family_beside_the_paper(profile):
    write_results(profile)
    table = report.table1(profile)
    assert table.loc["mlp", ("shape_mm", "ours")] == pytest.approx(2.0)  # mean of 1 and 3
    assert table.loc["rf-fwd", ("random_mm", "ours")] == pytest.approx(15.0)
    assert table.loc["rf-fwd", ("random_mm", "paper")] == pytest.approx(3.5)
    text = report.markdown(table, 1)
    assert text.splitlines()[0] == "| model | shape_mm ours | shape_mm paper | random_mm ours | random_mm paper |"
    assert "| RF-FWD | 7.0 | 5.0 | 15.0 | 3.5 |" in text


def test_table2_marks_models_the_paper_does_not_report(profile):
    write_results(profile)
    table = report.table2(profile)
    assert table.loc["mlp", ("phase_lag_s", "ours")] == pytest.approx(0.02)
    assert "| RF | 0.020 | -- | 18.000 | -- |" in report.markdown(table, 3)


def test_a_missing_result_names_the_notebook_that_writes_it(profile):
    with pytest.raises(ValueError, match="03_baselines.ipynb"):
        report.table1(profile)
    write_results(profile)
    with pytest.raises(ValueError, match="06_hardware_replay.ipynb"):
        report.table3(profile)


def test_the_report_does_not_import_torch():
    """Tables and the results page need pandas, not the models: a light import."""
    import subprocess
    import sys

    code = "import sys, softflow.report; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def study_rows():
    """Three seeds on two references per family; RF-FWD exactly 1 mm below the MLP everywhere."""
    base = dict(mlp=5.0, lstm=6.0, transformer=7.0, rf=5.5, **{"rf-physical": 6.5, "rf-fwd": 4.0})
    rows = [
        dict(model=model, seed=seed, reference=f"{family}{r}", family=family, rmse_mm=value + r + 0.1 * seed)
        for model, value in base.items()
        for seed in range(3)
        for family in ("shape", "random")
        for r in range(2)
    ]
    rows += [
        dict(model=FLOOR, seed=0, reference=f"{family}{r}", family=family, rmse_mm=0.1)
        for family in ("shape", "random")
        for r in range(2)
    ]
    return pd.DataFrame(rows)


def test_study_tables_carry_intervals_the_floor_and_a_verdict():
    rows = study_rows()
    table = report.table1_ci(rows)
    assert list(table.index) == [*report.MODELS, FLOOR]
    assert table.loc["mlp", "shape_mm"].startswith("5.60 [") and table.loc[FLOOR, "random_mm"].startswith("0.10")
    assert table.loc["mlp", "shape_seeds x refs"] == "3 x 2" and table.loc[FLOOR, "shape_seeds x refs"] == "1 x 2"
    verdict = report.best_against_best(rows)
    assert verdict.loc["shape", ["best_rf", "best_baseline"]].tolist() == ["rf-fwd", "mlp"]
    assert verdict.loc["shape", "difference_mm"] == pytest.approx(-1.0)
    assert verdict.loc["shape", "high"] < 0 and verdict.loc["shape", "verdict"] == "RF-FWD lower"
    conditions = rows.assign(condition="table1", coverage=1.0)
    grid = report.protocol_table(conditions)
    assert list(grid.columns) == [*report.MODELS, FLOOR, "coverage"]
    assert grid.loc["table1", "lstm"] == pytest.approx(6.6)


def test_regime_map_pairs_each_flow_with_the_mlp_per_variant():
    rows = []
    for variant, gain in (("paper", 0.0), ("folded", -2.0)):
        for model in ("mlp", "rf"):
            for seed in (0, 1, 2):
                for k, (reference, family) in enumerate((("circle", "shape"), ("star", "shape"), ("Rand1", "random"))):
                    rmse = 5.0 + k + 0.1 * seed + (gain if model == "rf" else 0.0)
                    rows.append(
                        dict(
                            variant=variant,
                            model=model,
                            seed=seed,
                            plan="zero",
                            reference=reference,
                            family=family,
                            rmse_mm=rmse,
                            u_rmse_test=0.1 + 0.01 * seed,
                            conditional_spread=0.3,
                            conditional_spread_floor=0.1,
                        )
                    )
    table = report.regime_map(pd.DataFrame(rows))
    assert table.loc[("folded", "rf"), "shape_mm"] == pytest.approx(-2.0)
    assert table.loc[("folded", "rf"), "shape_verdict"] == "RF lower"
    assert table.loc[("paper", "rf"), "random_mm"] == pytest.approx(0.0, abs=1e-12)
    assert table.loc[("paper", "rf"), "random_verdict"] == "no ranking"
    assert table.loc[("paper", "rf"), "step_N"] == pytest.approx(0.0, abs=1e-12)


def test_closed_loop_section_counts_references_worse_than_open_loop(profile):
    out = profile.output_dir
    pd.DataFrame(
        {
            "gravity": ["vertical"] * 3,
            "reference": ["star", "circle", "mean"],
            "open": [5.0, 3.0, 4.0],
            "closed": [6.0, 2.0, 4.0],
            "closed-ilc": [1.0, 1.0, 1.0],
        }
    ).to_csv(out / "10_table3_extended.csv", index=False)
    pd.DataFrame({"latency": [0.0], "dropped": [0.0], "vertical": [4.0]}).to_csv(out / "10_latency.csv", index=False)
    pd.DataFrame([["gravity", "vertical"], ["mode", "open"], ["gap", None], ["typical", 4.0]]).to_csv(
        out / "10_gap_sensitivity.csv", index=False, header=False
    )
    pd.DataFrame({"model": ["open, vertical"], "breaks_at_revolution": [3]}).to_csv(
        out / "10_burst_breaks.csv", index=False
    )
    pd.DataFrame({"truth": [0.1]}, index=["density"]).to_csv(out / "10_identified.csv")
    text = "\n".join(report.closed_loop_section(profile))
    assert "| vertical | 1 | 0 |" in text  # closed worse on the star only, learning never
    assert "| typical | 4.00 |" in text


def test_size_effects_separate_the_prior_from_being_generative():
    offsets = {"mlp": 0.0, "mlp-physical": -1.0, "rf": -0.5, "rf-physical": -1.5}  # prior -1, generative -0.5
    rows = pd.DataFrame(
        [
            dict(
                episodes=episodes,
                model=model,
                seed=seed,
                reference=f"{family}{r}",
                family=family,
                rmse_mm=5.0 + r + 0.1 * seed + offset,
            )
            for episodes in (100, 300)
            for model, offset in offsets.items()
            for seed in range(3)
            for family in ("shape", "random")
            for r in range(3)
        ]
    )
    table = report.size_effects(rows)
    assert table.loc[(100, "prior, flow", "shape"), "difference_mm"] == pytest.approx(-1.0)
    assert table.loc[(300, "generative, with prior", "random"), "difference_mm"] == pytest.approx(-0.5)
    assert table.loc[(300, "generative, with prior", "random"), "verdict"] == "RF-Physical lower"
    assert table.loc[(100, "prior, regression", "shape"), "verdict"] == "MLP-Physical lower"


def test_lambda_decision_changes_the_default_only_when_better_on_both_families():
    def rows(offsets):
        return pd.DataFrame(
            [
                dict(
                    consistency=weight,
                    model="rf-fwd",
                    seed=seed,
                    reference=f"{family}{r}",
                    family=family,
                    rmse_mm=5.0 + r + 0.1 * seed + offsets[weight].get(family, 0.0),
                )
                for weight in offsets
                for seed in range(3)
                for family in ("shape", "random")
                for r in range(3)
            ]
        )

    table, chosen = report.lambda_decision(
        rows(
            {0.0: {"shape": -1.0}, 0.1: {"shape": -1.0, "random": -0.5}, 0.3: {"shape": -1.0, "random": -0.8}, 1.0: {}}
        )
    )
    assert chosen == 0.3 and table.loc[0.1, "better_on_both"] and not table.loc[0.0, "better_on_both"]
    assert table["chosen"].tolist() == [False, False, True]
    assert table.loc[0.0, "random_mm"] == pytest.approx(0.0, abs=1e-12)
    _, chosen = report.lambda_decision(rows({0.0: {"shape": -1.0, "random": 0.5}, 1.0: {}}))
    assert chosen == 1.0


def test_where_flows_win_section_states_each_interval_that_excludes_zero(profile):
    out = profile.output_dir
    pd.DataFrame(
        [
            dict(
                variant="paper",
                flow="rf",
                conditional_spread=0.1,
                spread_floor=0.1,
                shape_mm=0.1,
                shape_low=-0.2,
                shape_high=0.4,
                random_mm=0.5,
                random_low=0.2,
                random_high=0.8,
                step_N=0.0,
                step_low=-0.001,
                step_high=0.001,
            ),
            dict(
                variant="folded",
                flow="rf",
                conditional_spread=0.5,
                spread_floor=0.1,
                shape_mm=-2.0,
                shape_low=-3.0,
                shape_high=-1.0,
                random_mm=-0.1,
                random_low=-0.5,
                random_high=0.3,
                step_N=-0.01,
                step_low=-0.02,
                step_high=0.0,
            ),
        ]
    ).to_csv(out / "09_regime_map.csv", index=False)
    pd.DataFrame(
        [
            dict(
                episodes=100,
                effect="prior, flow",
                family=family,
                difference_mm=-1.0,
                low=-1.5,
                high=-0.5,
                verdict="RF-Physical lower",
            )
            for family in ("shape", "random")
        ]
    ).to_csv(out / "09_data_size_effects.csv", index=False)
    text = "\n".join(report.where_flows_win_section(profile))
    assert "Of 4 comparisons" in text and "the flow is lower in 1, the MLP in 1, and 2 have no ranking" in text
    assert (
        "paper: the MLP lower in 1 (on the random references, by 0.50 mm), 1 without ranking; "
        "folded: the flow lower in 1 (on the shapes, by 2.00 mm)"
    ) in text
    assert "| 100 | prior, flow | -1.00 [-1.50, -0.50] | -1.00 [-1.50, -0.50] |" in text
    assert "| folded | RF | 0.500 / 0.100 | -2.00 [-3.00, -1.00] |" in text


def diagnostics(weights):
    """notebook 11's per-lambda diagnostics, made up: u error 0.01 lambda, one-step estimates
    0.5 N worse than Euler, residuals twice the floor of 0.04."""
    return pd.DataFrame(
        [
            dict(
                consistency=weight,
                u_rmse_test=0.01 * weight,
                forward_step_mm=0.2,
                residual_floor=0.04,
                **{
                    f"{kind}_u_error_tau{tau:g}": 0.1 * tau + (0.5 if kind == "one_step" else 0.0)
                    for kind in ("one_step", "euler")
                    for tau in (0.05, 0.5)
                },
                **{f"one_step_residual_tau{tau:g}": 0.08 for tau in (0.05, 0.5)},
            )
            for weight in weights
        ]
    ).set_index("consistency")


def test_consistency_term_summary_says_what_the_term_sees(profile):
    text = report.consistency_term_summary(diagnostics(weights=(0.0, 0.1, 1.0)))
    assert "is 0.0000 N without the term (RF) and 0.0010 / 0.0100 N at lambda = 0.1 / 1." in text
    assert "a residual of 0.0400" in text and "its one-step tip error is 0.200 mm" in text
    assert "residual at tau = 0.5 is 2.00 times that without the term and 2.00 times at lambda = 1. At tau" in text
    assert "At tau = 0.05 the one-step estimate misses u by 0.5050 N, 101.0 times a short Euler rollout" in text
    suited = diagnostics(weights=(0.0, 0.3)).assign(**{"one_step_residual_tau0.5": [0.05, 0.03]})
    assert (
        "is 1.25 times that without the term and 0.75 times at lambda = 0.3 (below 1: the flow's estimate suits "
        "the surrogate's own error better than the true u does)"
    ) in report.consistency_term_summary(suited)


def test_consistency_weight_section_states_the_rules_choice(profile):
    decision = pd.DataFrame(
        [
            dict(
                consistency=weight,
                shape_mm=-0.2,
                shape_low=-0.3,
                shape_high=-0.1,
                random_mm=random,
                random_low=random - 0.1,
                random_high=random + 0.1,
                better_on_both=random < -0.1,
                chosen=chosen,
            )
            for weight, random, chosen in ((0.1, 0.1, False), (0.3, -0.4, True))
        ]
    )
    decision.to_csv(profile.output_dir / "11_fwd_lambda_decision.csv", index=False)
    diagnostics(weights=(0.0, 0.1, 0.3, 1.0)).to_csv(profile.output_dir / "11_fwd_lambda_diagnostics.csv")
    text = "\n".join(report.consistency_weight_section(profile))
    assert "| 0.3 | 0.0030 | 0.2000 | 0.505 / 0.005 | 0.550 / 0.050 |" in text
    assert "lambda = 0.3 is better on both families, so the default changes to it" in text
    assert "| 0.1 | -0.20 [-0.30, -0.10] | +0.10 [+0.00, +0.20] |" in text
    decision.assign(chosen=False).to_csv(profile.output_dir / "11_fwd_lambda_decision.csv", index=False)
    assert "so the default stays" in "\n".join(report.consistency_weight_section(profile))


def test_regime_summary_gives_the_range_of_each_sides_wins_per_variant():
    def row(flow, shape, random):  # intervals of half-width 0.5 around each difference
        return dict(
            variant="folded",
            flow=flow,
            **{
                f"{family}_{k}": value + offset
                for family, value in (("shape", shape), ("random", random))
                for k, offset in (("mm", 0.0), ("low", -0.5), ("high", 0.5))
            },
        )

    regimes = pd.DataFrame([row("rf", -60.0, -3.0), row("rf-fwd", -65.0, 2.0)]).set_index(["variant", "flow"])
    text = report.regime_summary(regimes)
    assert "the flow is lower in 3, the MLP in 1, and 0 have no ranking" in text
    assert "folded: the flow lower in 3 (on both families, by 3.00-65.00 mm), the MLP lower in 1 (on the random" in text
