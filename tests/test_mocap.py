"""The rig of the loop study (hardware.mocap): a command acts DELAY after it is sent, the camera
holds and loses frames at the shares it is given, and its recordings read back as the loader's."""

import numpy as np
import pytest

from softflow import recordings
from softflow.hardware import mocap
from softflow.hardware.gap import TYPICAL_GAP
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
