"""Metrics of the paper's tables: tracking RMSE, phase lag, input energy, actuation MAE, latency."""

from __future__ import annotations

import math
import numbers
import time

import numpy as np
import pandas as pd

from softflow.checks import as_real_array


def _positions(states, name: str) -> tuple[np.ndarray, int]:
    """States (T+1, d), tip positions then their velocities, and the number of positions d/2."""
    states, _ = as_real_array(states, name, (None, None))
    if states.shape[1] % 2:
        raise ValueError(f"{name} must hold tip positions and their velocities (an even width); got {states.shape}")
    return states, states.shape[1] // 2


def tracking_rmse(achieved, reference, mask=None, axes=None) -> float:
    """RMSE (m) of the tip-position error over the masked samples: sqrt(mean ||p - p*||^2), over
    every position coordinate by default (3-D for the paper's rods); ``axes=(1, 2)`` gives the y-z
    (tip-plane) error of the paper's burst test."""
    achieved, n_positions = _positions(achieved, "achieved")
    reference, _ = as_real_array(reference, "reference", achieved.shape)
    mask = _scored(mask, len(achieved))
    axes = list(range(n_positions) if axes is None else axes)
    if not set(axes) <= set(range(n_positions)) or not axes:
        raise ValueError(
            f"axes must be a non-empty subset of the position axes {tuple(range(n_positions))}; got {axes}"
        )
    error = achieved[mask][:, axes] - reference[mask][:, axes]
    return float(np.sqrt(np.mean(np.sum(error**2, axis=1))))


def peak_speed(states, mask=None) -> float:
    """Largest tip speed ||v|| (m/s) over the masked samples of a (T+1, d) trajectory."""
    states, n_positions = _positions(states, "states")
    return float(np.linalg.norm(states[_scored(mask, len(states)), n_positions:], axis=1).max())


def _scored(mask, n: int) -> np.ndarray:
    """The samples a metric scores: all n by default, else a boolean (n,) mask with one True at least."""
    mask = np.ones(n, bool) if mask is None else np.asarray(mask, bool)
    if mask.shape != (n,) or not mask.any():
        raise ValueError(f"mask must be a boolean array of shape ({n},) with at least one True")
    return mask


def _check_dt(dt) -> None:
    """A sample period must be a finite number of seconds above 0: a negative one turns an
    energy negative and leaves phase_lag no shift to search."""
    if not (isinstance(dt, numbers.Real) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite sample period > 0 s; got {dt!r}")


def phase_lag(achieved, reference, dt: float, max_lag: float = 0.5) -> float:
    """Delay (s) of ``achieved`` behind ``reference`` (both (T,) or (T, D)).

    The shift k that best aligns them over a fixed window, minimising
    mean ||a_t - r_{t-k}||^2 = const - 2 xcorr(k) + energy(k): the cross-correlation
    with the window-energy term that would otherwise bias a finite record. Refined to
    sub-sample precision by a parabola through the three shifts around the minimum."""
    _check_dt(dt)
    a, r = np.atleast_2d(np.asarray(achieved, float).T).T, np.atleast_2d(np.asarray(reference, float).T).T
    if a.shape != r.shape:
        raise ValueError(f"achieved and reference must have the same shape; got {a.shape} and {r.shape}")
    n = len(a)
    K = int(np.ceil(max_lag / dt))
    if n < 2 * K + 3:
        raise ValueError(f"signals must be longer than 2 max_lag / dt + 3 = {2 * K + 3} samples; got {n}")
    window = np.arange(K, n - K)
    lags = np.arange(-K, K + 1)
    misfit = np.array([np.mean(np.sum((a[window] - r[window - k]) ** 2, axis=1)) for k in lags])
    i = int(np.argmin(misfit))
    offset = 0.0
    if 0 < i < len(lags) - 1:
        left, centre, right = misfit[i - 1], misfit[i], misfit[i + 1]
        curvature = left - 2 * centre + right
        offset = 0.5 * (left - right) / curvature if curvature > 0 else 0.0
    return float((lags[i] + offset) * dt)


def fitting_lag(n: int, dt: float, max_lag: float = 0.5) -> float:
    """The ``max_lag`` to give ``phase_lag`` for ``n`` samples: ``max_lag``, or less on a signal
    too short for it (a shape run fast). Half a sample below a whole number of samples, so
    phase_lag's ceil(max_lag / dt) lands on it whatever the rounding."""
    _check_dt(dt)
    shifts = min(int(np.ceil(max_lag / dt)), (n - 3) // 2)
    return (shifts - 0.5) * dt


def input_energy(u, dt: float) -> float:
    """E_u = sum_t ||u_t||^2 dt (N^2 s)."""
    _check_dt(dt)
    u, _ = as_real_array(u, "u", (None, None))
    return float(np.sum(u**2) * dt)


def actuation_mae(u, u_true) -> np.ndarray:
    """Mean absolute error of each actuation channel: (m,)."""
    u, _ = as_real_array(u, "u", (None, None))
    u_true, _ = as_real_array(u_true, "u_true", u.shape)
    return np.abs(u - u_true).mean(0)


def latency(fn, *args, repeats: int = 1000, warmup: int = 20) -> dict:
    """Wall time of fn(*args): median and p99 over ``repeats`` calls (s)."""
    for _ in range(warmup):
        fn(*args)
    times = np.empty(repeats)
    for k in range(repeats):
        start = time.perf_counter()
        fn(*args)
        times[k] = time.perf_counter() - start
    return {"median": float(np.median(times)), "p99": float(np.quantile(times, 0.99))}


def table_rows(results: pd.DataFrame) -> pd.DataFrame:
    """Per model: Table I (RMSE mean over shapes / random) and Table II (phase lag on shapes,
    input energy on random references)."""
    shapes, random = results[results.family == "shape"], results[results.family == "random"]
    return pd.DataFrame(
        {
            "rmse_shape_mm": shapes.groupby("model").rmse_mm.mean(),
            "rmse_random_mm": random.groupby("model").rmse_mm.mean(),
            "phase_lag_shape_s": shapes.groupby("model").phase_lag_s.mean(),
            "input_energy_random": random.groupby("model").input_energy.mean(),
        }
    )
