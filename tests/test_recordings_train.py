"""Training on recorded runs and planning with no simulator: `softflow train MODEL --recordings
DIR` writes a checkpoint keyed by the recordings, `load_controller` finds it (or loads it by path)
and plans a held-out recording in its own inputs, clipped to the range the recordings took."""

import contextlib
import functools
import io
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_recordings import TINY, point_mass_run

from softflow import cli, control, recordings
from softflow.control import planning
from softflow.models import checkpoints
from softflow.models.specs import build_model
from softflow.profiles import PROFILES


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Twelve recordings of a 3-input, 2-D-tip point mass and one held out; mlp and rf-fwd trained
    on them by the CLI with the ci profile shrunk to TINY, into a test folder (nothing in data/).
    Returns (folder, the held-out run, {model: stdout lines}, the Dataset, the checkpoints' root)."""
    runs, rng = tmp_path_factory.mktemp("runs"), np.random.default_rng(3)
    for i in range(12):
        point_mass_run(runs / f"run{i:02d}.csv", rng, 3, 2, 3.0)
    held_out = tmp_path_factory.mktemp("held_out") / "run.csv"
    point_mass_run(held_out, rng, 3, 2, 3.0)
    load = functools.partial(recordings.load_dataset, data_dir=None)
    outputs = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(PROFILES, "ci", replace(PROFILES["ci"], train=TINY))
        patch.setattr(checkpoints, "TRAINED", tmp_path_factory.mktemp("checkpoints"))
        trained_in = checkpoints.TRAINED
        patch.setattr(recordings, "load_dataset", load)
        for model in ("mlp", "rf-fwd"):
            with contextlib.redirect_stdout(io.StringIO()) as out:
                cli.main(["train", model, "--recordings", str(runs), "--profile", "ci"])
            outputs[model] = out.getvalue().strip().splitlines()
    data = load(runs)
    return runs, recordings.read(held_out, dt=data.dt), outputs, data, trained_in


@pytest.fixture
def ci_recordings(trained, monkeypatch):
    """``load_controller`` finds the models of ``trained``: the same budget, no cache in data/."""
    monkeypatch.setitem(PROFILES, "ci", replace(PROFILES["ci"], train=TINY))
    monkeypatch.setattr(planning, "load_recordings", functools.partial(recordings.load_dataset, data_dir=None))
    monkeypatch.setattr(checkpoints, "TRAINED", trained[4])
    return trained


def check_plan(controller, run, data):
    """The held-out run planned: (T, m), within the range the recordings took."""
    with warnings.catch_warnings():  # a tiny budget saturates some steps
        warnings.simplefilter("ignore", control.SaturationWarning)
        u = controller.plan(run.states)
    assert u.shape == run.inputs.shape and np.isfinite(u).all()
    assert np.abs(u).max() <= np.abs(data.u).max()
    assert controller.robot is None and controller.u_limit == np.abs(data.u).max()
    return u


def test_train_prints_the_checkpoint_last_in_a_folder_of_the_recordings(trained):
    _, _, outputs, data, _ = trained
    for model, lines in outputs.items():
        path = Path(lines[-1])
        assert path.is_file() and path.name == f"{model}.pt" and path.parent.name == data.key
        recorded = checkpoints.load_checkpoint(path)["recorded"]
        assert recorded["dt"] == data.dt == pytest.approx(0.01)
        np.testing.assert_array_equal(recorded["u_max"], data.u.max((0, 1)))
    assert outputs["mlp"][0].startswith(f"{data.key}: ")
    said = {"trains on": "train", "validates on": "val", "tests on": "test"}
    assert outputs["mlp"][1:4] == [f"{words}: {', '.join(data.split_files[split])}" for words, split in said.items()]


@pytest.mark.parametrize("model", ["mlp", "rf-fwd"])
def test_the_model_of_the_recordings_plans_a_held_out_run(ci_recordings, model):
    runs, run, outputs, data, _ = ci_recordings
    found = control.load_controller(model, "ci", recordings=runs)
    by_path = control.load_controller(outputs[model][-1])
    np.testing.assert_array_equal(check_plan(found, run, data), check_plan(by_path, run, data))
    if model == "rf-fwd":  # its surrogate was trained on the same recordings, beside it
        assert checkpoints.load_checkpoint(Path(outputs[model][-1]).with_name("forward.pt"))["data_key"] == data.key


def test_a_model_not_trained_on_the_recordings_names_the_command(ci_recordings):
    runs = ci_recordings[0]
    with pytest.raises(ValueError, match=f"train it with: python -m softflow train lstm --recordings {runs} --profile"):
        control.load_controller("lstm", "ci", recordings=runs)


def test_the_profile_is_part_of_a_models_name_for_every_verb(ci_recordings, capsys, tmp_path):
    """A model trained with the ci budget is not the quick profile's: plan asks for that one."""
    runs = ci_recordings[0]
    assert control.find_trained("mlp", "ci", recordings=ci_recordings[3])[0] is not None
    argv = ["plan", "mlp", "--recordings", str(runs), "--profile", "quick"]
    with pytest.raises(SystemExit) as stop:
        cli.main([*argv, "--reference", str(tmp_path / "path.csv"), "--out", str(tmp_path / "u.csv")])
    expected = f"train it with: softflow train mlp --profile quick --recordings {runs}"
    assert stop.value.code == 2 and expected in capsys.readouterr().err


def test_a_checkpoint_loaded_by_path_against_other_recordings_is_refused(trained):
    runs, _, outputs, data, _ = trained
    path = outputs["mlp"][-1]
    assert control.load_controller(path, recordings=data).name == "mlp"  # the recordings it was trained on
    other = recordings.load_dataset(runs, fractions=(0.5, 0.25), data_dir=None)  # another split: another Dataset
    with pytest.raises(ValueError, match="was trained on other data"):
        control.load_controller(path, recordings=other)


def test_the_cli_names_the_whole_train_command_of_a_missing_model_of_recordings(ci_recordings, capsys, tmp_path):
    """Typed as asked, the command trains exactly the model plan looks for: --tip, --fractions and
    the other options that make its Dataset are part of it."""
    runs = ci_recordings[0]
    argv = ["plan", "lstm", "--recordings", str(runs), "--profile", "ci", "--tip", "x_m,y_m", "--fractions", "0.5,0.25"]
    with pytest.raises(SystemExit) as stop:
        cli.main([*argv, "--reference", str(tmp_path / "path.csv"), "--out", str(tmp_path / "u.csv")])
    expected = f"softflow train lstm --profile ci --recordings {runs} --tip x_m,y_m --fractions 0.5,0.25"
    assert stop.value.code == 2 and f"train it with: {expected}" in capsys.readouterr().err


def test_physical_models_need_a_simulated_rods_statics(trained, tmp_path, monkeypatch):
    runs = trained[0]
    monkeypatch.setitem(PROFILES, "ci", replace(PROFILES["ci"], train=TINY))
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path)
    with pytest.raises(SystemExit) as stop, contextlib.redirect_stderr(io.StringIO()) as err:
        cli.main(["train", "rf-physical", "--recordings", str(runs), "--profile", "ci"])
    assert stop.value.code == 2 and "static prior of a simulated rod" in err.getvalue()
    with pytest.raises(ValueError, match="static prior of a simulated rod"):
        control.Controller(build_model("rf-physical", trained[3].dims), "rf-physical", robot=None)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--ship"], "--ship cannot go with --recordings"),
        (["--robot", "hw"], "--robot cannot go with --recordings"),
        (["--gravity", "horizontal"], "--gravity cannot go with --recordings"),
    ],
)
def test_a_simulated_rods_options_are_refused_with_recordings(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["train", "mlp", "--recordings", str(tmp_path), *argv])
    assert stop.value.code == 2 and message in capsys.readouterr().err


def test_recording_options_need_recordings(capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["train", "mlp", "--dt", "0.02"])
    assert stop.value.code == 2 and "--dt describe recordings; they need --recordings DIR" in capsys.readouterr().err


def test_inputs_of_one_sign_are_clipped_per_input_to_the_range_seen(trained):
    """Motor positions from 0 to 30 mm: each input is kept within its own [min, max], with a
    warning, never mirrored to -30 mm as a symmetric limit would."""
    assert planning.recorded_range(dict(u_min=[-1.0, -2.0], u_max=[3.0, 0.5])) == (-3.0, 3.0)
    low, high = planning.recorded_range(dict(u_min=[0.0, 2.0], u_max=[30.0, 28.0]))
    np.testing.assert_array_equal(np.stack([low, high]), [[0.0, 2.0], [30.0, 28.0]])
    _, run, outputs, _, _ = trained
    model = control.load_controller(outputs["mlp"][-1]).model
    free = control.Controller(model, "mlp", robot=None, u_range=(-1e9, 1e9)).plan(run.states)
    low, high = np.quantile(free, 0.3, axis=0), np.quantile(free, 0.7, axis=0)  # (m,) each: clips 60 % of u
    box = control.Controller(model, "mlp", robot=None, u_range=(low, high))
    planned = r"mlp: \d+ of \d+ planned u values exceed the input ranges -?\d"
    with pytest.warns(control.SaturationWarning, match=planned) as caught:
        np.testing.assert_array_equal(box.plan(run.states), np.clip(free, low, high))
    assert caught[0].filename == __file__  # the warning points at the caller of plan
    with pytest.warns(control.SaturationWarning, match="stepped u values exceed the input ranges"):
        stepped = box.step(run.states[:-1], run.states[1:])  # (T, m)
    assert ((stepped >= low) & (stepped <= high)).all()


def test_check_prints_a_line_per_recording_and_fails_where_one_would_be_refused(tmp_path, capsys):
    rng = np.random.default_rng(3)
    for i in range(3):
        point_mass_run(tmp_path / f"run{i}.csv", rng, 2, 2, 2.0)
    cli.main(["check", str(tmp_path), "--no-delay"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:3] == ["file", "rows", "seconds"] and len(lines) == 4
    assert sorted(line.split()[-1] for line in lines[1:]) == ["test", "train", "val"]
    (tmp_path / "broken.csv").write_text("time_s,u1\n0,1\n")
    with pytest.raises(SystemExit) as stop:
        cli.main(["check", str(tmp_path), "--no-delay"])
    assert stop.value.code == 1 and "broken.csv" in capsys.readouterr().out
