"""The summary notebooks 03 and 04 share: training log, Table I/II text, planning latency and
the figure grids, each on a tiny input whose right answer is known."""

import numpy as np
import pandas as pd
import pytest
import torch

from softflow import control, profiles, training
from softflow.data.references import Reference, shape_reference
from softflow.report import model_summary
from softflow.rod import SIM_ROBOT, Simulator

CHECKPOINTS = {
    "mlp": dict(epochs_run=4, best_val=0.00481, wall_seconds=12.0),
    "transformer": dict(epochs_run=12, best_val=0.12346, wall_seconds=150.0),
}


@pytest.fixture
def profile(tmp_path, monkeypatch):
    monkeypatch.setattr(profiles, "REPO", tmp_path)
    p = profiles.Profile("summary-test", n_episodes=1)
    p.output_dir.mkdir(parents=True)
    return p


@pytest.fixture(scope="module")
def sim():
    return Simulator(SIM_ROBOT)


def test_train_models_keeps_each_models_checkpoint(monkeypatch):
    calls = []

    def ensure_trained(name, profile, dataset):
        calls.append((name, profile, dataset))
        return f"model {name}", CHECKPOINTS[name]

    monkeypatch.setattr(training, "ensure_trained", ensure_trained)
    assert model_summary.train_models(["transformer", "mlp"], "P", "D") == {
        "transformer": CHECKPOINTS["transformer"],
        "mlp": CHECKPOINTS["mlp"],
    }
    assert calls == [("transformer", "P", "D"), ("mlp", "P", "D")]


def test_training_log_has_one_row_per_model_in_minutes():
    log = model_summary.training_log(CHECKPOINTS)
    assert list(log.columns) == ["model", "epochs", "best_val", "minutes"]
    assert log.model.tolist() == ["mlp", "transformer"]
    assert log.epochs.tolist() == [4, 12]
    np.testing.assert_allclose(log.minutes, [0.2, 2.5])
    np.testing.assert_allclose(log.best_val, [0.00481, 0.12346])


def test_training_text_prints_one_aligned_line_per_model():
    assert model_summary.training_text(CHECKPOINTS).split("\n") == [
        "mlp          4 epochs, best validation loss 0.0048, training 0.2 min",
        "transformer  12 epochs, best validation loss 0.1235, training 2.5 min",
    ]


def test_table_text_rounds_each_column_as_the_paper_and_keeps_the_row_order():
    table = pd.DataFrame(
        dict(rmse_shape_mm=[2.26, 1.04], rmse_random_mm=[9.94, 14.42], phase_lag_shape_s=[0.01234, -0.0004]),
        index=pd.Index(["transformer", "mlp"], name="model"),
    ).assign(input_energy_random=[18.23, 17.96])
    lines = model_summary.table_text(table).split("\n")
    assert lines[2].split() == ["transformer", "2.3", "9.9", "0.012", "18.2"]
    assert lines[3].split() == ["mlp", "1.0", "14.4", "-0.000", "18.0"]


def test_step_window_is_the_window_one_control_step_reads():
    states = np.arange(10 * 6, dtype=float).reshape(10, 6)
    window = model_summary.step_window(states, context=3, step=5)
    assert window.dtype == torch.float32 and window.shape == (1, 4, 6)
    np.testing.assert_array_equal(window[0].numpy(), states[3:7])
    start = model_summary.step_window(states, context=3, step=0)  # before the first sample: x_0 repeated
    np.testing.assert_array_equal(start[0].numpy(), states[[0, 0, 0, 1]])


def test_step_latency_runs_on_one_thread_without_autograd():
    seen = []

    def predict(x, y):
        seen.append((torch.get_num_threads(), torch.is_inference_mode_enabled(), x + y))

    threads = torch.get_num_threads()
    torch.set_num_threads(2)  # a caller with two threads: the timed calls still get one
    try:
        timing = model_summary.step_latency(predict, 1, 2, repeats=5)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(threads)
    assert set(timing) == {"median", "p99"} and 0 <= timing["median"] <= timing["p99"]
    assert len(seen) == 20 + 5  # warm-up calls, then the timed ones
    assert set(seen) == {(1, True, 3)}


@pytest.fixture(scope="module")
def mlp(trained):
    return control.Controller(trained("mlp")[0], "mlp")


def test_evaluate_models_plans_every_reference_of_every_model_in_one_run(monkeypatch, sim, mlp, profile):
    loaded = []

    def load_controller(name, profile_name):
        loaded.append((name, profile_name))
        return control.Controller(mlp.model, name)

    monkeypatch.setattr(control, "load_controller", load_controller)
    references = [shape_reference(sim, "circle", size=0.04), shape_reference(sim, "heart", size=0.04)]
    controllers, results, runs = model_summary.evaluate_models(["a", "b"], profile, references, sim)
    assert loaded == [("a", "summary-test"), ("b", "summary-test")]
    assert list(controllers) == ["a", "b"]
    assert list(zip(results.model, results.reference)) == [
        ("a", "circle"),
        ("a", "heart"),
        ("b", "circle"),
        ("b", "heart"),
    ]
    assert {name: set(run) for name, run in runs.items()} == {"a": {"circle", "heart"}, "b": {"circle", "heart"}}
    alone, _ = control.evaluate(mlp, references, sim)  # the same model alone: the same numbers
    np.testing.assert_allclose(results.rmse_mm.iloc[:2], alone.rmse_mm)
    np.testing.assert_allclose(results.rmse_mm.iloc[2:], alone.rmse_mm)


def test_planning_latency_has_one_row_per_model(sim, mlp):
    states = shape_reference(sim, "circle", size=0.04).states
    latency = model_summary.planning_latency({"mlp": mlp}, states, step_repeats=5, plan_repeats=2)
    assert list(latency.index) == ["mlp"]
    assert list(latency.columns) == ["step_median_ms", "step_p99_ms", "trajectory_ms", "trajectory_steps"]
    row = latency.loc["mlp"]
    assert row.trajectory_steps == len(states) - 1
    # times, not their order against each other: a loaded machine can hold up one step longer than a plan
    assert 0 < row.step_median_ms <= row.step_p99_ms and row.trajectory_ms > 0


def grid_input(steps=20):
    """The four shown references on a short line, one model that follows each exactly."""
    states = np.zeros((steps + 1, 6))
    states[:, 1] = np.linspace(0, 0.05, steps + 1)
    u_true = np.ones((steps, 2))
    references = {
        name: Reference(name, "random", states, np.ones(steps + 1, bool), u_true) for name in model_summary.SHOWN
    }
    runs = {"m": {name: dict(states=states, u=u_true) for name in model_summary.SHOWN}}
    return runs, references


def test_tracking_figure_draws_the_shown_references_and_saves_them(profile):
    fig = model_summary.tracking_figure(*grid_input(), profile, "tracking")
    assert [ax.get_title() for ax in fig.axes] == ["circle", "heart", "Rand2", "Rand3"]
    assert (profile.output_dir / "tracking.png").stat().st_size > 0


def test_inputs_figure_draws_both_inputs_per_shown_reference_and_saves_them(profile):
    fig = model_summary.inputs_figure(*grid_input(), profile, "inputs", shown=["heart", "Rand3"])
    assert len(fig.axes) == 4
    assert [ax.get_title() for ax in fig.axes[:2]] == ["heart", "Rand3"]
    assert [ax.get_ylabel() for ax in fig.axes] == ["$u_1$ [N]", "$u_1$ [N]", "$u_2$ [N]", "$u_2$ [N]"]
    assert (profile.output_dir / "inputs.png").stat().st_size > 0
