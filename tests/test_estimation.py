"""The tip estimator on synthetic camera tracks with a known truth: exact on the motion its
model assumes, below the camera's noise on a circle, latency compensated by prediction, lost
frames bridged."""

import math

import numpy as np
import pytest

from softflow.checks import as_real_array
from softflow.control.estimation import TipEstimator

FPS, DT = 30.0, 0.01


def estimate_track(frame_times, positions, times, latency: float = 0.0, **options) -> np.ndarray:
    """What the loop would have estimated at each of ``times`` (s), (N, 6): frames taken at
    ``frame_times`` (K,) with positions (K, 3) (NaN rows lost), each usable ``latency`` s after
    it was taken. The loop calls ``TipEstimator`` itself; this replays it offline."""
    frame_times, _ = as_real_array(frame_times, "frame_times", (None,))
    positions = np.asarray(positions, float)
    if positions.shape != (len(frame_times), 3):
        raise ValueError(f"positions must have shape ({len(frame_times)}, 3); got {positions.shape}")
    times, _ = as_real_array(times, "times", (None,))
    if not (math.isfinite(latency) and latency >= 0):
        raise ValueError(f"latency must be a non-negative number of seconds; got {latency!r}")
    first = np.flatnonzero(np.isfinite(positions).all(1))
    if not len(first):
        raise ValueError("no frame found the marker")
    estimator = TipEstimator(positions[first[0]], **options)
    out, k = np.empty((len(times), 6)), 0
    for i, t in enumerate(times):
        while k < len(frame_times) and frame_times[k] + latency <= t + 1e-12:
            estimator.update(frame_times[k], positions[k])
            k += 1
        out[i] = estimator.state(max(t, estimator.t if estimator.t is not None else t))
    return out


def circle(t, radius=0.05, speed=0.15):
    w = speed / radius
    p = np.stack([0.4 + 0 * t, radius * np.cos(w * t), radius * np.sin(w * t)], -1)
    v = np.stack([0 * t, -radius * w * np.sin(w * t), radius * w * np.cos(w * t)], -1)
    return np.concatenate([p, v], -1)


def camera(truth_at, seconds, noise, rng, drop=0.0):
    frame_times = np.arange(0, seconds, 1 / FPS)
    seen = (
        truth_at(frame_times)[:, :3] + rng.normal(0, noise, (len(frame_times), 3))
        if noise
        else truth_at(frame_times)[:, :3]
    )
    seen[rng.random(len(frame_times)) < drop] = np.nan
    return frame_times, seen


def errors(estimate, truth, settle=0.5):
    keep = np.arange(len(truth)) * DT >= settle
    return (np.sqrt(np.mean(np.sum((estimate[keep, k] - truth[keep, k]) ** 2, 1))) for k in (slice(0, 3), slice(3, 6)))


def test_constant_acceleration_is_tracked_exactly_through_latency():
    def truth_at(t):
        a, v0 = np.array([0.2, -0.1, 0.3]), np.array([0.05, 0.1, 0.0])
        return np.concatenate([np.outer(t, v0) + 0.5 * np.outer(t**2, a), v0 + np.outer(t, a)], -1)

    frame_times, seen = camera(truth_at, 3.0, 0.0, np.random.default_rng(0))
    times = np.arange(0, 3.0, DT)
    estimate = estimate_track(frame_times, seen, times, latency=0.066, frame_noise=1e-6)
    position, velocity = errors(estimate, truth_at(times), settle=1.0)
    assert position < 1e-6 and velocity < 1e-5


def test_noise_latency_and_lost_frames_on_a_circle():
    times = np.arange(0, 4.0, DT)
    truth = circle(times)
    rng = np.random.default_rng(1)
    frame_times, seen = camera(circle, 4.0, 1e-3, rng)
    position, velocity = errors(estimate_track(frame_times, seen, times, latency=0.0), truth)
    assert position < np.sqrt(3) * 1e-3 and velocity < 0.25 * 0.15  # below the camera's 3D noise

    late = estimate_track(frame_times, seen, times, latency=0.066)
    held = np.array([seen[max(np.searchsorted(frame_times, t - 0.066, side="right") - 1, 0)] for t in times])
    compensated, _ = errors(late, truth)
    uncompensated = np.sqrt(np.mean(np.sum((held - truth[:, :3])[times >= 0.5] ** 2, 1)))
    assert compensated < uncompensated / 2  # 66 ms at 0.15 m/s is 10 mm behind; prediction recovers most

    frame_times, dropped = camera(circle, 4.0, 1e-3, np.random.default_rng(1), drop=0.1)
    with_drops, _ = errors(estimate_track(frame_times, dropped, times, latency=0.066), truth)
    assert with_drops < 1.5 * compensated

    gap = seen.copy()
    gap[60:63] = np.nan  # 0.1 s without the marker: the tip moves 15 mm meanwhile
    bridged = estimate_track(frame_times, gap, times)
    inside = (times >= frame_times[60]) & (times < frame_times[63])
    held = np.linalg.norm(seen[59] - truth[inside, :3], axis=1).max()
    assert np.linalg.norm(bridged[inside, :3] - truth[inside, :3], axis=1).max() < held / 2


def test_estimator_counts_frames_and_refuses_bad_input():
    estimator = TipEstimator([0.4, 0.0, 0.0])
    estimator.update(0.0, [0.4, 0.0, 0.0])
    estimator.update(1 / FPS, [np.nan] * 3)
    assert (estimator.frames, estimator.lost) == (2, 1)
    with pytest.raises(ValueError, match="order"):
        estimator.update(0.0, [0.4, 0.0, 0.0])
    with pytest.raises(ValueError, match="before the last frame"):
        estimator.state(0.0)
    with pytest.raises(ValueError, match="shape"):
        estimator.update(1.0, [0.4, 0.0])
    with pytest.raises(ValueError, match="positive"):
        TipEstimator([0.4, 0.0, 0.0], jerk=0.0)
    with pytest.raises(ValueError, match="no frame"):
        estimate_track([0.0, 0.1], np.full((2, 3), np.nan), [0.0])
