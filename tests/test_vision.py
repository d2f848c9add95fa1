"""Synthetic RGB-D camera, red-marker tracking, stroboscope and recordings."""

import types

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from softflow.hardware.vision import Camera, camera_facing, observe, read_rgbd, render, stroboscope, track, write_rgbd

TIP = np.array([0.45, 0.0, 0.0])  # m, undeformed tip of the hardware rod


def circle(times, radius=0.1, period=2.5):
    """Tip on a circle in the y-z plane with some motion along x (depth): (T, 3)."""
    phase = 2 * np.pi * times / period
    return TIP + np.column_stack([0.02 * np.sin(2 * phase), radius * np.cos(phase), radius * np.sin(phase)])


def rod(tips, n_points=20):
    """A bent rod from the base to each tip: (T, P, 3)."""
    s = np.linspace(0, 1, n_points)[:, None]
    return s * tips[:, None] * [1.0, 0.0, 0.0] + s**2 * tips[:, None] * [0.0, 1.0, 1.0]


def test_project_deproject_round_trip():
    rng = np.random.default_rng(0)
    camera = Camera(rotation=Rotation.random(random_state=1).as_matrix(), position=(0.1, -0.2, 0.3))
    points = camera.C + rng.uniform(0.2, 1.0, (100, 1)) * (camera.R[2] + rng.uniform(-0.4, 0.4, (100, 3)) @ camera.R)
    pixels, depth = camera.project(points)
    assert np.all(depth > 0)
    np.testing.assert_allclose(camera.deproject(pixels, depth), points, atol=1e-9)


def test_camera_facing_sees_the_target_at_the_principal_point():
    camera = camera_facing(TIP, distance=0.4)
    pixels, depth = camera.project([TIP, TIP + [0.0, 0.1, 0.0], TIP + [0.0, 0.0, 0.1]])
    np.testing.assert_allclose(pixels[0], [camera.cx, camera.cy], atol=1e-9)
    np.testing.assert_allclose(depth, 0.4, atol=1e-12)
    assert pixels[1, 0] > camera.cx and pixels[2, 1] < camera.cy  # +y to the right, +z up


def test_tracks_a_moving_marker_within_a_millimetre():
    """Simulation at 100 Hz, filmed at 30 fps with default noise, the rod in view."""
    times = np.arange(0, 2.5 + 1e-9, 0.01)
    camera = camera_facing(TIP)
    frame_times, tracked = observe(
        times, circle(times), camera, np.random.default_rng(0), centerlines=rod(circle(times)), rod_diameter=0.004
    )
    np.testing.assert_allclose(frame_times, np.arange(76) / 30, atol=1e-12)
    error = tracked - circle(frame_times)  # linear resampling of the 100 Hz circle is exact to 0.01 mm
    assert np.sqrt(np.mean(np.sum(error**2, 1))) < 1e-3  # m, 3-D RMSE
    assert np.sqrt(np.mean(np.sum(error[:, 1:] ** 2, 1))) < 0.3e-3  # m, image plane (y-z): about 0.15 px


def test_frames_without_a_whole_marker_give_nan_rows():
    camera = camera_facing(TIP)
    positions = TIP + [
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.205, 0.0],
        [0.6, 0.0, 0.0],
    ]  # seen, out of view, cut by the border, behind the camera
    frames = render(positions, camera, 0)
    assert isinstance(frames, types.GeneratorType)
    tracked = track(frames, camera)
    assert np.all(np.isfinite(tracked[0])) and np.all(np.isnan(tracked[1:]))
    np.testing.assert_allclose(tracked[0], TIP, atol=1e-3)


def test_stroboscope_shows_several_poses():
    camera = camera_facing(TIP)
    times = np.arange(60) / camera.fps
    colors = (
        color for color, _ in render(circle(times), camera, 0, centerlines=rod(circle(times)), rod_diameter=0.004)
    )
    picture = stroboscope(colors, every=12)
    assert picture.shape == (camera.height, camera.width, 3) and picture.dtype == np.uint8
    hsv = cv2.cvtColor(picture, cv2.COLOR_BGR2HSV)
    red = cv2.inRange(hsv, (0, 90, 40), (10, 255, 255)) | cv2.inRange(hsv, (170, 90, 40), (179, 255, 255))
    assert cv2.connectedComponents(red)[0] - 1 == 5  # frames 0, 12, 24, 36, 48 of one 2.5 s turn


def test_recording_round_trip(tmp_path):
    camera = camera_facing(TIP, depth_noise=0.002)
    times = np.arange(4) / camera.fps
    frames = list(render(circle(times), camera, 0))
    path = tmp_path / "run.npz"
    write_rgbd(path, times, iter(frames), camera)
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz"]  # no temp file left
    read_times, read_frames, read_camera = read_rgbd(path)
    assert read_camera == camera and len(read_frames) == 4
    np.testing.assert_array_equal(read_times, times)
    for _ in range(2):  # the frames can be read more than once
        for (color, depth), (read_color, read_depth) in zip(frames, read_frames, strict=True):
            assert read_color.dtype == np.uint8 and read_depth.dtype == np.uint16
            np.testing.assert_array_equal(read_color, color)
            np.testing.assert_array_equal(read_depth, depth)


@pytest.mark.parametrize("damage", ["truncated", "garbage", "missing key"])
def test_damaged_recording_is_reported_by_path(tmp_path, damage):
    camera = camera_facing(TIP)
    path = tmp_path / "run.npz"
    write_rgbd(path, [0.0], render([TIP], camera, 0), camera)
    data = path.read_bytes()
    if damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(b"not a recording" * 100)
    else:
        np.savez(path, times=[0.0])
    with pytest.raises(ValueError, match="run.npz"):
        read_rgbd(path)


def test_bad_input_is_rejected(tmp_path):
    camera = camera_facing(TIP)
    with pytest.raises(ValueError, match="rotation"):
        Camera(rotation=[[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], position=(0, 0, 0))
    with pytest.raises(ValueError, match="width"):
        camera_facing(TIP, width=0)
    with pytest.raises(ValueError, match="shape"):
        render(np.zeros((5, 2)), camera, 0)
    with pytest.raises(ValueError, match="shape"):
        camera.deproject(np.zeros((3, 2)), np.ones(2))
    with pytest.raises(ValueError, match="frame 0: depth"):
        track([(np.zeros((480, 640, 3), np.uint8), np.zeros((480, 640), np.float32))], camera)
    with pytest.raises(ValueError, match="increasing"):
        observe([0.0, 0.0, 1.0], np.zeros((3, 3)), camera, 0)
    with pytest.raises(ValueError, match="every"):
        stroboscope([np.zeros((4, 4, 3), np.uint8)], every=0)
    with pytest.raises(ValueError, match="number"):
        write_rgbd(tmp_path / "run.npz", [0.0, 1.0], render([TIP], camera, 0), camera)
    assert not list(tmp_path.iterdir())  # nothing written
