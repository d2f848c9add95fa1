"""The rig of the loop study (hardware.mocap): a command acts DELAY after it is sent, the camera
holds and loses frames at the shares it is given, and its recordings read back as the loader's."""

import contextlib
import io

import numpy as np
import pytest
from test_recorded_loop import example
from test_recordings import tiny_training

from softflow import cli, recordings
from softflow.hardware import mocap
from softflow.hardware.gap import FRICTION_GAP, TYPICAL_GAP
from softflow.hardware.recorder import motor_columns
from softflow.rod.robots import DT, HW_ROBOT


def test_a_command_acts_the_delay_after_it_is_sent():
    rig = mocap.MocapRig(TYPICAL_GAP, batch=2, noise=0.0, held=0.0, lost=0.0)
    pulled = rig.rest.copy()
    pulled[1, 0] += 3.0  # mm: rig 1 pulls its first motor in, rig 0 holds its rest
    for _ in range(40):
        rig.send(pulled)
    tips = np.stack(rig.states, 1)[..., :3]  # (2, 41, 3)
    delay = int(round(mocap.DELAY / DT))
    np.testing.assert_array_equal(tips[0, : delay + 1], tips[1, : delay + 1])  # nothing moved yet
    assert np.abs(tips[1, -1] - tips[0, -1]).max() > 1e-4  # then rig 1 bends


def test_the_camera_holds_and_loses_the_shares_of_frames_it_is_given():
    rig = mocap.MocapRig(TYPICAL_GAP, batch=4, held=0.2, lost=0.1, seed=3)
    frames = np.stack([rig.read() for _ in range(1500)], 1)  # (4, 1500, 3), the rod at rest
    lost = np.isnan(frames).all(-1)
    held = np.zeros_like(lost)
    for b in range(4):
        seen = np.flatnonzero(~lost[b])
        held[b, seen[1:]] = (frames[b, seen[1:]] == frames[b, seen[:-1]]).all(-1)
    assert lost.mean() == pytest.approx(0.1, abs=0.02) and held.mean() == pytest.approx(0.2, abs=0.03)
    assert np.nanstd(frames[~lost & ~held] - rig.states[0][0, :3], axis=0) == pytest.approx(mocap.NOISE, rel=0.1)


def test_recorded_runs_read_back_with_the_delay_the_rig_has(tmp_path):
    paths = mocap.record_runs(tmp_path, 6, 4.0, TYPICAL_GAP, seed=0)
    data = recordings.load_dataset(paths, inputs=motor_columns(HW_ROBOT), fractions=(0.5, 0.25), data_dir=None)
    assert data.input_columns == tuple(motor_columns(HW_ROBOT)) and data.dt == pytest.approx(DT)
    # the actuator's 20 periods plus the motors' and the rod's own lag; never less than the delay
    assert round(mocap.DELAY / DT) <= data.delay_steps <= round(mocap.DELAY / DT) + 5
    assert mocap.record_runs(tmp_path, 6, 4.0, TYPICAL_GAP, seed=0) == paths  # present: kept, not redone


def test_the_example_runs_the_exported_loop_on_the_twin_behind_the_rigs_faults(tmp_path, monkeypatch):
    """examples/run_loop.py, numpy and onnxruntime alone, on the loop study's rig: the graph of an
    MLP trained (ci budget shrunk) on the rig's own recordings by the CLI."""
    runs = tmp_path / "runs"
    mocap.record_runs(runs, 6, 4.0, TYPICAL_GAP, seed=0)
    tiny_training(monkeypatch, tmp_path / "checkpoints")
    options = ["--recordings", str(runs), "--profile", "ci", "--inputs", ",".join(motor_columns(HW_ROBOT))]
    options += ["--delay", f"{mocap.DELAY}", "--fractions", "0.5,0.25"]
    with contextlib.redirect_stdout(io.StringIO()):
        cli.main(["train", "mlp", *options])
        cli.main(["export", "mlp", *options, "--loop", "--onnx", str(tmp_path / "loop.onnx")])
    runner = example()
    graph = runner.LoopGraph(tmp_path / "loop.onnx")
    assert graph.meta["input_units"] == ["mm", "mm", "mm"]
    reference = recordings.read(runs / "run0005.csv", inputs=motor_columns(HW_ROBOT), delay=mocap.DELAY).states
    rig = mocap.MocapRig(FRICTION_GAP, seed=1)
    u, holding, late = runner.run(graph, rig, reference[:150], paced=False)
    low, high, rate = (np.array(graph.meta[k]) for k in ("input_low", "input_high", "input_rate"))
    assert u.shape == (149, 3) and late == 0
    assert ((u >= low - 1e-4) & (u <= high + 1e-4)).all() and (np.abs(np.diff(u, axis=0)) <= rate + 1e-4).all()
    assert holding.mean() < 0.1 and np.isfinite(np.stack(rig.states)).all()
