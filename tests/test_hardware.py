"""Hardware twin: commands through the model, the cable-driven plant, files in and out."""

import dataclasses

import numpy as np
import pytest

from softflow import hardware
from softflow.data.excitation import sum_of_sines_excitation
from softflow.data.references import Reference
from softflow.hardware import vision
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT


@pytest.fixture(scope="module", params=["vertical", "horizontal"])
def sim(request):
    return Simulator(HW_ROBOT, request.param)


@pytest.fixture(scope="module")
def u():
    return sum_of_sines_excitation(2, 200, 7, u_max=3.5, frequencies=(0.2, 1.5))


def test_replaying_the_commands_without_a_gap_reproduces_the_tension_driven_motion(sim, u):
    expected = sim.rollout(u)
    replayed = hardware.CablePlant(HW_ROBOT, sim.gravity).replay(hardware.cable_commands(u, sim))
    error = np.linalg.norm(replayed["states"][..., :3] - expected[..., :3], axis=-1)
    assert np.ptp(expected[..., 1:3]) > 0.05  # the rod really moves
    assert error.max() < 0.5e-3
    assert replayed["tensions"].min() > 0  # the pretension keeps every cable taut


def test_the_reality_gap_moves_the_plant_and_every_term_counts(sim, u):
    expected = sim.rollout(u)
    commands = hardware.cable_commands(u, sim)
    for term, value in [("youngs_modulus", -0.15), ("motor_lag", 0.03), ("slack", 5e-4)]:
        gap = dataclasses.replace(hardware.NO_GAP, **{term: value})
        replayed = hardware.CablePlant(HW_ROBOT, sim.gravity, gap).replay(commands)
        assert np.abs(replayed["states"][..., :3] - expected[..., :3]).max() > 1e-3, term


def test_gap_terms_scale_the_plant_and_are_checked():
    gap = hardware.RealityGap(youngs_modulus=-0.1, damping=0.2, density=0.1)
    robot = gap.plant_robot(HW_ROBOT)
    assert robot.youngs_modulus == pytest.approx(0.9 * HW_ROBOT.youngs_modulus)
    assert robot.damping == pytest.approx(1.2 * HW_ROBOT.damping)
    assert gap.doubled("density").density == pytest.approx(0.2)
    with pytest.raises(ValueError, match="term"):
        gap.doubled("gravity")
    with pytest.raises(ValueError, match="motor_lag"):
        hardware.RealityGap(motor_lag=-0.01)
    with pytest.raises(ValueError, match="relative"):
        hardware.RealityGap(youngs_modulus=-1.0)


def test_command_files_round_trip_and_bad_files_are_named(tmp_path):
    commands = np.random.default_rng(0).uniform(-5e-3, 5e-3, (50, 3))
    path = tmp_path / "circle.csv"
    hardware.write_commands(path, commands)
    assert path.read_text().splitlines()[0] == "time_s,l1_mm,l2_mm,l3_mm"
    np.testing.assert_allclose(hardware.read_commands(path), commands, atol=1e-7)  # 0.1 um in the file
    path.write_text("not,a\ncommand file\n")
    with pytest.raises(ValueError, match="circle.csv"):
        hardware.read_commands(path)
    with pytest.raises(ValueError, match="no such file"):
        hardware.read_commands(tmp_path / "missing.csv")


def test_tracked_rmse_of_a_hand_worked_case():
    states = np.zeros((101, 6))
    states[:, 1] = np.linspace(0, 0.1, 101)
    reference = Reference("line", "shape", states, np.arange(101) >= 20)
    frame_times = np.arange(0, 1.0001, 0.1)
    tracked = np.interp(frame_times, np.arange(101) * DT, states[:, 1])[:, None] * [0, 1, 0] + [0, 0, 0.002]
    tracked[-1] = np.nan  # a frame without the marker is skipped
    assert hardware.tracked_rmse(frame_times, tracked, reference) == pytest.approx(0.002)


def test_recordings_load_from_a_marker_csv_and_from_rgbd_frames(tmp_path):
    sim = Simulator(HW_ROBOT, "vertical")
    q = sim.static_q(np.stack([np.linspace(0, 3, 12), np.linspace(0, -2, 12)], -1))
    tips = sim.tip_positions(q)
    times = np.arange(12) / 30
    hardware.write_marker_csv(tmp_path / "run.csv", times, tips)
    loaded_times, positions = hardware.load_recording(tmp_path / "run.csv")
    np.testing.assert_allclose(loaded_times, times, atol=1e-6)  # microsecond timestamps
    np.testing.assert_allclose(positions, tips, atol=1e-6)

    camera = hardware.twin_camera(sim, hardware.TYPICAL_GAP)
    centerlines, _ = sim.centerline(q)
    vision.write_rgbd(
        tmp_path / "run.npz", times, vision.render(tips, camera, 0, centerlines=centerlines, rod_diameter=0.004), camera
    )
    _, tracked = hardware.load_recording(tmp_path / "run.npz")
    assert np.sqrt(np.mean(np.sum((tracked - tips) ** 2, axis=1))) < 1e-3


MARKER_HEADER = "time_s,x_m,y_m,z_m\n"


@pytest.mark.parametrize(
    "rows, message",
    [
        ("0.0,0.4,0,0\n0.033,inf,0,0\n", r"bad\.csv: data row 2, column 'x_m': 'inf' is not a finite number"),
        ("0.0,0.4,0,0\ninf,0.4,0,0\n", r"bad\.csv: data row 2, column 'time_s': 'inf' is not a finite number"),
        ("0.0,0.4,0,0\n0.033,0.4,abc,0\n", r"bad\.csv: data row 2, column 'y_m': 'abc' is not a finite number"),
        ("0.0,0.4,0,0\n0.033,0.4,,0\n", r"bad\.csv: data row 2, column 'y_m': 'nan' is not a finite number"),
        (
            "0.0,0.4,0,0\n0.066,0.4,0,0\n0.033,0.4,0,0\n",
            r"bad\.csv: time_s must increase strictly; data row 3 \(0\.033\) does not follow row 2 \(0\.066\)",
        ),
        ("0.0,0.4,0,0\n0.033,0.4,0,0\n0.033,0.4,0,0\n", r"data row 3 \(0\.033\) does not follow row 2 \(0\.033\)"),
        ("", r"bad\.csv: has a header but no samples"),
    ],
)
def test_a_bad_marker_recording_names_the_file_and_the_row(tmp_path, rows, message):
    path = tmp_path / "bad.csv"
    path.write_text(MARKER_HEADER + rows)
    with pytest.raises(ValueError, match=message):
        hardware.load_recording(path)


def test_a_missing_recording_or_a_directory_is_a_value_error_in_both_formats(tmp_path):
    for name in ("missing.csv", "missing.npz"):
        with pytest.raises(ValueError, match=f"no such file: .*{name}"):
            hardware.load_recording(tmp_path / name)
    with pytest.raises(ValueError, match="is a directory; expected a recording"):
        hardware.load_recording(tmp_path)


def test_command_files_need_increasing_time(tmp_path):
    path = tmp_path / "commands.csv"
    path.write_text("time_s,l1_mm,l2_mm,l3_mm\n0.00,1,2,3\n0.00,1,2,3\n")
    with pytest.raises(ValueError, match="time_s must increase strictly; data row 2"):
        hardware.read_commands(path)


def test_sag_calibration_recovers_the_plants_rho_over_e():
    """A plant with E -15 % and rho +10 %: statics see only rho / E, so the calibrated rod's
    E is nominal x 0.85 / 1.10 and its rest tip matches the plant's."""
    plant = hardware.TYPICAL_GAP.plant_robot(HW_ROBOT)
    rest_tip = Simulator(plant, gravity="horizontal").static_tip(np.zeros((1, 2)))[0]
    calibrated = hardware.calibrate_sag(HW_ROBOT, rest_tip, gravity="horizontal")
    assert calibrated.youngs_modulus / HW_ROBOT.youngs_modulus == pytest.approx(0.85 / 1.10, rel=1e-4)
    tip = Simulator(calibrated, gravity="horizontal").static_tip(np.zeros((1, 2)))[0]
    assert np.linalg.norm(tip - rest_tip) < 1e-4  # within 0.1 mm
    with pytest.raises(ValueError, match="metres"):
        hardware.calibrate_sag(HW_ROBOT, 1e3 * rest_tip, gravity="horizontal")  # millimetres by mistake


def test_step_commands_equal_the_command_file_of_the_same_plan():
    sim = Simulator(HW_ROBOT, "vertical")
    u = np.random.default_rng(3).uniform(-2, 2, (1, 30, 2))
    stepper = hardware.StepCommands(sim)
    np.testing.assert_allclose(np.array([stepper(u_t) for u_t in u[0]]), hardware.cable_commands(u, sim)[0], atol=1e-12)


def test_twin_rig_delivers_frames_late_and_loses_the_share_it_is_told():
    sim = Simulator(HW_ROBOT, "vertical")
    rig = hardware.TwinRig(sim, latency=0.066, dropped=0.5, seed=1)
    received = []
    for step in range(1, 61):
        rig.command(np.zeros(2))
        arrived = rig.measure()
        assert all(step * DT - taken >= 0.066 - 1e-9 for taken, _ in arrived)
        received += arrived
    taken = [t for t, _ in received]
    in_flight = [t for t in rig.frame_times if t + 0.066 > 60 * DT + 1e-9]
    assert taken == sorted(taken) and len(in_flight) == 3 and len(received) == len(rig.frame_times) - len(in_flight)
    lost = sum(np.isnan(p).any() for _, p in received)
    assert 0.25 < lost / len(received) < 0.75
    rest = sim.tip_positions(sim.rest_q()[None])[0]
    seen = np.array([p for _, p in received if np.isfinite(p).all()])
    assert np.abs(seen - rest).max() < 2e-3  # the unactuated rod stays at rest, seen within the camera's error
    with pytest.raises(ValueError, match="dropped"):
        hardware.TwinRig(sim, dropped=1.0)
