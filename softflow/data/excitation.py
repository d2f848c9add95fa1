"""Excitation families: random actuation signals (B, T, m) that drive the rod to make data."""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from softflow.rod.robots import DT, U_MAX


def polynomial_excitation(
    n_episodes: int,
    n_steps: int,
    rng: np.random.Generator,
    degrees=(1, 8),
    amplitudes=(0.5, U_MAX),
    n_inputs: int = 2,
) -> np.ndarray:
    """Training family: one random polynomial per input over the episode, (B, T, m), m = ``n_inputs``
    (a rod's ``n_inputs``: every input its own draw, so a redundant rod's null space is covered too).

    Degree uniform in ``degrees``; Legendre coefficients N(0, 1) so every degree up to
    the highest contributes; the curve is scaled to a peak |u| drawn uniformly from
    ``amplitudes`` (N), so episodes stay inside [-U_MAX, U_MAX] and span small to full bends.
    The draws for two inputs are the ones the paper's datasets were made with.
    """
    t = np.linspace(-1.0, 1.0, n_steps)
    basis = legendre.legvander(t, degrees[1])  # (T, degree + 1)
    degree = rng.integers(degrees[0], degrees[1] + 1, (n_episodes, n_inputs))
    coefficients = rng.normal(size=(n_episodes, n_inputs, degrees[1] + 1))
    coefficients[np.arange(degrees[1] + 1) > degree[..., None]] = 0.0
    curves = coefficients @ basis.T  # (B, m, T)
    peak = rng.uniform(*amplitudes, (n_episodes, n_inputs, 1))
    return (peak * curves / np.abs(curves).max(-1, keepdims=True)).transpose(0, 2, 1)


def sum_of_sines_excitation(
    n_episodes: int, n_steps: int, seed: int, u_max: float = U_MAX, frequencies=(0.1, 1.5), n_inputs: int = 2
) -> np.ndarray:
    """Held-out family: four sines per input with random frequencies (Hz) and phases,
    scaled to peak at u_max, (B, T, m), m = ``n_inputs``. Unlike the polynomial training data."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_steps) * DT
    f = rng.uniform(*frequencies, (n_episodes, n_inputs, 4))
    phases = rng.uniform(0, 2 * np.pi, (n_episodes, n_inputs, 4))
    waves = np.sin(2 * np.pi * f[..., None] * t + phases[..., None]).sum(2)  # (B, m, T)
    return (u_max * waves / np.abs(waves).max(-1, keepdims=True)).transpose(0, 2, 1)


def mixed_excitation(n_episodes: int, n_steps: int, seed: int, u_max: float = 3.5) -> np.ndarray:
    """Complex-3D family (paper Sec. IV-C): a sinusoid, a sigmoid step and a linear ramp per
    cable pair, random in every parameter, scaled to peak at u_max: (B, T, 2). Starts at 0."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_steps) * DT
    duration = n_steps * DT
    shape = (n_episodes, 2, 1)
    sine = rng.uniform(0.5, 1.0, shape) * np.sin(
        2 * np.pi * rng.uniform(0.2, 1.0, shape) * t + rng.uniform(0, 2 * np.pi, shape)
    )
    centre, width = rng.uniform(0.25, 0.75, shape) * duration, rng.uniform(0.1, 0.5, shape)
    sigmoid = rng.uniform(-1, 1, shape) / (1 + np.exp(-(t - centre) / width))
    ramp = rng.uniform(-1, 1, shape) * t / duration
    signal = sine + sigmoid + ramp
    signal -= signal[..., :1]  # from rest, no jump at t = 0
    return (u_max * signal / np.abs(signal).max(-1, keepdims=True)).transpose(0, 2, 1)
