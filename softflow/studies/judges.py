"""Referees of a real robot that never saw what they score: the tip's path over a window
predicted from the inputs sent, by a model fitted on other runs.

A judge predicts the tip at step t of a window that starts at step s, anchored at the recorded
tip there: p_t = p_s + g(h_t) - g(h_s). The history h_t holds the inputs paired with the steps
before t (each step paired with the input sent the rig's delay before it), every ``LAG`` periods
over ``HISTORY`` s: before the window the recorded inputs, inside it the planner's. So the judged
error of the recorded inputs is the judge's own error (its floor), and a planner's inputs move
the judged tip only through g. Two kinds of g, neither a class that any planner trains or uses:

- ``ridge``: linear in the history (a finite impulse response of the tip), ridge-regularised;
- ``kernel``: a Gaussian-kernel ridge regression on the same history (random Fourier features,
  ``FEATURES`` of them, bandwidth ``BANDWIDTH`` times the root of the history's size, since the
  distance between two standardised histories grows with it): smooth and nonlinear.

Why this shape: anchoring at the window's start removes the rest-position drift between
recording sessions (5-20 mm on the trunk); predicting from the inputs alone, never from a state
rolled forward, accumulates no error over the window; and neither judge shares a parameter or
a class with the inverse models or RF-FWD's forward surrogate. g is fitted on whole runs, each
run's mean tip removed (its session's offset).

Cross-fitting: ``fit_judges`` fits the judge that scores run R on the other runs it is given
(``Judge.fitted_on``); ``provenance`` lists them, and a scored run is never among its judge's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

KINDS = ("ridge", "kernel")
HISTORY = 1.0  # s of inputs a judge sees before each step
LAG = 5  # periods between the inputs of a history
RIDGE = 1e-4  # penalty on a judge's weights, per sample (the history standardised)
FEATURES = 2000  # kernel: random Fourier features
BANDWIDTH = 2.0  # kernel: times the root of the history's size


@dataclass(frozen=True)
class Judge:
    """g for one kind, fitted on the runs ``fitted_on`` (names), for the run ``scores``."""

    kind: str
    scores: str
    fitted_on: tuple[str, ...]
    lags: np.ndarray  # (L,) periods before the step
    mean: np.ndarray  # (L * m,) of the histories it was fitted on
    scale: np.ndarray  # (L * m,)
    weights: np.ndarray  # (L * m, 3) ridge; (FEATURES, 3) kernel
    frequencies: np.ndarray | None = None  # kernel: (L * m, FEATURES)
    phases: np.ndarray | None = None  # kernel: (FEATURES,)

    def features(self, histories: np.ndarray) -> np.ndarray:
        """(N, L * m) histories -> what the weights multiply: standardised, or their Fourier features."""
        z = (histories - self.mean) / self.scale
        if self.kind == "ridge":
            return z
        return np.sqrt(2 / FEATURES) * np.cos(z @ self.frequencies + self.phases)

    def g(self, histories: np.ndarray) -> np.ndarray:
        """(N, L * m) histories -> (N, 3) tip, up to a constant (m)."""
        return self.features(histories) @ self.weights


def settings() -> dict:
    """The constants a fitted judge depends on: part of the key of what it scores."""
    return dict(kinds=KINDS, history=HISTORY, lag=LAG, ridge=RIDGE, features=FEATURES, bandwidth=BANDWIDTH)


def as_arrays(judge: Judge) -> dict[str, np.ndarray]:
    """A judge's fitted arrays, to be cached (``from_arrays`` reads them back)."""
    empty = np.zeros(0)
    arrays = dict(lags=judge.lags, mean=judge.mean, scale=judge.scale, weights=judge.weights)
    return arrays | dict(
        frequencies=empty if judge.frequencies is None else judge.frequencies,
        phases=empty if judge.phases is None else judge.phases,
    )


def from_arrays(kind: str, scores: str, fitted_on: tuple[str, ...], arrays) -> Judge:
    """The judge ``as_arrays`` gave ``arrays`` of."""
    fourier = kind == "kernel"
    return Judge(
        kind,
        scores,
        tuple(fitted_on),
        arrays["lags"],
        arrays["mean"],
        arrays["scale"],
        arrays["weights"],
        arrays["frequencies"] if fourier else None,
        arrays["phases"] if fourier else None,
    )


def lags(period: float) -> np.ndarray:
    """The history's lags in periods: 1, 1 + LAG, ... up to HISTORY s (1: the input paired with
    the step just before)."""
    return 1 + np.arange(0, int(round(HISTORY / period)), LAG)


def histories(u: np.ndarray, lag: np.ndarray) -> np.ndarray:
    """u (T, m) -> (T+1, L * m): row t holds u[t - lag] for each lag (u[0] before the start)."""
    index = np.clip(np.arange(len(u) + 1)[:, None] - lag[None, :], 0, len(u) - 1)  # (T+1, L)
    return u[index].reshape(len(u) + 1, -1)


def fit(kind: str, runs: dict[str, tuple[np.ndarray, np.ndarray]], scores: str, period: float) -> Judge:
    """The judge of ``kind`` for run ``scores``, fitted on ``runs`` ({name: (u (T, m), tip (T+1, 3))},
    ``scores`` never among them)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
    if scores in runs or not runs:
        raise ValueError(f"a judge of {scores!r} is fitted on other runs; got {sorted(runs)}")
    lag = lags(period)
    h = [histories(u, lag) for u, _ in runs.values()]
    mean, scale = np.concatenate(h).mean(0), np.concatenate(h).std(0) + 1e-9
    judge = Judge(kind, scores, tuple(runs), lag, mean, scale, np.zeros(0))
    if kind == "kernel":
        rng = np.random.default_rng(0)
        width = BANDWIDTH * np.sqrt(len(mean))
        judge = replace(
            judge,
            frequencies=rng.standard_normal((len(mean), FEATURES)) / width,
            phases=rng.uniform(0, 2 * np.pi, FEATURES),
        )
    # each run's mean removed from its features and its tip: a session's offset is no input's effect
    X = np.concatenate([(f := judge.features(x)) - f.mean(0) for x in h])  # (N, F)
    Y = np.concatenate([tip - tip.mean(0) for _, tip in runs.values()])  # (N, 3)
    weights = np.linalg.solve(X.T @ X + RIDGE * len(X) * np.eye(X.shape[1]), X.T @ Y)
    return replace(judge, weights=weights)


def fit_judges(runs: dict[str, tuple[np.ndarray, np.ndarray]], scored, period: float) -> dict:
    """{(kind, scored run): Judge} for every kind and each run in ``scored``, each fitted on the
    other runs of ``runs``."""
    return {
        (kind, name): fit(kind, {other: run for other, run in runs.items() if other != name}, name, period)
        for kind in KINDS
        for name in scored
    }


def provenance(judges: dict) -> list[dict]:
    """One row per judge and run it was fitted on: what ``judges.csv`` lists for a reader."""
    return [
        dict(judge=judge.kind, scores=judge.scores, fitted_on=name)
        for judge in judges.values()
        for name in judge.fitted_on
    ]


def window_starts(steps: int, length: int, every: int) -> np.ndarray:
    """The first step of each window of ``length`` steps, ``every`` steps apart, within ``steps``."""
    return np.arange(0, steps - length + 1, every)


def judged_errors(judge: Judge, u: np.ndarray, tip: np.ndarray, plan: np.ndarray, length: int, every: int):
    """The judged tip error (mm, RMS over the window) of ``plan`` (T, m) on a run of recorded
    inputs ``u`` (T, m) and tip (T+1, 3), for windows of ``length`` steps starting every ``every``:
    (W,). The plan's inputs replace the recorded ones from each window's start on."""
    errors = []
    for s in window_starts(len(u), length, every):
        sent = np.concatenate([u[:s], plan[s : s + length]])  # (s + length, m)
        h = histories(sent, judge.lags)[s:]  # (length + 1, L * m): steps s .. s + length
        g = judge.g(h)
        predicted = tip[s] + g[1:] - g[0]  # (length, 3)
        errors.append(1e3 * np.sqrt(np.mean(np.sum((predicted - tip[s + 1 : s + 1 + length]) ** 2, -1))))
    return np.array(errors)


# ---------------------------------------------------------------------------- the resolution curve
DELAYS = (1, 2, 5, 10)  # periods
NOISE = (1.0, 2.0, 5.0)  # RMS of the smooth noise added, in the inputs' units (degrees on the trunk)
SCALES = (0.9, 1.1)
SMOOTHING = 20  # periods: the noise's moving average


def perturbations() -> list[str]:
    """The known changes of the recorded inputs a judge must see, in order of size per kind."""
    return [f"delay {k}" for k in DELAYS] + [f"noise {s:g}" for s in NOISE] + [f"scale {a:g}" for a in SCALES]


def perturbed(u: np.ndarray, name: str, seed: int = 0) -> np.ndarray:
    """The recorded inputs (T, m) changed by ``name`` (``perturbations``): sent ``k`` periods late,
    plus noise smoothed over SMOOTHING periods with the given RMS per input, or scaled."""
    kind, _, size = name.partition(" ")
    if kind == "delay":
        return u[np.maximum(np.arange(len(u)) - int(size), 0)]
    if kind == "noise":
        white = np.random.default_rng(seed).standard_normal((len(u) + SMOOTHING - 1, u.shape[1]))
        smooth = np.stack([np.convolve(w, np.ones(SMOOTHING) / SMOOTHING, "valid") for w in white.T], 1)
        return u + float(size) * smooth / np.sqrt(np.mean(smooth**2, 0))
    if kind == "scale":
        return float(size) * u
    raise ValueError(f"perturbation must be one of {perturbations()}; got {name!r}")
