"""Notebook 12's pieces: the two_segment study's tables on small hand-made rows (Table I per
observation with the floor, the decision rule per family, per-step scores, the conditional
spread; an unfinished or empty sweep), and ``fit_holding``, the second input history of the
redundancy figure (another u on the curve of u that reaches one tip point)."""

import numpy as np
import pandas as pd
import pytest
from small_runs import report_profile, write_sweep

from softflow.data import least_norm_lift
from softflow.report import sections, study_tables
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT, TWO_SEGMENT_ROD
from softflow.rod.validation import arc_tip

FAMILIES = {"shape": ("S1", "S2", "S3"), "random": ("R1", "R2", "R3"), "path3d": ("P1",)}
OFFSET = {"S1": 0.0, "S2": 0.4, "S3": 0.8, "R1": 10.0, "R2": 14.0, "R3": 12.0, "P1": 3.0}


def _rows(cells) -> pd.DataFrame:
    """One row per reference (and plan) of each (observation, model, seed, level, per-step error):
    RMSE = the reference's offset + level + seed / 10 on the shapes and the 3-D path; on the
    random references the level's sign alternates, so no model is lower on all of them."""
    out = []
    for observation, model, seed, level, u_error in cells:
        plans = ["zero", "mean-of-4"] if model.startswith("rf") else ["zero"]
        for plan in plans:
            for family, references in FAMILIES.items():
                for k, reference in enumerate(references):
                    shift = level * (-1) ** k if family == "random" else level
                    out.append(
                        dict(
                            model=model,
                            seed=seed,
                            observation=observation,
                            family=family,
                            reference=reference,
                            plan=plan,
                            rmse_mm=OFFSET[reference] + shift + seed / 10 + (50.0 if plan != "zero" else 0.0),
                            u_rmse_test=u_error + seed / 100,
                            tip_step_mm=2 * u_error,
                            conditional_spread=0.5 if observation == "tip" else 0.25,
                            conditional_spread_floor=0.2,
                        )
                    )
    return pd.DataFrame(out)


@pytest.fixture(scope="module")
def rows() -> pd.DataFrame:
    """tip: MLP and RF, two seeds, RF 1 mm lower on the shapes; tip+disk: only the MLP so far (a
    sweep that has not finished); the floor, whose rows have no plan and no per-step measures."""
    models = _rows(
        [
            ("tip", "mlp", 0, 1.0, 0.8),
            ("tip", "mlp", 1, 1.0, 0.8),
            ("tip", "rf", 0, 0.0, 0.7),
            ("tip", "rf", 1, 0.0, 0.7),
            ("tip+disk", "mlp", 0, 0.5, 0.3),
        ]
    )
    floor = pd.DataFrame(
        [
            dict(model="ilc-floor", seed=0, observation="simulator", family=f, reference=r, rmse_mm=0.1)
            for f, references in FAMILIES.items()
            for r in references
        ]
    )
    return pd.concat([floor, models], ignore_index=True)  # the grid lists the floor first


def test_table_one_per_observation_with_the_floor_last_and_only_zero_plans(rows):
    table = study_tables.two_segment_table(rows)
    bound = ("simulator", study_tables.ILC_BOUND)  # the floor's rows, named for what they are
    assert table.index.tolist() == [("tip", "mlp"), ("tip", "rf"), ("tip+disk", "mlp"), bound]
    assert table.columns.tolist() == [f"{family}_{column}" for family in FAMILIES for column in ("mm", "seeds x refs")]
    assert table.loc[bound, "shape_mm"] == "0.10 [0.10, 0.10]"
    assert table.loc[bound, "random_seeds x refs"] == "1 x 3"
    assert table.loc[("tip", "mlp"), "shape_seeds x refs"] == "2 x 3"
    assert table.loc[("tip+disk", "mlp"), "path3d_seeds x refs"] == "1 x 1"
    # RF's z = 0 plans: 0.4 mean offset + 0.05 mean seed; its mean-of-4 rows (50 mm higher) are not Table I's
    assert table.loc[("tip", "rf"), "shape_mm"].startswith("0.45 [")
    assert table.loc[("tip", "rf"), "path3d_mm"].startswith("3.05 [")


def test_decision_rule_per_family_where_both_groups_have_rows(rows):
    differences = study_tables.two_segment_differences(rows).set_index(["observation", "family"])
    assert differences.index.tolist() == [("tip", "shape"), ("tip", "random"), ("tip", "path3d")]  # tip+disk: no RF yet
    shape = differences.loc[("tip", "shape")]
    assert (shape.a, shape.b) == ("rf", "mlp")
    assert shape.estimate == pytest.approx(-1.0) and shape.high < 0 and shape.t_high < 0
    assert shape.lower == "rf" and shape.kept_after_holm
    assert pd.isna(differences.loc[("tip", "random"), "lower"])
    path3d = differences.loc[("tip", "path3d")]  # one path in rotations: not ranked, out of the Holm family
    assert pd.isna(path3d.lower) and np.isnan(path3d.holm_p)
    assert shape.holm_p == pytest.approx(min(1.0, 2 * min(shape.p, differences.loc[("tip", "random"), "p"])))


def test_the_answer_says_each_verdict_whichever_way(rows, tmp_path, monkeypatch):
    profile = report_profile(tmp_path, monkeypatch)
    rows = rows.assign(key=rows.model + rows.observation + rows.seed.astype(str))
    write_sweep(profile, "two_segment", rows)
    answer = sections.words(sections.two_segment_section(profile), "answer")
    assert answer.startswith("Best RF variant minus best baseline seen at the tip alone: -1.00 mm [")
    assert "(RF lower) on the shapes, -0.33 mm [" in answer and "(no ranking) on the random references." in answer
    assert "middle disk" not in answer  # no RF variant there yet
    write_sweep(profile, "two_segment", rows.iloc[:0])
    nothing = sections.words(sections.two_segment_section(profile), "answer")
    assert nothing == "No observation has rows of both sides yet (0 cells have rows)."


def test_best_against_best_keeps_its_families_and_leaves_out_one_without_both_groups(rows):
    tip = rows[(rows.observation == "tip") & (rows.plan == "zero")]
    assert study_tables.best_against_best(tip).family.tolist() == ["shape", "random"]  # the default, as before
    baselines_only = rows[rows.observation == "tip+disk"]
    assert study_tables.best_against_best(baselines_only, families=("shape", "path3d")).empty


def test_per_step_scores_per_model_with_their_seed_spread(rows):
    per_step = study_tables.two_segment_per_step(rows)
    assert per_step.index.tolist() == [("tip", "mlp"), ("tip", "rf"), ("tip+disk", "mlp")]  # no floor
    assert per_step.loc[("tip", "mlp"), "u_rmse_test"] == pytest.approx(0.805)
    assert per_step.loc[("tip", "mlp"), "u_rmse_test_sd"] == pytest.approx(0.01 / np.sqrt(2))
    assert per_step.loc[("tip", "rf"), "tip_step_mm"] == pytest.approx(1.4)
    assert per_step.loc[("tip+disk", "mlp"), "seeds"] == 1 and np.isnan(
        per_step.loc[("tip+disk", "mlp"), "tip_step_mm_sd"]
    )


def test_conditional_spread_per_observation_against_its_floor(rows):
    spread = study_tables.two_segment_spread(rows)
    assert spread.index.tolist() == ["tip", "tip+disk"]  # the floor observes nothing
    np.testing.assert_allclose(spread["spread / floor"], [2.5, 1.25])


def test_the_regime_map_places_each_observation_as_a_variant(rows):
    """RF against the MLP per observation, as the ambiguity study's variants are: on the tip RF is
    1 mm lower on every shape (both intervals exclude 0), no ranking on the random references;
    tip+disk has no flow yet, so no row; the floor and the 3-D path never enter."""
    variants = study_tables.two_segment_variants(rows)
    assert set(variants.variant) == {"two segments, tip", "two segments, tip+disk"}
    assert set(variants.family) == {"shape", "random"} and "ilc-floor" not in set(variants.model)
    regimes = study_tables.regime_map(variants)
    assert set(zip(regimes.variant, regimes.a)) == {("two segments, tip", "rf")}
    tip = regimes.set_index("family")
    assert (tip.conditional_spread == 0.5).all() and (tip.spread_floor == 0.2).all()
    assert tip.estimate["shape"] == pytest.approx(-1.0) and tip.high["shape"] < 0 and tip.lower["shape"] == "rf"
    assert pd.isna(tip.lower["random"])
    assert tip.estimate["step"] == pytest.approx(-0.1)
    assert study_tables.two_segment_variants(rows.iloc[:0]).empty


def test_an_empty_or_floor_only_sweep_gives_empty_tables(rows):
    for part in (pd.DataFrame(), rows[rows.model == "ilc-floor"]):
        assert study_tables.two_segment_differences(part).empty
        assert study_tables.two_segment_per_step(part).empty
        assert study_tables.two_segment_spread(part).empty
    assert study_tables.two_segment_table(pd.DataFrame()).empty
    assert study_tables.two_segment_table(rows[rows.model == "ilc-floor"]).index.tolist() == [
        ("simulator", study_tables.ILC_BOUND)
    ]


# ---------------------------------------------------------------------------- fit_holding


def test_holding_an_input_recovers_the_u_that_made_the_point_on_the_closed_form_arcs():
    """Without gravity the tip is the closed-form piecewise arc: from a start 0.3 N off on the
    free inputs, the fit with u_1 held at its true value finds the true u again, and its tip is
    the arc's (no GVS in the check)."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity="none")
    u = np.array([[1.0, -0.5, 2.0, 1.5], [-2.0, 1.0, -1.0, 2.5]])
    p = arc_tip(u, TWO_SEGMENT_ROD)
    found = sim.fit_holding(p, 0, u[:, 0], start=u + [0.0, 0.3, -0.3, 0.3])
    np.testing.assert_allclose(found, u, rtol=0, atol=1e-9)  # measured 3e-15 N
    np.testing.assert_allclose(arc_tip(found, TWO_SEGMENT_ROD), p, rtol=0, atol=1e-12)


def test_a_second_u_reaches_the_least_norm_u_s_point_under_gravity():
    """A point 6 mm above the least-norm depth (there the u that reach it form a wide curve): u_1
    held 1 N above the least-norm u_1, the other inputs put the tip on the point, with more force
    than the least-norm u."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity="vertical")
    yz = sim.static_tip(np.zeros((1, 4)))[:, 1:] + 0.05 * np.array([[np.cos(np.pi / 3), np.sin(np.pi / 3)]])
    p = least_norm_lift(sim, yz).positions[:, -1] - [[0.006, 0.0, 0.0]]
    least_norm = sim.inverse_static(p)
    held = sim.fit_holding(p, 0, least_norm[:, 0] + 1.0, start=least_norm)
    assert held[0, 0] == least_norm[0, 0] + 1.0
    np.testing.assert_allclose(sim.static_tip(held), p, rtol=0, atol=1e-12)
    assert np.linalg.norm(held) > np.linalg.norm(least_norm) + 0.01 and np.abs(held - least_norm).max() >= 1.0


def test_holding_checks_its_input():
    sim = Simulator(TWO_SEGMENT_ROD, gravity="vertical")
    rest = sim.static_tip(np.zeros((1, 4)))
    with pytest.raises(ValueError, match="more inputs than the tip's 3 coordinates"):
        Simulator(SIM_ROBOT).fit_holding(rest, 0, 0.0)
    for index in (4, -1, True, 1.0):
        with pytest.raises(ValueError, match=r"index must be an input's index, an integer in \[0, 3\]"):
            sim.fit_holding(rest, index, 0.0)
    with pytest.raises(ValueError, match=r"value must have shape \(1\)"):
        sim.fit_holding(rest, 0, [0.0, 1.0])
    with pytest.raises(ValueError, match=r"p must have shape \(any, 3\)"):
        sim.fit_holding(rest[:, :2], 0, 0.0)
    with pytest.raises(
        ValueError, match="not reached with u1 held at 2.000 N"
    ):  # the straight rod's tip is the deepest: any bend lifts it
        sim.fit_holding(rest, 0, 2.0)
