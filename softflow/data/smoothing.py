"""Offline tip positions and velocities from recorded frames: a Rauch-Tung-Striebel smoother
over a constant-acceleration Kalman model per axis (state p, v, a; white jerk), whose two
levels (frame noise, jerk density) are fitted to each axis's frames by maximum likelihood.

Why not Savitzky-Golay: recorded frames come at their own jittered times, at a camera rate
unlike the command rate, with frames lost. The Kalman model takes each frame at the time it
was taken and answers at any query time, and the backward pass uses the frames on both sides;
a Savitzky-Golay filter needs uniform samples (so resampling, i.e. made-up frames, first) and
a window length that has no scale of its own. Fitting the two levels gives every robot,
fast or slow, large or small, its own bandwidth without a knob.
"""

from __future__ import annotations

import math

import numpy as np

from softflow.checks import as_real_array

NOISE_GRID = np.logspace(-6, -1, 11)  # m: candidate frame noise (1 um .. 10 cm), half-decade steps
JERK_GRID = np.logspace(-4, 6, 21)  # m/s^3/sqrt(Hz): candidate white-jerk densities, half-decade steps
PRIOR_SPEED, PRIOR_ACCELERATION = 1.0, 100.0  # m/s, m/s^2: spread of the state at the first frame
MIN_FIT_FRAMES = 10  # frames needed to fit the two levels (the first three only fix p, v, a)
TIME_TOLERANCE = 1e-6  # s: how far a query may lie outside the frames (rounding of a grid, not extrapolation)


def transition(h) -> tuple[np.ndarray, np.ndarray]:
    """F (..., 3, 3) and Q (..., 3, 3) of the constant-acceleration model over steps of h (...) s;
    Q is for a unit white-jerk density (scale it by the density squared)."""
    h = np.asarray(h, float)[..., None, None]
    one, zero = np.ones_like(h), np.zeros_like(h)
    F = np.block([[one, h, h * h / 2], [zero, one, h], [zero, zero, one]])
    Q = np.block([[h**5 / 20, h**4 / 8, h**3 / 6], [h**4 / 8, h**3 / 3, h**2 / 2], [h**3 / 6, h**2 / 2, h]])
    return F, Q


def _filter(times, values, noise, jerk, *, keep: bool = False):
    """Kalman filter of B models (noise, jerk: (B,)) over one axis's timeline (N,) starting at
    a frame; NaN values are times without a frame (predicted only). Returns the log-likelihood
    of the frames after the third (B,) and, with ``keep``, the predicted and filtered means and
    covariances, each (N, B, 3[, 3])."""
    B, N = len(noise), len(times)
    x = np.zeros((B, 3))  # p, v, a
    x[:, 0] = values[0]
    P = np.zeros((B, 3, 3))
    P[:, 0, 0], P[:, 1, 1], P[:, 2, 2] = noise**2, PRIOR_SPEED**2, PRIOR_ACCELERATION**2
    stored = [np.empty((N, B, 3)), np.empty((N, B, 3, 3)), np.empty((N, B, 3)), np.empty((N, B, 3, 3))] if keep else []
    loglik, frames = np.zeros(B), 1
    steps, unit_noise = transition(np.diff(times))  # (N-1, 3, 3) each
    for n in range(N):
        if n:
            F = steps[n - 1]
            x, P = x @ F.T, F @ P @ F.T + jerk[:, None, None] ** 2 * unit_noise[n - 1]
        if keep:
            stored[0][n], stored[1][n] = x, P
        if n and math.isfinite(values[n]):
            S = P[:, 0, 0] + noise**2  # innovation variance, H = [1, 0, 0]
            innovation = values[n] - x[:, 0]
            if frames >= 3:
                loglik -= 0.5 * (np.log(2 * np.pi * S) + innovation**2 / S)
            frames += 1
            gain = P[:, :, 0] / S[:, None]  # (B, 3)
            x = x + gain * innovation[:, None]
            P = P - gain[:, :, None] * P[:, None, 0, :]
            P = (P + P.transpose(0, 2, 1)) / 2
        if keep:
            stored[2][n], stored[3][n] = x, P
    return loglik, stored


def check_levels(noise, jerk) -> None:
    """The smoother's levels are positive numbers, or None to fit them."""
    for name, level in (("noise", noise), ("jerk", jerk)):
        if level is not None and not (isinstance(level, (int, float)) and math.isfinite(level) and level > 0):
            raise ValueError(f"{name} must be a positive number or None (fitted); got {level!r}")


def _fit_levels(times, values, *, noise: float | None = None, jerk: float | None = None) -> tuple[float, float]:
    """The (frame noise, jerk density) of the grids that make one axis's frames (N,) at times
    (N,) most likely; a given level is kept and only the other fitted."""
    noises = NOISE_GRID if noise is None else np.array([noise], float)
    jerks = JERK_GRID if jerk is None else np.array([jerk], float)
    if (noise is None or jerk is None) and len(times) < MIN_FIT_FRAMES:
        raise ValueError(
            f"fitting the smoother needs {MIN_FIT_FRAMES} frames; got {len(times)} (or give noise and jerk)"
        )
    grid_noise, grid_jerk = (a.ravel() for a in np.meshgrid(noises, jerks, indexing="ij"))
    loglik, _ = _filter(times, values, grid_noise, grid_jerk)
    best = int(np.argmax(loglik))
    return float(grid_noise[best]), float(grid_jerk[best])


def smooth(times, values, query, *, noise: float | None = None, jerk: float | None = None, causal: bool = False):
    """Position and velocity (Q,) each at the query times (Q,) from one axis's frames: values
    (N,) taken at nondecreasing times (N,), all finite. Queries must lie between the first and
    the last frame: the smoother bridges gaps, it does not extrapolate. ``causal``: the filter's
    estimate from the frames up to each query alone (what a control loop can know then; the
    loop's ``control.loop.Estimator``), not the smoother's from every frame. Returns (positions,
    velocities, noise, jerk), the last two the levels used (fitted when not given)."""
    times, _ = as_real_array(times, "times", (None,))
    values, _ = as_real_array(values, "values", (len(times),))
    query, _ = as_real_array(query, "query", (None,))
    if len(times) < 2 or np.any(np.diff(times) < 0):
        raise ValueError(f"need at least two frames at nondecreasing times; got times {times[:5]}...")
    if len(query) and (query.min() < times[0] - TIME_TOLERANCE or query.max() > times[-1] + TIME_TOLERANCE):
        raise ValueError(
            f"query times must lie within the frames' [{times[0]}, {times[-1]}] s; got [{query.min()}, {query.max()}]"
        )
    check_levels(noise, jerk)
    noise, jerk = _fit_levels(times, values, noise=noise, jerk=jerk)
    query = np.clip(query, times[0], times[-1])  # the timeline starts at a frame

    merged_times = np.concatenate([times, query])
    order = np.argsort(merged_times, kind="stable")  # a frame before a query at the same time
    merged_times = merged_times[order]
    merged_values = np.concatenate([values, np.full(len(query), np.nan)])[order]
    _, (x_pred, P_pred, x_filt, P_filt) = _filter(
        merged_times, merged_values, np.array([noise]), np.array([jerk]), keep=True
    )
    if causal:
        at_query = x_filt[:, 0][np.argsort(order, kind="stable")[len(times) :]]  # (Q, 3)
        return at_query[:, 0], at_query[:, 1], noise, jerk
    F, _ = transition(np.diff(merged_times))  # (M-1, 3, 3)
    gains = np.linalg.solve(P_pred[1:, 0], F @ P_filt[:-1, 0]).transpose(0, 2, 1)  # P_filt F^T P_pred^-1
    smoothed = np.empty((len(merged_times), 3))  # the RTS backward pass, means only
    smoothed[-1] = x_filt[-1, 0]
    for n in range(len(merged_times) - 2, -1, -1):
        smoothed[n] = x_filt[n, 0] + gains[n] @ (smoothed[n + 1] - x_pred[n + 1, 0])
    at_query = smoothed[np.argsort(order, kind="stable")[len(times) :]]  # (Q, 3)
    return at_query[:, 0], at_query[:, 1], noise, jerk
