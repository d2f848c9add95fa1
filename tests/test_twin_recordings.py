"""The twin records like a rig: runs written in the recordings format, read back by
``recordings.load_dataset``, the tip as the camera saw the plant's, resumable, and a model
trains on them."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_recordings import TINY

from softflow import recordings, store, training
from softflow.data.excitation import polynomial_excitation
from softflow.hardware import FRICTION_GAP, CablePlant, cable_commands, recorder
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT

SECONDS = 3.0
COLUMNS = ["time_s", "u1_N", "u2_N", "l1_mm", "l2_mm", "l3_mm", "x_m", "y_m", "z_m"]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Three runs of 3 s of the vertical twin across FRICTION_GAP: (folder, paths, their bytes)."""
    folder = tmp_path_factory.mktemp("twin_runs")
    paths = recorder.record_runs(folder, 3, SECONDS, gravity="vertical", progress=False)
    return folder, paths, [path.read_bytes() for path in paths]


def test_runs_are_files_of_the_recordings_format(recorded):
    folder, paths, _ = recorded
    assert [path.name for path in paths] == ["run0000.csv", "run0001.csv", "run0002.csv"]
    assert sorted(p.name for p in folder.iterdir()) == ["recorder.json", *[path.name for path in paths]]
    table = pd.read_csv(paths[0])
    assert list(table.columns) == COLUMNS
    assert (np.diff(table.time_s) >= 0).all()
    sent = table.dropna(subset=["u1_N"])
    seen = table.dropna(subset=["x_m"])
    assert sent[["y_m"]].isna().all().all() and seen[["u1_N", "l1_mm"]].isna().all().all()  # rows of one kind
    np.testing.assert_allclose(np.diff(sent.time_s), DT, atol=1e-9)  # commands at 100 Hz
    np.testing.assert_allclose(np.diff(seen.time_s), 1 / 30, atol=2e-6)  # frames at 30 fps (stamps in us)
    assert len(sent) == 300 and len(seen) == 91  # frames at 0, 1/30, ..., 3 s


def test_load_dataset_reads_them_on_the_command_period(recorded):
    folder = recorded[0]
    data = recordings.load_dataset(folder, delay=0.0, fractions=(1 / 3, 1 / 3), data_dir=None)
    assert data.dt == pytest.approx(DT)
    assert data.u.shape == (3, 300, 2) and data.states.shape == (3, 301, 6)  # u by default, a 3-D tip
    motors = recordings.load_dataset(
        folder, inputs=recorder.motor_columns(HW_ROBOT), fractions=(1 / 3, 1 / 3), data_dir=None
    )
    d = motors.delay_steps  # estimated: the plant's motor lag and the camera, a few periods
    assert motors.u.shape == (3, 300 - d, 3) and d == round(np.median(motors.delays) / DT) and 0 <= d <= 10
    assert sorted(np.concatenate([data.train, data.val, data.test])) == [0, 1, 2]


def test_the_recorded_tip_is_the_plants_within_the_cameras_noise(recorded):
    """Run 1 made again from its documented recipe: the polynomial draw of (seed, run), its
    commands through the model rod, the plant's replay. The file holds the same u and commands
    (to its printed digits) and the camera's tip within a fraction of a millimetre of the true
    tip at the frame times."""
    table = pd.read_csv(recorded[1][1])
    model = Simulator(HW_ROBOT, "vertical")
    u = polynomial_excitation(1, 300, np.random.default_rng([0, 1]))
    commands = cable_commands(u, model)
    sent = table.dropna(subset=["u1_N"])
    np.testing.assert_allclose(sent[["u1_N", "u2_N"]], u[0], atol=5e-7)
    np.testing.assert_allclose(sent[["l1_mm", "l2_mm", "l3_mm"]], 1e3 * commands[0], atol=5e-7)
    true = CablePlant(HW_ROBOT, "vertical", FRICTION_GAP).replay(commands)["states"][0, :, :3]  # (301, 3)
    seen = table.dropna(subset=["x_m"])
    expected = np.stack([np.interp(seen.time_s, np.arange(301) * DT, true[:, k]) for k in range(3)], -1)
    error = seen[["x_m", "y_m", "z_m"]].to_numpy() - expected  # (K, 3) m
    assert np.ptp(true[:, 1:], axis=0).max() > 0.02  # the tip really moves
    assert np.sqrt(np.mean(np.sum(error**2, 1))) < 0.3e-3  # the camera's noise: ~0.1 mm at 0.4 m
    assert np.abs(error).max() < 1e-3


def test_an_interrupted_recording_resumes_to_the_same_files(recorded, monkeypatch):
    folder, paths, contents = recorded
    stamps = [path.stat().st_mtime_ns for path in paths]
    paths[1].unlink()

    def interrupted(path, text):  # the write dies half way, as a killed process would
        with store.atomic_write(path, "w") as f:
            f.write(text[: len(text) // 2])
            raise KeyboardInterrupt

    monkeypatch.setattr(recorder, "write_text", interrupted)
    with pytest.raises(KeyboardInterrupt):
        recorder.record_runs(folder, 3, SECONDS, gravity="vertical", progress=False)
    assert not paths[1].exists()  # never half a file under the run's name
    assert not [p for p in folder.iterdir() if p.name.endswith(".tmp")]
    monkeypatch.undo()
    again = recorder.record_runs(folder, 3, SECONDS, gravity="vertical", progress=False)
    assert again == paths
    assert [path.read_bytes() for path in paths] == contents  # the recreated run is the same run
    assert [paths[0].stat().st_mtime_ns, paths[2].stat().st_mtime_ns] == [stamps[0], stamps[2]]  # kept, not rewritten


def test_two_processes_record_the_files_one_process_records(tmp_path):
    """Runs 0-8 span two chunks of simulation: shared between two processes, the same bytes."""
    one = recorder.record_runs(tmp_path / "one", 9, 0.2, gravity="vertical", progress=False)
    two = recorder.record_runs(tmp_path / "two", 9, 0.2, gravity="vertical", workers=2, progress=False)
    assert [path.name for path in two] == [path.name for path in one]
    assert [path.read_bytes() for path in two] == [path.read_bytes() for path in one]


def test_runs_of_other_settings_are_not_mixed_into_a_folder(recorded, tmp_path):
    folder = recorded[0]
    with pytest.raises(ValueError, match=r"other settings \(seconds differ"):
        recorder.record_runs(folder, 3, 4.0, gravity="vertical", progress=False)
    with pytest.raises(ValueError, match="gravity"):
        recorder.record_runs(folder, 3, SECONDS, gravity="horizontal", progress=False)
    (tmp_path / "mine.csv").write_text("time_s,u1\n0,1\n")
    with pytest.raises(ValueError, match=r"holds CSV files but no recorder\.json"):
        recorder.record_runs(tmp_path, 1, SECONDS, gravity="vertical", progress=False)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(n_runs=0), "n_runs must be a whole number of runs >= 1"),
        (dict(seconds=0.05), "seconds must be a run length of at least 0.1 s"),
        (dict(dropped=1.0), r"dropped must be a share of frames in \[0, 1\)"),
        (dict(latency=-0.01), "latency must be a time >= 0 s"),
        (dict(gap="typical"), "gap must be a RealityGap"),
        (dict(workers=0), "workers must be a whole number of processes >= 1"),
    ],
)
def test_bad_settings_say_what_was_expected(kwargs, message, tmp_path):
    arguments = dict(n_runs=1, seconds=SECONDS, gravity="vertical", progress=False) | kwargs
    with pytest.raises(ValueError, match=message):
        recorder.record_runs(tmp_path, **arguments)
    assert not any(tmp_path.iterdir())  # nothing written


def test_an_mlp_trains_on_the_twins_recordings(recorded, tmp_path):
    data = recordings.load_dataset(recorded[0], fractions=(1 / 3, 1 / 3), data_dir=None)
    model, checkpoint = training.train("mlp", data, TINY, tmp_path / "mlp.pt", progress=False)
    assert Path(tmp_path / "mlp.pt").is_file() and checkpoint["data_key"] == data.key
    assert np.isfinite(checkpoint["best_val"]) and checkpoint["epochs_run"] == TINY.epochs
    assert checkpoint["recorded"]["dt"] == pytest.approx(DT)
    assert all(np.isfinite(p.detach().numpy()).all() for p in model.parameters())
