"""A rig's input-to-motion delay through training and planning, and the observed points a user
chooses: a model of delayed recordings plans inputs already advanced by the delay (row k is sent
at period k), from a desired path given as positions in a CSV, on the command line as in Python."""

import contextlib
import io

import numpy as np
import pandas as pd
import pytest
from test_recordings import delayed_rod_run, tiny_training

from softflow import cli, control, recordings
from softflow.control.planning import advance

DELAY = 6  # periods of 10 ms


def test_advance_moves_each_row_earlier_and_holds_the_last():
    u = np.arange(10.0)[:, None] * [1.0, -1.0]  # (T=10, 2): row t is "the input for step t"
    moved = advance(u, 3)
    np.testing.assert_array_equal(moved[:, 0], [3, 4, 5, 6, 7, 8, 9, 9, 9, 9])
    np.testing.assert_array_equal(advance(u[None], 3)[0], moved)  # batched the same
    assert advance(u, 0) is u


@pytest.fixture(scope="module")
def delayed(tmp_path_factory):
    """Three runs of the rod whose inputs act 60 ms after they are sent, an MLP trained on them by
    the CLI with the delay given (ci profile shrunk to TINY; nothing in data/), and a desired path
    (the first run's tip, positions only, filmed at 50 Hz). Returns (folder, path, trained_in)."""
    runs = tmp_path_factory.mktemp("delayed")
    for seed in range(3):
        delayed_rod_run(runs / f"run{seed}.csv", DELAY, seed=20 + seed, seconds=6.0)
    frame = pd.read_csv(runs / "run0.csv").iloc[::2]
    path = tmp_path_factory.mktemp("path") / "desired.csv"
    frame[["time_s", "x_m", "y_m", "z_m"]].to_csv(path, index=False)
    trained_in = tmp_path_factory.mktemp("checkpoints")
    with pytest.MonkeyPatch.context() as patch:
        tiny_training(patch, trained_in)
        with contextlib.redirect_stdout(io.StringIO()) as out:
            cli.main(
                ["train", "mlp", "--recordings", str(runs), "--profile", "ci", "--delay", "0.06"]
                + ["--fractions", "0.34,0.34"]
            )
    assert "delay 6 periods (0.06 s, given)" in out.getvalue()
    return runs, path, trained_in


@pytest.fixture
def with_models(delayed, monkeypatch):
    tiny_training(monkeypatch, delayed[2])
    return delayed


def test_a_plan_comes_advanced_by_the_delay_the_model_was_trained_with(with_models, tmp_path):
    runs, path, _ = with_models
    data = recordings.load_dataset(runs, delay=0.06, fractions=(0.34, 0.34))
    controller = control.load_controller("mlp", "ci", recordings=data)
    assert controller.delay_steps == DELAY and controller.tip_columns == ("x_m", "y_m", "z_m")
    states = recordings.read_path(path, tip=["x_m", "y_m", "z_m"], dt=data.dt)  # (T+1, 6)
    controller.workspace_margin = None
    with pytest.warns(control.SaturationWarning):  # a tiny budget overshoots at a few steps
        planned = controller.plan(states)  # (T, 2)
        stepped = controller.step(states[:-1], states[1:])  # (T, 2): the input for each step, not advanced
    T = len(planned)
    np.testing.assert_allclose(planned[: T - DELAY], stepped[DELAY:], atol=1e-5)  # sent DELAY periods early
    np.testing.assert_allclose(planned[T - DELAY :], np.repeat(stepped[-1:], DELAY, 0), atol=1e-5)

    out = tmp_path / "u.csv"
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        cli.main(
            ["plan", "mlp", "--profile", "ci", "--recordings", str(runs), "--delay", "0.06"]
            + ["--fractions", "0.34,0.34", "--reference", str(path), "--out", str(out)]
        )
    assert printed.getvalue().strip().splitlines()[-1] == str(out)
    written = pd.read_csv(out)
    assert list(written.columns) == ["time_s", "u1", "u2"] and len(written) == T
    np.testing.assert_allclose(written[["u1", "u2"]].to_numpy(), planned, atol=2e-6)  # written to 1e-6


def test_velocities_of_a_desired_path_come_from_its_positions(tmp_path):
    t = np.arange(0, 3.0, 1 / 30)  # a 30 fps path of positions only
    pd.DataFrame({"time_s": t, "y_m": 0.05 * np.sin(2 * np.pi * t), "z_m": 0.05 * np.cos(2 * np.pi * t)}).to_csv(
        tmp_path / "circle.csv", index=False
    )
    states = recordings.read_path(tmp_path / "circle.csv", tip=["y_m", "z_m"], dt=0.01)  # (T+1, 4)
    grid = np.arange(len(states)) * 0.01
    assert len(states) == 297  # 0 to 2.967 s on a 10 ms grid
    inside = slice(20, -20)  # the smoother's ends see one side only
    np.testing.assert_allclose(states[inside, 0], 0.05 * np.sin(2 * np.pi * grid[inside]), atol=1e-4)
    np.testing.assert_allclose(states[inside, 2], 0.1 * np.pi * np.cos(2 * np.pi * grid[inside]), atol=5e-3)
    with pytest.raises(ValueError, match="looks like milliseconds"):
        pd.DataFrame({"time_s": 1e3 * t, "y_m": t, "z_m": t}).to_csv(tmp_path / "ms.csv", index=False)
        recordings.read_path(tmp_path / "ms.csv", tip=["y_m", "z_m"], dt=0.01)


def test_a_model_of_every_point_asked_for_the_tip_alone_names_what_it_needs(with_models):
    runs, _, _ = with_models
    data = recordings.load_dataset(runs, delay=0.06, fractions=(0.34, 0.34))
    controller = control.load_controller("mlp", "ci", recordings=data)
    with pytest.raises(ValueError, match=r"trained on the observed columns x_m, y_m, z_m: .* needs 6 .* got 4.*--tip"):
        controller.plan(np.zeros((10, 4)))


def test_command_line_errors_name_the_flags_not_the_keywords(tmp_path, capsys):
    for i in range(2):
        delayed_rod_run(tmp_path / f"run{i}.csv", 0, seed=i, seconds=2.0)
    with pytest.raises(SystemExit) as exit_:
        cli.main(["train", "mlp", "--recordings", str(tmp_path), "--profile", "ci", "--delay", "0"])
    message = capsys.readouterr().err
    assert exit_.value.code == 2 and "record at least three" in message and "usage:" not in message
    assert cli.in_flags("or pass other fractions (e.g. (1/3, 1/3) for three)") == (
        "or pass --fractions (e.g. --fractions 0.34,0.34 for three)"
    )
    assert cli.in_flags("name them with tip=[...]; pass delay= (s)") == "name them with --tip COLS; pass --delay (s)"
    with pytest.raises(SystemExit):
        cli.main(["plan", "mlp", "--profile", "ci", "--reference", "p.csv", "--out", str(tmp_path / "u.csv")])
    assert "give both" in capsys.readouterr().err
