"""The recorded study (docs/assumptions.md, "The recorded study"): its grids as pre-registered,
the ci study run in process (rows with the pre-registered columns for every cell and
reference), a model of recordings planning motor commands within the recorded range, the
plant replaying planned commands as the open-loop experiment replays its own, and rows keyed
by how the runs were recorded."""

import dataclasses
import json
from collections import Counter

import numpy as np
import pandas as pd
import pytest
from small_runs import assert_like_shipped, report_profile, write_sweep

from softflow import hardware
from softflow.control import planning
from softflow.data.references import HARDWARE_SHAPES
from softflow.hardware import recorder
from softflow.profiles import PROFILES, TrainConfig
from softflow.report import sections, study_tables
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, U_MAX
from softflow.studies import recorded, sweep

CI_CELLS = [
    dict(
        study="recorded",
        seed=0,
        model=model,
        gravity="vertical",
        gap="friction",
        trained_on="recordings",
        runs=8,
        mode="planned-commands",
    )
    for model in ("mlp", "rf")
] + [
    dict(
        study="recorded",
        seed=0,
        model="rf-fwd",
        gravity="vertical",
        gap="friction",
        trained_on="simulator",
        mode="open",
        latency=0.033,
        dropped=0.0,
    )
]
RUN_SECONDS = 1.0  # the ci grid's recorded runs
TRACKING = ["reference", "family", "rmse_mm", "rmse_true_mm", "clipped", "cell_seconds"]
TRAINING = ["u_rmse_test", "conditional_spread", "conditional_spread_floor", "best_val", "epochs_run", "train_minutes"]
FLOW = ["u_rmse_draw", "u_rmse_mean_of_draws", "draw_spread", "spread_error_spearman"]


def test_the_ci_grid_is_the_pre_registered_one():
    """Vertical, FRICTION_GAP, 12 runs of 2 s (8 trained on, 4 held out, seed 1), MLP and RF at
    seed 0 with data_size's ci budget, the ci profile's simulator-trained RF-FWD open; the circle."""
    assert recorded.cells("ci") == CI_CELLS
    grid = recorded.RECORDED["ci"]
    assert grid.seconds == 1.0 and grid.held_out == 4 and list(grid.trained) == [("friction", 8)]
    assert grid.train == TrainConfig(
        epochs=3, steps_per_epoch=100, batch_size=256, warmup_steps=20, val_samples=2000, patience=3
    )
    assert recorded.GAPS["friction"] == hardware.FRICTION_GAP and recorded.GAPS["typical"] == hardware.TYPICAL_GAP
    assert [r.name for r in recorded.references(Simulator(HW_ROBOT, "vertical"), "ci")] == ["circle"]


def test_the_paper_grid_is_the_pre_registered_one():
    """Per configuration: 33 training cells (5 models on 60 minutes with friction, MLP and RF on 5
    and 15 minutes of it and on 60 minutes without, 3 seeds) and the shipped RF-FWD in 3 modes
    under each gap; 20 000 steps for every model; Table III's shapes and the burst circle."""
    cells = recorded.cells("paper")
    assert len(cells) == 78
    grid = recorded.RECORDED["paper"]
    assert grid.seconds == 5.0 and grid.held_out == 60 and grid.draws == 16
    assert grid.train == TrainConfig(epochs=40, steps_per_epoch=500, patience=40) and grid.train.batch_size == 512
    for gravity in ("vertical", "horizontal"):
        mine = [c for c in cells if c["gravity"] == gravity]
        trained = Counter((c["gap"], c["runs"] * 5 / 60, c["model"]) for c in mine if c["trained_on"] == "recordings")
        assert trained == Counter(
            {(gap, minutes, model): 3 for gap, minutes, models in [
                ("friction", 60, ("mlp", "lstm", "transformer", "rf", "rf-fwd")),
                ("friction", 5, ("mlp", "rf")),
                ("friction", 15, ("mlp", "rf")),
                ("typical", 60, ("mlp", "rf")),
            ] for model in models}
        )  # fmt: skip
        assert {c["seed"] for c in mine if c["trained_on"] == "recordings"} == {0, 1, 2}
        simulated = sorted((c["gap"], c["mode"]) for c in mine if c["trained_on"] == "simulator")
        assert simulated == sorted(
            (gap, mode)
            for gap in ("friction", "typical")
            for mode in ("open", "open-calibrated", "closed-ilc-calibrated")
        )
    names = [r.name for r in recorded.references(Simulator(HW_ROBOT, "vertical"), "paper")]
    assert names[:4] == list(HARDWARE_SHAPES) and len(names) == 5 and names[4].startswith("burst")


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """The ci study run in this process. The twin's RF-FWD is trained with the ci budget on 12
    ci episodes instead of 200 (simulating those took 69 of the study's 160 CPU-s; the cell's
    other steps are what is tested here)."""
    root = tmp_path_factory.mktemp("sweeps")
    few = dataclasses.replace(PROFILES["ci"], n_episodes=12, episode_seconds=2.0)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(recorded, "get_profile", lambda name: few if name == "ci" else PROFILES[name])
        result = sweep.run_sweep("recorded", "ci", client=None, device="cpu", root=root, progress=False)
        yield result, root / "recorded"


def test_the_ci_study_gives_the_pre_registered_rows(swept):
    result, _ = swept
    assert result.failures == [] and result.computed == 3
    rows = result.rows
    assert len(rows) == 3 and list(rows.reference) == ["circle"] * 3  # one row per cell and reference
    for cell, row in zip(CI_CELLS, rows.to_dict("records")):
        assert {k: row[k] for k in cell} == cell
    assert np.isfinite(rows[["rmse_mm", "rmse_true_mm"]].to_numpy()).all()
    assert (rows.rmse_mm < 25).all()  # the circle is 50 mm across: each tracks it
    learnt = rows[rows.trained_on == "recordings"]
    assert np.isfinite(learnt[TRACKING[2:] + TRAINING].to_numpy(float)).all()
    assert (learnt.epochs_run == 3).all() and (learnt.runs == 8).all()
    assert learnt[["train_runs", "val_runs", "held_out_runs"]].to_numpy().tolist() == [[7, 1, 4]] * 2
    np.testing.assert_allclose(learnt.recorded_minutes, 8 * RUN_SECONDS / 60)
    assert learnt.conditional_spread.nunique() == 1  # one recording set, one spread
    flow = learnt[learnt.model == "rf"]
    assert np.isfinite(flow[FLOW].to_numpy(float)).all()
    assert learnt[learnt.model == "mlp"][FLOW].isna().all().all()
    simulated = rows[rows.trained_on == "simulator"]
    assert simulated[TRACKING].notna().all().all() and simulated[TRAINING].isna().all().all()
    assert pd.read_csv(result.csv).shape == rows.shape
    # the recordings cells as they ship (the simulator cell here trains on fewer episodes than its shipped row)
    shipped = sweep.shipped_rows("recorded", "ci").astype({"key": str}).set_index("key")
    assert_like_shipped(learnt.reset_index(drop=True), shipped.loc[learnt.key.astype(str)].reset_index())


def test_the_runs_are_recorded_once_per_folder_under_the_sweep(swept):
    """One training folder (seed 0, 8 runs) and one held-out folder (seed 1, 4 runs) of the
    vertical twin across FRICTION_GAP, each with the recorder's settings; record_grid names the
    same folders."""
    _, workdir = swept
    folders = sorted((workdir / "recordings" / "ci").iterdir())
    assert [f.name.rsplit("-", 1)[0] for f in folders] == ["vertical-friction-seed0", "vertical-friction-seed1"]
    assert [len(list(f.glob("run*.csv"))) for f in folders] == [8, 4]
    for folder, seed in zip(folders, (0, 1)):
        settings = json.loads((folder / recorder.SETTINGS).read_text())
        assert settings["seed"] == seed and settings["seconds"] == RUN_SECONDS and settings["gravity"] == "vertical"
        assert settings["gap"] == hardware.FRICTION_GAP.parameters()
    stamps = {path: path.stat().st_mtime_ns for path in workdir.glob("recordings/ci/*/*")}
    recorded.record_grid("ci", workdir)  # the grid's folders, all there: nothing recorded again
    assert {path: path.stat().st_mtime_ns for path in workdir.glob("recordings/ci/*/*")} == stamps


def test_a_model_of_recordings_plans_motor_commands_within_the_recorded_range(swept):
    result, workdir = swept
    sim = Simulator(HW_ROBOT, "vertical")
    circle = recorded.references(sim, "ci")
    for cell in CI_CELLS[:2]:
        model, checkpoint, dataset, held_out = recorded.recorded_model(
            cell, "ci", "cpu", workdir
        )  # found, not retrained
        assert checkpoint["epochs_run"] == 3
        assert dataset.u.shape == (8, 100, 3) and held_out.u.shape == (4, 100, 3)  # l1..l3 in mm per 0.01 s
        (plan,), (clipped,) = recorded.plan_commands(model, cell["model"], checkpoint, circle)
        assert plan.shape == (circle[0].n_steps, HW_ROBOT.n_cables)
        seen = checkpoint["recorded"]  # what load_controller clips a model of recordings to
        np.testing.assert_array_equal(seen["u_min"], dataset.u.min((0, 1)))  # (3,) mm
        np.testing.assert_array_equal(seen["u_max"], dataset.u.max((0, 1)))
        low, high = planning.recorded_range(seen)  # +-the largest where every motor took both signs
        assert (plan >= low).all() and (plan <= high).all()
        assert np.ptp(plan, 0).min() > 1.0  # mm: it moves every motor, in the recorded units
        row = result.rows[(result.rows.model == cell["model"]) & (result.rows.trained_on == "recordings")]
        assert int(row.clipped.iloc[0]) == clipped


def test_planned_commands_replay_as_the_open_loop_experiment_replays_its_own():
    """run_commands on the commands the model rod makes of a plan is run_twin's open loop of
    that plan: the same plant, camera and seed per reference, so the rows are the same."""
    sim = Simulator(HW_ROBOT, "vertical")
    reference = recorded.references(sim, "ci")[0]
    short = dataclasses.replace(reference, states=reference.states[:81], mask=np.ones(81, bool))  # scored whole
    u = np.stack([np.full(80, 2.0), np.linspace(-3.0, 3.0, 80)], -1)  # (80, 2) N

    class Fixed:  # a controller that plans u whatever the reference
        def plan(self, states):
            return u

    gap, both = hardware.FRICTION_GAP, [short, dataclasses.replace(short, name="again")]
    expected, _ = hardware.run_twin(Fixed(), both, sim, gap, seed=3, u_limit=U_MAX)
    commands = hardware.cable_commands(np.stack([u, u]), sim)  # (2, 80, 3) m
    replayed, runs = hardware.run_commands(list(commands), both, sim, gap, clipped=[0, 2], seed=3)
    pd.testing.assert_frame_equal(replayed.drop(columns="clipped"), expected.drop(columns="clipped"))
    assert replayed.clipped.tolist() == [0, 2] and replayed.rmse_mm.nunique() == 2  # a camera seed per reference
    np.testing.assert_array_equal(runs["again"]["u"], commands[1])
    with pytest.raises(ValueError, match=r"commands must hold one \(T, C\) plan per reference \(2\); got 1"):
        hardware.run_commands(list(commands[:1]), both, sim, gap)
    with pytest.raises(ValueError, match=r"commands for 'circle' must have one row per step of it \(80\); got 79"):
        hardware.run_commands([commands[0, :79]], [short], sim, gap)
    with pytest.raises(ValueError, match=r"commands\[0\] must have shape \(any, 3\); got \(80, 2\)"):
        hardware.run_commands([commands[0, :, :2]], [short], sim, gap)


def test_changing_how_runs_are_recorded_rekeys_the_rows_of_their_models(monkeypatch):
    """The recorder's settings (its version, the run length, the held-out runs) are part of a
    recordings cell's key; the simulator-trained cell's key does not depend on them."""

    def keys():
        return [sweep.cell_key("recorded", cell, "ci", "cpu") for cell in recorded.cells("ci")]

    before = keys()
    assert len(set(before)) == 3
    for change in (
        lambda: monkeypatch.setattr(recorder, "RECORDER_VERSION", recorder.RECORDER_VERSION + 1),
        lambda: monkeypatch.setitem(recorded.RECORDED, "ci", dataclasses.replace(recorded.RECORDED["ci"], seconds=3.0)),
        lambda: monkeypatch.setitem(recorded.RECORDED, "ci", dataclasses.replace(recorded.RECORDED["ci"], held_out=5)),
    ):
        change()
        after = keys()
        assert after[0] != before[0] and after[1] != before[1] and after[2] == before[2]
        monkeypatch.undo()
        assert keys() == before


def test_the_table_gives_each_condition_and_model_its_interval():
    """Hand-made rows: a model of 8 recorded runs (two seeds, two shapes) and the simulator-trained
    RF-FWD open (one seed); the means are the rows' own, each condition apart, the true tip beside."""
    recorded_rows = [
        dict(gravity="vertical", gap="friction", trained_on="recordings", runs=8, mode="planned-commands", model="mlp",
             seed=seed, reference=reference, family="shape", rmse_mm=value, rmse_true_mm=value + 1)
        for seed, reference, value in [(0, "star", 1.0), (0, "circle", 3.0), (1, "star", 2.0), (1, "circle", 6.0)]
    ]  # fmt: skip
    simulator_rows = [
        dict(gravity="vertical", gap="friction", trained_on="simulator", runs=np.nan, mode="open", model="rf-fwd",
             seed=0, reference=reference, family="shape", rmse_mm=value, rmse_true_mm=value)
        for reference, value in [("star", 5.0), ("circle", 7.0)]
    ]  # fmt: skip
    table = study_tables.recorded_table(pd.DataFrame(recorded_rows + simulator_rows))
    assert list(table.index) == [
        ("vertical", "friction, 8 runs", "mlp"),
        ("vertical", "friction, simulator, open", "rf-fwd"),
    ]
    means = table["shape_mm"].str.split(" ").str[0].astype(float)
    np.testing.assert_allclose(means, [3.0, 6.0])
    np.testing.assert_allclose(table["shape_true_mm"].str.split(" ").str[0].astype(float), [4.0, 6.0])
    assert list(table["shape_seeds x refs"]) == ["2 x 2", "1 x 2"]
    assert study_tables.recorded_table(pd.DataFrame()).empty


SHAPES, BASE = ("star", "spiral", "circle", "heart"), np.array([4.0, 5.0, 6.0, 7.0])


def shape_rows(model, trained_on, values, *, gap="friction", runs=np.nan, mode="planned-commands", seeds=(0, 1)):
    """Hand-made rows of one model and condition on the four shapes, seed s adding 0.1 s mm."""
    return [
        dict(gravity="vertical", gap=gap, family="shape", model=model, trained_on=trained_on, runs=runs, mode=mode,
             seed=seed, reference=r, rmse_mm=v)
        for seed in seeds
        for r, v in zip(SHAPES, values + 0.1 * seed)
    ]  # fmt: skip


def rule_rows() -> pd.DataFrame:
    """On 60 runs RF (1 mm better than MLP) is clearly below the simulator's better mode,
    open-calibrated; on 12 runs MLP wobbles about it by +-1 mm."""
    return pd.DataFrame(
        shape_rows("rf-fwd", "simulator", BASE + 2, mode="open", seeds=(0,))
        + shape_rows("rf-fwd", "simulator", BASE, mode="open-calibrated", seeds=(0,))
        + shape_rows("rf-fwd", "simulator", BASE - 3, mode="closed-ilc-calibrated", seeds=(0,))  # not ranked against
        + shape_rows("mlp", "recordings", BASE - 1, runs=60)
        + shape_rows("rf", "recordings", BASE - 2, runs=60)
        + shape_rows("mlp", "recordings", BASE + np.array([1.0, -1.0, 1.0, -1.0]), runs=12)
        + shape_rows("rf", "recordings", BASE + 3, runs=12)
        + shape_rows("rf", "recordings", BASE - 5, runs=60, gap="typical")  # another gap
    )


def model_rule_rows() -> pd.DataFrame:
    """Under friction on 60 runs RF is 2 mm below LSTM and MLP (on 12 runs, ignored, it is not);
    without friction RF is 2 mm above MLP."""
    return pd.DataFrame(
        shape_rows("mlp", "recordings", BASE, runs=60)
        + shape_rows("lstm", "recordings", BASE + 0.5, runs=60)
        + shape_rows("rf", "recordings", BASE - 2, runs=60)
        + shape_rows("rf", "recordings", BASE + 9, runs=12)
        + shape_rows("mlp", "recordings", BASE, runs=60, gap="typical")
        + shape_rows("rf", "recordings", BASE + 2, runs=60, gap="typical")
    )


def test_the_recording_rule_compares_the_better_of_each_side():
    table = study_tables.recording_rule(rule_rows())
    assert list(zip(table.gravity, table.runs)) == [("vertical", 12), ("vertical", 60)]
    assert set(table.b) == {"rf-fwd | friction, simulator, open-calibrated"}
    assert list(table.a) == ["mlp | friction, 12 runs", "rf | friction, 60 runs"]
    np.testing.assert_allclose(table.estimate, [0.05, -1.95])  # the recorded seeds' mean is +0.05
    assert [sections.verdict(row, sections.RECORDING_SIDES) for row in table.itertuples()] == [
        "no ranking",
        "recordings lower",
    ]


def test_the_model_rule_ranks_on_the_most_runs_and_sees_friction_change_the_winner():
    table = study_tables.recorded_model_rule(model_rule_rows())
    assert list(zip(table.gravity, table.gap)) == [("vertical", "friction"), ("vertical", "typical")]
    assert list(table.b) == ["mlp", "mlp"] and list(table.a) == ["rf", "rf"]
    np.testing.assert_allclose(table.estimate, [-2.0, 2.0])
    assert list(table.lower) == ["rf", "mlp"] and set(table.friction_changes) == {"yes"}


def test_the_answer_says_each_verdict_whichever_way_and_whether_friction_changes_the_best(tmp_path, monkeypatch):
    profile = report_profile(tmp_path, monkeypatch)
    keyed = lambda rows: rows.assign(key=rows.model + rows.gap + rows.runs.astype(str))  # noqa: E731
    write_sweep(profile, "recorded", keyed(rule_rows()))
    answer = sections.words(sections.recorded_section(profile), "answer")
    assert "minus the simulator-trained RF-FWD is -1.95 to +0.05 mm over 2 configurations and sizes" in answer
    assert "(no ranking in 1 of 2, recordings lower in 1 of 2)" in answer
    write_sweep(profile, "recorded", keyed(model_rule_rows()))
    answer = sections.words(sections.recorded_section(profile), "answer")
    assert "The best RF variant minus the best baseline with the most recording is -2.00 to +2.00 mm" in answer
    assert answer.endswith(
        "(RF lower in 1 of 2, MLP lower in 1 of 2); friction changes which model is best (vertical)."
    )
    write_sweep(profile, "recorded", rule_rows().iloc[:0].assign(key=""))
    nothing = sections.words(sections.recorded_section(profile), "answer")
    assert nothing == "No comparison has rows of both its sides yet (0 cells have rows)."


def test_the_spread_table_gives_each_training_set_its_ratio_to_the_floor():
    rows = pd.DataFrame(
        [
            dict(gravity="vertical", gap=gap, trained_on=on, runs=n, conditional_spread=s, conditional_spread_floor=f)
            for gap, on, n, s, f in [
                ("friction", "recordings", 60, 0.30, 0.20),
                ("friction", "recordings", 60, 0.30, 0.20),  # another model on the same recordings
                ("typical", "recordings", 60, 0.21, 0.20),
                ("friction", "simulator", np.nan, np.nan, np.nan),  # no training set of its own
            ]
        ]
    )
    spread = study_tables.recorded_spread(rows)
    assert list(spread.index) == [("vertical", "friction", 60), ("vertical", "typical", 60)]
    np.testing.assert_allclose(spread["spread / floor"], [1.5, 1.05])
    assert study_tables.recorded_spread(rows.iloc[3:]).empty


def test_the_per_step_table_averages_each_model_over_its_seeds_once():
    """Hand-made rows: an MLP of 60 runs (two seeds, each on two references: counted once per seed),
    an RF with its draw measures, and the simulator's RF-FWD, which has no held-out runs of its own."""
    rows = pd.DataFrame(
        [
            dict(gravity="vertical", gap="friction", trained_on=on, runs=n, mode=mode, model=model, seed=seed,
                 reference=reference, u_rmse_test=error, draw_spread=spread)
            for on, n, mode, model, seed, error, spread in [
                ("recordings", 60, "planned-commands", "mlp", 0, 0.10, np.nan),
                ("recordings", 60, "planned-commands", "mlp", 1, 0.20, np.nan),
                ("recordings", 60, "planned-commands", "rf", 0, 0.30, 0.05),
                ("simulator", np.nan, "open", "rf-fwd", 0, np.nan, np.nan),
            ]
            for reference in ("star", "circle")
        ]
    )  # fmt: skip
    table = study_tables.recorded_per_step(rows)
    assert list(table.index) == [("vertical", "friction, 60 runs", "mlp"), ("vertical", "friction, 60 runs", "rf")]
    np.testing.assert_allclose(table.u_rmse_test, [0.15, 0.30])
    np.testing.assert_allclose(table.u_rmse_test_sd, [np.std([0.10, 0.20], ddof=1), np.nan])
    np.testing.assert_allclose(table.draw_spread, [np.nan, 0.05])
    assert list(table.seeds) == [2, 1]
    assert study_tables.recorded_per_step(rows[rows.trained_on == "simulator"]).empty
