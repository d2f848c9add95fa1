"""The one-step study's rules on hand-made rows: a one-step flow as good as its parent is
"within" 10 %, a plain flow in one Euler step that gives the MLP's errors has collapsed, and
the tip-alone win is a verdict of the two intervals and Holm."""

import numpy as np
import pandas as pd

from softflow.studies import one_step


def rows(errors: dict, rod: str = one_step.TWO_SEGMENT_TIP, references: int = 12) -> pd.DataFrame:
    """Rows of each (model, plan_steps): RMSE = its factor x a per-reference error shared by all
    (1 to 12 mm), +0.01 mm per seed."""
    shared = np.linspace(1.0, 12.0, references)
    return pd.DataFrame(
        [
            dict(rod=rod, model=model, plan_steps=steps, seed=seed, reference=f"R{r}", family="random")
            | dict(rmse_mm=factor * shared[r] + 0.01 * seed)
            for (model, steps), factor in errors.items()
            for seed in range(3)
            for r in range(references)
        ]
    )


def test_the_rules_on_rows_where_the_one_step_flow_keeps_its_parents_errors():
    made = rows(
        {
            ("mlp", 0): 1.0,
            ("rf", 4): 0.8,
            ("rf", 1): 1.0,  # one Euler step: the MLP's errors
            ("rf-1", 1): 0.82,  # 2.5 % above its parent
            ("rf-1", 2): 0.8,
            ("rf-fwd", 4): 0.8,
            ("rf-fwd", 1): 1.3,
            ("rf-fwd-1", 1): 1.0,  # 25 % above its parent: as the MLP
        }
    )
    tables = one_step.summarise(made)
    parity = tables["parity"].set_index("a")
    assert abs(parity.at["rf-1@1", "ratio"] - 0.82 / 0.8) < 1e-3
    assert parity.at["rf-1@1", "within_10_percent"] == "within"
    assert parity.at["rf-fwd-1@1", "within_10_percent"] == "outside"
    collapse = tables["collapse"].set_index("a")
    assert collapse.at["rf@1", "within_10_percent"] == "within"  # the collapse the theory predicts
    assert collapse.at["rf-fwd@1", "within_10_percent"] == "outside"
    win = tables["tip_win"].set_index("a")
    assert win.at["rf-1@1", "lower"] == "rf-1@1"  # 18 % below the MLP on every reference
    assert pd.isna(win.at["rf-fwd-1@1", "lower"])  # the MLP's errors exactly
    assert (win["holm_p"] >= win["p"]).all()


def test_the_paper_rod_has_no_tip_alone_comparison():
    made = rows({("mlp", 0): 1.0, ("rf", 4): 0.9, ("rf", 1): 1.0, ("rf-1", 1): 0.9}, rod=one_step.PAPER_ROD)
    tables = one_step.summarise(made)
    assert tables["tip_win"].empty and len(tables["parity"]) == 1 and len(tables["collapse"]) == 1


def test_the_grid_is_the_registered_one():
    paper = one_step.cells("paper")
    assert len(paper) == 2 * 5 * 3  # two rods, five models, three seeds
    assert {c["model"] for c in paper} == set(one_step.PLANS)
    assert {(c["rod"], c["model"]) for c in one_step.cells("ci")} == {("paper", m) for m in ("mlp", "rf", "rf-1")}


def test_the_answer_states_each_rules_words(tmp_path, monkeypatch):
    """The one-step answer quotes every comparison with its own words and interval."""
    from small_runs import report_profile, write_sweep

    from softflow.report import sections

    profile = report_profile(tmp_path, monkeypatch)
    made = rows({("mlp", 0): 1.0, ("rf", 4): 0.8, ("rf", 1): 1.0, ("rf-1", 1): 0.82, ("rf-fwd-1", 1): 1.0})
    write_sweep(
        profile, "one_step", made.assign(key=made["model"] + made["plan_steps"].astype(str) + made["seed"].astype(str))
    )
    said = sections.words(sections.one_step_section(profile), "answer")
    assert said.startswith("A one-step flow at 1 step over its parent at 4 is 1.02x (within in 1 of 1)")
    assert "a plain flow in 1 Euler step over the MLP, 1.00x (within in 1 of 1)" in said
    assert "RF-1@1 minus the MLP " in said and "(RF-1@1 lower)" in said and "(no ranking)" in said
