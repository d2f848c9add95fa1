"""Tables from result CSVs: the paper's numbers beside ours, Markdown, and clear errors."""

import json
import subprocess
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from small_runs import report_profile, write_sweep

from softflow import report
from softflow.report import result_files, results_page, sections
from softflow.rod.robots import HW_ROBOT
from softflow.store import REPO
from softflow.studies.catalogue import STUDIES
from softflow.studies.study import FLOOR
from softflow.studies.table1 import TABLE1

ILC_TRIALS = 8  # the test profile's ILC budget: its last trial is trial 8


@pytest.fixture
def profile(tmp_path, monkeypatch):
    p = report_profile(tmp_path, monkeypatch)
    monkeypatch.setitem(TABLE1, p.name, replace(TABLE1["ci"], ilc_iterations=ILC_TRIALS))
    return p


def write_results(profile):
    rows = []
    for k, model in enumerate(report.TABLE1_MODELS):
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
    with pytest.raises(ValueError, match="study 'table1' .* notebooks/08_honest_table1.ipynb"):
        report.read_sweep(profile, "table1")


def test_every_committed_result_file_is_registered_and_its_notebook_writes_it():
    """The registry names every file under figures/ and no other; each entry's notebook has a
    cell that names it (a study table through write_table / write_summary, any other by its stem)."""
    assert set(result_files.RESULT_FILES) == {path.name for path in (REPO / "figures").glob("*.csv")}
    sources = {}
    for name, entry in result_files.RESULT_FILES.items():
        if entry.notebook not in sources:
            cells = json.loads((REPO / "notebooks" / entry.notebook).read_text())["cells"]
            sources[entry.notebook] = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
        code = sources[entry.notebook]
        study = getattr(entry, "studies", ("",))[0]
        named = f'"{name}"' in code or f'"{name.removesuffix(".csv")}' in code
        assert named or f'write_summary("{study}"' in code, f"{entry.notebook} does not write {name}"
    assert result_files.writer("results_baselines.csv") == "03_baselines.ipynb"
    assert result_files.writer("twin_sensitivity.csv") == "06_hardware_replay.ipynb"
    with pytest.raises(ValueError, match="'nobody_writes.csv' is not a registered result file"):
        result_files.writer("nobody_writes.csv")


@pytest.mark.parametrize("study", [s for s in STUDIES if STUDIES[s].notebook])
def test_the_notebook_a_study_names_runs_it(study):
    cells = json.loads((REPO / "notebooks" / STUDIES[study].notebook).read_text())["cells"]
    code = ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]
    assert any("run_sweep(" in cell and f'"{study}"' in cell for cell in code)


def test_every_study_names_the_commit_that_fixed_it_from_this_history():
    git = lambda *args: subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True)  # noqa: E731
    if git("rev-parse", "--is-shallow-repository").stdout.strip() != "false":
        pytest.skip("not a full git checkout: the commits cannot be looked up")
    fixed = {name: study.fixed_in for name, study in STUDIES.items() if study.fixed_in}
    assert {"table1", "ambiguity", "trunk_v2", "loop"} <= set(fixed)
    for name, commit in fixed.items():
        assert git("cat-file", "-e", f"{commit}^{{commit}}").returncode == 0, f"{name}: no commit {commit}"


def test_the_report_does_not_import_torch():
    """Tables and the results page need pandas, not the models: a light import."""
    import subprocess
    import sys

    code = "import sys, softflow.report; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def study_rows():
    """Three seeds on two references per family. Shapes: RF-FWD exactly 1 mm below the MLP on
    each. Random (every model 10 mm higher): RF-FWD 1 and 2 mm below the MLP, which the bootstrap
    ranks and the t-interval on two references does not. The floor's best ILC trial is its last
    on three of its four references."""
    base = dict(mlp=5.0, lstm=6.0, transformer=7.0, rf=5.5, **{"rf-physical": 6.5, "rf-fwd": 4.0})
    rows = [
        dict(
            model=model,
            seed=seed,
            reference=f"{family}{r}",
            family=family,
            rmse_mm=value + r + 0.1 * seed + (10.0 - (r if model == "rf-fwd" else 0.0) if family == "random" else 0.0),
        )
        for model, value in base.items()
        for seed in range(3)
        for family in ("shape", "random")
        for r in range(2)
    ]
    rows += [
        dict(model=FLOOR, seed=0, reference=f"{family}{r}", family=family, rmse_mm=0.1, ilc_best_trial=trial)
        for (family, r), trial in zip([("shape", 0), ("shape", 1), ("random", 0), ("random", 1)], (8, 8, 2, 8))
    ]
    return pd.DataFrame(rows)


def test_study_tables_carry_intervals_the_floor_and_a_verdict():
    rows = study_rows()
    table = report.table1_ci(rows)
    assert list(table.index) == [*report.TABLE1_MODELS, FLOOR]
    assert table.loc["mlp", "shape_mm"].startswith("5.60 [") and table.loc[FLOOR, "random_mm"].startswith("0.10")
    assert table.loc["mlp", "shape_seeds x refs"] == "3 x 2" and table.loc[FLOOR, "shape_seeds x refs"] == "1 x 2"
    verdict = report.best_against_best(rows).set_index("family")
    assert verdict.loc["shape", ["a", "b"]].tolist() == ["rf-fwd", "mlp"]
    assert verdict.loc["shape", "estimate"] == pytest.approx(-1.0)
    assert verdict.loc["shape", "high"] < 0 and verdict.loc["shape", "lower"] == "rf-fwd"
    assert verdict.loc["shape", ["t_low", "t_high"]].tolist() == pytest.approx([-1.0, -1.0])  # the same on both
    # random: the bootstrap excludes 0, the t-interval on differences -1, -2 (t 12.71, 1 dof) does not
    assert verdict.loc["random", "a"] == "rf-fwd" and verdict.loc["random", "high"] < 0
    assert verdict.loc["random", ["t_low", "t_high"]].tolist() == pytest.approx([-1.5 - 6.353, -1.5 + 6.353], abs=1e-3)
    assert pd.isna(verdict.loc["random", "lower"])
    assert [sections.verdict(row) for row in verdict.itertuples()] == ["RF-FWD lower", "no ranking"]
    conditions = rows.assign(condition="table1", coverage=1.0)
    grid = report.protocol_table(conditions)
    assert list(grid.columns) == [*report.TABLE1_MODELS, FLOOR, "coverage"]
    assert grid.loc["table1", "lstm"] == pytest.approx(6.6)


def ambiguity_rows(noise=0.1):
    """Two variants, MLP and RF, three seeds on two shapes and one random reference: RF 2 mm
    below the MLP on every reference of the folded variant, equal in the paper's."""
    rows = []
    for variant, gain in (("paper", 0.0), ("folded", -2.0)):
        for model in ("mlp", "rf"):
            for seed in (0, 1, 2):
                for k, (reference, family) in enumerate((("circle", "shape"), ("star", "shape"), ("Rand1", "random"))):
                    rmse = 5.0 + k + noise * seed + (gain if model == "rf" else 0.0)
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
    return pd.DataFrame(rows)


def test_regime_map_pairs_each_flow_with_the_mlp_per_variant():
    table = report.regime_map(ambiguity_rows()).set_index(["variant", "a", "family"])
    assert table.loc[("folded", "rf", "shape"), "estimate"] == pytest.approx(-2.0)
    assert table.loc[("folded", "rf", "shape"), "lower"] == "rf"
    assert table.loc[("paper", "rf", "random"), "estimate"] == pytest.approx(0.0, abs=1e-12)
    assert pd.isna(table.loc[("paper", "rf", "random"), "lower"])
    assert table.loc[("paper", "rf", "step"), "estimate"] == pytest.approx(0.0, abs=1e-12)
    # one random reference: the bootstrap over seeds excludes 0, a t-interval needs two references
    random = table.loc[("folded", "rf", "random")]
    assert random.high < 0 and np.isnan(random.t_low) and pd.isna(random.lower)
    step = table.loc[("folded", "rf", "step")]  # one number per model: no references to pair over
    assert pd.isna(step.lower) and np.isnan(step.holm_p)  # and out of the map's Holm family


def write_closed_loop(out):
    """Notebook 10's tables: the closed loop worse than the open one on one reference per
    gravity, the calibrated learning never."""
    pd.DataFrame(
        {
            "gravity": ["vertical"] * 3 + ["horizontal"] * 3,
            "reference": ["star", "circle", "mean"] * 2,
            "open": [5.0, 3.0, 4.0, 10.0, 6.0, 8.0],
            "closed": [6.0, 2.0, 4.0, 8.0, 7.0, 7.5],
            "closed-ilc-calibrated": [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
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


def test_the_closed_loop_section_answers_with_the_means_over_the_shapes(profile):
    write_closed_loop(profile.output_dir)
    section = sections.closed_loop_section(profile)
    assert "open 4.00 / 8.00 mm, closed 4.00 / 7.50 mm" in sections.words(section, "answer")
    assert "| vertical star | 5.00 | 6.00 | 1.00 |" in sections.table_text(section)


def data_size_rows(noise=0.1):
    """Two sizes, the four models of data_size, three seeds on three references per family: the
    prior 1 mm lower, being generative 0.5 mm lower, on every reference."""
    offsets = {"mlp": 0.0, "mlp-physical": -1.0, "rf": -0.5, "rf-physical": -1.5}
    return pd.DataFrame(
        [
            dict(
                episodes=episodes,
                model=model,
                seed=seed,
                reference=f"{family}{r}",
                family=family,
                rmse_mm=5.0 + r + noise * seed + offset,
            )
            for episodes in (100, 300)
            for model, offset in offsets.items()
            for seed in range(3)
            for family in ("shape", "random")
            for r in range(3)
        ]
    )


def test_size_effects_separate_the_prior_from_being_generative():
    table = report.size_effects(data_size_rows()).set_index(["episodes", "effect", "family"])
    assert table.loc[(100, "prior, flow", "shape"), "estimate"] == pytest.approx(-1.0)
    assert table.loc[(300, "generative, with prior", "random"), "estimate"] == pytest.approx(-0.5)
    assert table.loc[(300, "generative, with prior", "random"), ["t_low", "t_high"]].tolist() == pytest.approx(
        [-0.5, -0.5]
    )
    assert table.loc[(300, "generative, with prior", "random"), "lower"] == "rf-physical"
    assert table.loc[(100, "prior, regression", "shape"), "lower"] == "mlp-physical"


def fwd_lambda_rows(offsets, noise=0.1):
    """fwd_lambda's rows: three seeds on three references per family; ``offsets``: weight ->
    family -> the weight's RMSE change, one number or one per reference."""

    def offset(weight, family, r):
        change = offsets[weight].get(family, 0.0)
        return change[r] if isinstance(change, tuple) else change

    return pd.DataFrame(
        [
            dict(
                consistency=weight,
                model="rf-fwd",
                seed=seed,
                reference=f"{family}{r}",
                family=family,
                rmse_mm=5.0 + r + noise * seed + offset(weight, family, r),
            )
            for weight in offsets
            for seed in range(3)
            for family in ("shape", "random")
            for r in range(3)
        ]
    )


def test_lambda_decision_changes_the_default_only_when_better_on_both_families():
    table, chosen = report.lambda_decision(
        fwd_lambda_rows(
            {0.0: {"shape": -1.0}, 0.1: {"shape": -1.0, "random": -0.5}, 0.3: {"shape": -1.0, "random": -0.8}, 1.0: {}}
        )
    )
    weights = table.groupby("a")[["better_on_both", "chosen"]].all()
    assert chosen == 0.3 and weights.loc[0.1, "better_on_both"] and not weights.loc[0.0, "better_on_both"]
    assert weights["chosen"].tolist() == [False, False, True]
    assert table.set_index(["a", "family"]).loc[(0.0, "random"), "estimate"] == pytest.approx(0.0, abs=1e-12)
    _, chosen = report.lambda_decision(fwd_lambda_rows({0.0: {"shape": -1.0, "random": 0.5}, 1.0: {}}))
    assert chosen == 1.0


def test_lambda_decision_needs_the_t_interval_too():
    """Random differences -0.2, -0.8, -1.4: every bootstrap mean of them is below 0, but the
    t-interval is -0.8 +- 4.303 x 0.6 / sqrt(3) = [-2.29, +0.69]."""
    table, chosen = report.lambda_decision(
        fwd_lambda_rows({0.3: {"shape": -1.0, "random": (-0.2, -0.8, -1.4)}, 1.0: {}})
    )
    by_family = table.set_index("family")
    assert by_family.loc["random", "high"] < 0 and by_family.loc["shape", "high"] < 0
    assert by_family.loc["random", ["t_low", "t_high"]].tolist() == pytest.approx([-2.2905, 0.6905], abs=1e-3)
    assert not table.better_on_both.any() and chosen == 1.0


def test_the_ambiguity_and_data_size_answers_state_only_what_both_intervals_rank(profile):
    write_sweep(profile, "ambiguity", ambiguity_rows(noise=0.0))
    write_sweep(profile, "data_size", data_size_rows(noise=0.0))
    regimes = sections.ambiguity_section(profile)
    # folded: 2 mm lower on both shapes (ranked) and on the one random reference (no t-interval: not ranked)
    answer = sections.words(regimes, "answer")
    assert "a flow minus the MLP is -2.00 mm (RF lower in 1 of 2, no ranking in 1 of 2)" in answer
    assert "over all 4 comparisons the flow is lower in 1, the MLP in 0, 3 unranked" in answer
    table = sections.table_text(regimes)
    assert (
        "| folded | RF | 0.300 / 0.100 | -2.00 [-2.00, -2.00] (RF lower) | -2.00 [-2.00, -2.00] (no ranking) |" in table
    )
    sizes = sections.data_size_section(profile)
    assert "| 100 | prior, flow | -1.00 [-1.00, -1.00] (" in sections.table_text(sizes)
    assert sections.words(sizes, "answer").startswith("Of 16 effects (prior and being generative, per size and family)")


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


def test_the_consistency_weight_answer_states_the_rules_choice(profile):
    offsets = {0.1: {"shape": -0.2, "random": 0.1}, 0.3: {"shape": -0.2, "random": -0.4}, 1.0: {}}
    write_sweep(profile, "fwd_lambda", fwd_lambda_rows(offsets, noise=0.0))
    section = sections.fwd_lambda_section(profile)
    assert sections.words(section, "answer") == "lambda = 0.3 is better on both families, so the default changes to it."
    assert "| 0.1 | -0.20 [-0.20, -0.20] | +0.10 [+0.10, +0.10] | no |" in sections.table_text(section)
    offsets[0.3]["random"] = (-0.2, -0.8, -1.4)  # the bootstrap ranks it, the t-interval does not
    write_sweep(profile, "fwd_lambda", fwd_lambda_rows(offsets, noise=0.0))
    assert "so the default stays" in sections.words(sections.fwd_lambda_section(profile), "answer")


def test_floor_progress_counts_references_still_improving_at_the_last_trial():
    assert report.floor_progress(study_rows(), ILC_TRIALS) == (3, 4)
    assert report.floor_progress(study_rows(), 40) == (0, 4)  # a longer budget: none stopped at its last


def test_verdict_counts_count_what_each_rule_ranks():
    def compared(family, low, high, t_low=np.nan, t_high=np.nan):
        return dict(family=family, low=low, high=high, t_low=t_low, t_high=t_high)

    table1 = pd.DataFrame(
        [compared("shape", -2, -1, -3, -0.5), compared("random", 1, 2, -1, 4)]  # both rank it; the bootstrap alone
    )
    regimes = pd.DataFrame(
        [
            compared("shape", -1, 1, -1, 1),  # neither
            compared("random", 1, 2, 0.5, 3),  # both
            compared("step", 0.1, 0.2),  # the bootstrap only: no t-interval per step
        ]
    )
    counts = report.verdict_counts({"table1": table1, "ambiguity": regimes})
    assert counts.loc["best RF variant - best baseline (table1)"].tolist() == [2, 2, 1]
    assert counts.loc["flow - MLP, tracking (ambiguity)"].tolist() == [2, 1, 1]
    assert counts.loc["flow - MLP, per-step u error (ambiguity)"].tolist() == [1, 1, 0]
    assert counts.loc["all"].tolist() == [5, 4, 2]
    assert "prior and generative effects (data_size)" not in counts.index  # a study not given is left out


def test_table4_appends_our_measured_rf_fwd_row(profile):
    out = profile.output_dir
    pd.DataFrame({"steps": [1, 4, 8], "latency_ms": [0.05, 0.1234, 0.3]}).to_csv(out / "euler_sweep.csv", index=False)
    pd.DataFrame({"model": ["rf", "rf-fwd", "forward"], "minutes": [5.0, 10.2, 3.4]}).to_csv(
        out / "training_rf.csv", index=False
    )
    pd.DataFrame({"family": ["burst", "burst", "shape"], "peak_speed": [0.45, 0.9, 3.0]}).to_csv(
        out / "twin_results.csv", index=False
    )
    pd.DataFrame({"reference": ["star", "mean"], "vertical": [100.0, 4.5], "horizontal": [1.0, 9.0]}).to_csv(
        out / "table3_twin.csv", index=False
    )
    table = report.table4(profile)
    assert list(table.index[:-1]) == list(report.PAPER_TABLE4.index)  # the paper's rows, unchanged
    assert table.loc["RF-FWD (paper)"].tolist() == report.PAPER_TABLE4.loc["RF-FWD (paper)"].tolist()
    length_mm = 1e3 * HW_ROBOT.length
    ours = table.loc["RF-FWD (this repo, twin)"]
    assert ours.control == "Feedforward" and ours.inference_ms == "0.123"  # N = 4 Euler steps
    assert ours["speed_m_s (v/L 1/s)"] == f"0.90 ({0.9 / HW_ROBOT.length:.2f})"  # the burst's peak, not a shape's
    assert ours["error_mm (%L)"] == f"4.5-9.0 ({450 / length_mm:.2f}-{900 / length_mm:.2f}%)"  # the mean row
    assert ours.train_min == "14"  # 10.2 + 3.4 for the surrogate


def write_page_inputs(profile):
    """The smallest set of result CSVs and sweep rows the claims and the results page read."""
    out = profile.output_dir
    write_results(profile)
    rows = study_rows()
    write_sweep(profile, "table1", rows)
    write_sweep(profile, "ambiguity", ambiguity_rows(noise=0.0))
    write_sweep(profile, "data_size", data_size_rows(noise=0.0))
    write_sweep(profile, "fwd_lambda", fwd_lambda_rows({0.3: {"shape": -0.2, "random": -0.4}, 1.0: {}}, noise=0.0))
    summaries = {family: report.with_ci(rows, "rmse_mm", family) for family in ("shape", "random")}
    pd.concat(summaries, names=["family"]).to_csv(out / "08_table1_ci.csv")  # as notebook 08 writes it
    report.protocol_table(rows.assign(condition="table1", coverage=1.0)).to_csv(out / "08_protocol.csv")
    write_closed_loop(out)
    diagnostics(weights=(0.0, 0.3, 1.0)).to_csv(out / "11_fwd_lambda_diagnostics.csv")
    pd.DataFrame(
        [dict(model="rf-fwd", peak_speed=0.76, rmse_yz_mm=0.65, rmse_pct_L=0.16, reference_peak_speed=0.79)]
    ).to_csv(out / "stress_burst.csv", index=False)
    pd.DataFrame(
        {"model": ["rf-fwd", "rf-fwd", "mlp"], "mae_u1": [0.01, 0.02, 9.0], "mae_u2": [0.03, 0.03, 9.0]}
    ).to_csv(out / "stress_complex3d.csv", index=False)
    pd.DataFrame({"reference": ["star", "mean"], "vertical": [7.0, 6.0], "horizontal": [30.0, 23.35]}).to_csv(
        out / "table3_twin.csv", index=False
    )
    pd.DataFrame({"steps": [4], "latency_ms": [0.161]}).to_csv(out / "euler_sweep.csv", index=False)
    pd.DataFrame(
        {"vertical": [3.2, 6.0, 7.0, 6.5, 6.1], "horizontal": [2.6, 23.35, 40.9, 31.7, 23.9]},
        index=["no gap", "typical gap", "2 x youngs_modulus", "2 x density", "2 x damping"],
    ).to_csv(out / "twin_sensitivity.csv")
    pd.DataFrame(
        [dict(model="mlp", size="hidden=256", parameters=135426, rmse_shape_mm=0.5, rmse_random_mm=2.3, epochs=240)]
    ).to_csv(out / "baseline_sizes.csv", index=False)
    pd.DataFrame({"rmse_shape_mm": [0.65], "rmse_random_mm": [3.27]}, index=["rf-fwd, lambda = 0.1"]).to_csv(
        out / "design_sweep.csv"
    )


def test_claims_take_each_number_from_its_csv(profile):
    write_page_inputs(profile)
    items = {
        item.split("**")[1]: item.split("**: ", 1)[1]
        for item in " ".join(report.claims_list(profile).split("\n  ")).split("\n")
    }
    best = items["Best RF variant against the best baseline (shapes / random)"]
    # the change from the table1 study's 3-seed means (notebook 08), not from seed 0's Table I:
    # shapes 4.6 against 5.6 mm, ranked; random 14.1 against 15.6 mm, ranked by the bootstrap alone
    assert "ours 18 % lower / -10 %, no ranking;" in best
    assert "over 3 seeds" in best and "shape: -1.00 mm [-1.13, -0.87] (t: [-1.00, -1.00]), RF-FWD lower" in best
    assert "random: -1.50 mm [" in best and "(t: [-7.85, +4.85]), no ranking" in best
    assert "above the ILC floor of 0.10 / 0.10 mm (still improving at its last trial on 3 of 4 references" in best
    assert "ours 7.00 / 15.00;" in items["RF-FWD RMSE, shapes / random (mm)"]  # seed-0 Table I (write_results)
    assert "ours 0.015 / 0.030;" in items["Complex 3D: RF-FWD MAE u1 / u2 (N)"]  # RF-FWD's rows only
    hardware = items["Hardware mean RMSE, vertical / horizontal (mm)"]
    assert "ours 6.00 / 23.35;" in hardware and "without a reality gap 3.2 / 2.6 mm" in hardware
    assert "any other term at most 23.9 mm" in hardware and "closed loop: 1.00 / 2.00 mm" in hardware
    assert "ours 0.161 (eager torch, N = 4);" in items["Inference per step, batch 1 (ms)"]


def test_results_page_holds_every_table_and_section_and_only_existing_figures(profile, tmp_path):
    write_page_inputs(profile)
    (profile.output_dir / "05_burst.png").write_bytes(b"")
    run = tmp_path / "run"
    run.mkdir()
    for name, seconds in (("01_simulator.ipynb", 120.0), ("07_comparison_tables.ipynb", 60.0)):
        (run / name).write_text(json.dumps({"metadata": {"papermill": {"duration": seconds}}}))
    tables = {
        name: f"| {name} | made-up table |"
        for name in ("table1_tracking", "table2_inputs", "table3_hardware", "table4_literature")
    }
    page = results_page(profile, tables, run)
    headings = [line for line in page.splitlines() if line.startswith("## ")]
    assert headings == [
        "## Wall time per notebook (`make reproduce`, data and checkpoints cached)",
        "## Table I - open-loop tracking RMSE (mm), shapes / random references",
        "## Table II - phase lag on shapes (s), input energy on random references (N^2 s)",
        "## Table III - hardware-twin tracking RMSE through the camera (mm)",
        "## Table IV - comparison with the literature",
        "## When a ranking is stated",
        "## Table I with 95 % intervals and the floor (notebook 08)",
        "## The evaluation protocol's effect (notebook 08)",
        "## Where a flow beats regression (notebook 09)",
        "## The prior or being generative, by data size (notebook 09)",
        "## RF-FWD's consistency weight (notebook 11)",
        "## Closing the loop on the twin (notebook 10)",
        "## A two-segment rod: four inputs, one tip (notebook 12)",
        "## Learning from recorded runs (notebook 13)",
        "## A real robot: the ASL trunk (notebook 14)",
        "## The ASL trunk asked again (notebook 14)",
        "## A flow in one step (notebook 15)",
        "## The loop of a model of recorded runs (notebook 16)",
        "## Where the rows were computed",
        "## Numbers across CPUs",
        "## The paper's claims, reproduced or not",
        "## Design choices",
        "## Key figures",
    ]
    for heading, text in zip(headings[1:5], tables.values()):
        assert f"{heading}\n\n{text}\n" in page  # each table under its heading
    assert "| 01_simulator.ipynb | 2.0 | x86_64" in page and "Total: 2.0 min." in page  # 07 itself is not timed
    assert "| best RF variant - best baseline (table1) | 2 | 2 | 1 |" in page  # random: the bootstrap alone
    words = " ".join(page.split())  # the claims' list is filled to 110 columns
    assert "on 3 of 4 references" in words and "ours 18 % lower / -10 %, no ranking;" in words
    assert max(len(line) for line in page.splitlines()) <= 300
    assert "lambda = 0.3 is better on both families" in page
    assert "### High-speed burst circle\n\n![High-speed burst circle](../figures/05_burst.png)" in page
    assert page.count("![") == 1  # no other figure exists
    assert page.endswith("05_burst.png)\n")


def test_a_run_of_some_notebooks_keeps_the_measured_times_of_the_others(tmp_path):
    """The wall-time table is each notebook's last timed run: a later run of one notebook
    replaces its row (with this machine and commit) and keeps the rest as measured."""
    from softflow.report.provenance import recorded_wall_times

    file = tmp_path / "bench" / "reproduce.csv"
    first, second = tmp_path / "first", tmp_path / "second"
    for run, durations in ((first, {"01_a.ipynb": 60.0, "02_b.ipynb": 120.0}), (second, {"02_b.ipynb": 30.0})):
        run.mkdir()
        for name, seconds in durations.items():
            (run / name).write_text(json.dumps({"metadata": {"papermill": {"duration": seconds}}}))
    recorded_wall_times(first, file)
    kept = pd.read_csv(file, index_col="notebook")
    kept.loc["01_a.ipynb", "machine"] = "another machine"
    kept.to_csv(file)
    times = recorded_wall_times(second, file)
    assert times.minutes.to_dict() == {"01_a.ipynb": 1.0, "02_b.ipynb": 0.5}
    assert times.loc["01_a.ipynb", "machine"] == "another machine"  # not re-stamped
    assert pd.read_csv(file, index_col="notebook").minutes.to_dict() == times.minutes.to_dict()  # written back
    empty = tmp_path / "empty"
    empty.mkdir()
    assert recorded_wall_times(empty, file).equals(times)  # nothing timed: nothing replaced


def test_a_pipe_inside_a_markdown_cell_is_escaped():
    """A label like "rf | friction, 60 runs" stays one cell of the table."""
    from softflow.report import markdown

    text = markdown(pd.DataFrame({"best": ["rf | friction, 60 runs"], "mm": [-1.282]}, index=["vertical"]))
    assert text.splitlines()[-1] == "| vertical | rf \\| friction, 60 runs | -1.28 |"


def test_portability_section_shows_each_path_and_the_largest_spread_per_file(profile):
    assert "make portability" in "\n".join(report.page.portability_section(profile))  # no bench yet: the words only
    bench = profile.output_dir / "bench"
    bench.mkdir()
    pd.DataFrame(
        dict(
            path=["native", "generic"],
            kernels=["numpy X86_V4", "numpy baseline"],
            passed=[True, False],
            test_minutes=[7.0, 14.0],
            largest_share_of_tolerance=[0.5, 0.9],
        )
    ).to_csv(bench / "portability.csv", index=False)
    pd.DataFrame(
        dict(
            path=["generic", "generic", "avx2"],
            file=["a.csv", "b.csv", "a.csv"],
            largest_relative_difference=[1e-4, 5.9e-4, 3e-5],
        )
    ).to_csv(bench / "portability_spread.csv", index=False)
    text = "\n".join(report.page.portability_section(profile))
    assert "| native | numpy X86_V4 | True |" in text and "| generic | numpy baseline | False |" in text
    spread = text.split("per file")[1]
    assert spread.index("b.csv") < spread.index("a.csv")  # largest first
    assert "0.00059" in spread


def test_a_study_whose_rows_come_from_several_machines_says_so(profile):
    assert report.page.machines_section(profile) == []  # no rows shipped: nothing to say
    write_sweep(profile, "old", pd.DataFrame(dict(score=[1.0, 2.0])))  # before the machine column
    write_sweep(profile, "one", pd.DataFrame(dict(score=[1.0, 2.0], machine=["AMD EPYC", "AMD EPYC"])))
    write_sweep(profile, "mixed", pd.DataFrame(dict(score=[1.0, 2.0, 3.0], machine=["Xeon", None, "Xeon"])))
    text = "\n".join(report.page.machines_section(profile))
    assert "| mixed | Xeon (2 rows), unknown (1 row) |" in text and "| old | unknown (2 rows) |" in text
    assert "| one | AMD EPYC (2 rows) |" in text
    assert "different or unknown machines: mixed." in text
