"""How many-valued is an inverse? The spread of u given the condition (x_t, x_t+1), measured
on data. A regression returns the conditional mean, so it loses exactly this spread; a flow
can only beat it where the spread is large against the regression's other errors.

Estimator: half the mean squared difference of u between each point and its nearest
neighbour in the standardised condition space (the nearest-neighbour form of the von
Neumann difference estimator). For a deterministic, smooth u it tends to zero as the data
get denser; at a finite density it is not zero, so every estimate comes with the same
estimator's value on a deterministic control: u replaced by its least-squares linear fit on
the condition (one u per condition by construction). A spread is meaningful only well above
that floor.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .checks import as_real_array


@dataclass(frozen=True)
class Spread:
    spread: float  # RMS spread of u given the condition (units of u), all channels together
    floor: float  # the estimator on the deterministic control: spreads near it mean "none measurable"
    points: int  # how many (condition, u) pairs it rests on


def conditional_spread(condition, u, *, max_points: int = 200_000, seed: int = 0) -> Spread:
    """RMS spread of ``u`` (N, m) given ``condition`` (N, d), and its deterministic floor."""
    condition, _ = as_real_array(condition, "condition", (None, None))
    u, _ = as_real_array(u, "u", (len(condition), None))
    if len(condition) < 3:
        raise ValueError(f"need at least 3 (condition, u) pairs; got {len(condition)}")
    if len(condition) > max_points:
        keep = np.random.default_rng(seed).choice(len(condition), max_points, replace=False)
        condition, u = condition[keep], u[keep]
    std = condition.std(0)
    scaled = (condition - condition.mean(0)) / np.where(std > 0, std, 1.0)
    _, index = cKDTree(scaled).query(scaled, k=2)
    neighbour = index[:, 1]  # the nearest other point
    design = np.column_stack([scaled, np.ones(len(scaled))])
    linear = design @ np.linalg.lstsq(design, u, rcond=None)[0]

    def estimate(values):
        return float(np.sqrt(np.mean(np.sum((values - values[neighbour]) ** 2, axis=1)) / 2))

    return Spread(estimate(u), estimate(linear), len(condition))


def transition_spread(states, u, episodes, **options) -> Spread:
    """The spread of u_t given (x_t, x_t+1) over the transitions of ``episodes`` of a dataset
    (states (E, T+1, 6), u (E, T, 2))."""
    states, u = np.asarray(states)[episodes], np.asarray(u)[episodes]
    condition = np.concatenate([states[:, :-1], states[:, 1:]], -1).reshape(-1, 12)
    return conditional_spread(condition, u.reshape(-1, u.shape[-1]), **options)
