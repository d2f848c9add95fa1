"""Stress tests (Sec. IV-C): where open-loop tracking of a speeding-up circle breaks, and,
beyond the paper, whether a flow's spread over noise draws flags its own tracking error.

The burst circle's period falls with time, so each revolution is a speed level: scoring
revolution by revolution turns one run into a speed sweep.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from softflow.control.metrics import peak_speed, tracking_rmse
from softflow.data.references import Reference
from softflow.rod.robots import DT

BREAK_FRACTION = 0.10  # tracking counts as broken once a revolution's y-z RMSE exceeds 10 % of L


def revolutions(reference: Reference, centre=(0.0, 0.0)) -> np.ndarray:
    """Revolution number (0, 1, ...) of each sample of a circular reference, counted from its
    start point by the unwrapped y-z angle about ``centre``; -1 in the masked-out approach."""
    yz = reference.states[:, 1:3] - np.asarray(centre, float)
    start = int(np.argmax(reference.mask))
    angle = np.unwrap(np.arctan2(yz[start:, 1], yz[start:, 0]))
    turn = np.full(len(yz), -1)
    turn[start:] = np.floor(np.abs(angle - angle[0]) / (2 * np.pi) + 1e-9).astype(int)
    return turn


def burst_summary(reference: Reference, runs: dict, length: float, u_limit: float) -> pd.DataFrame:
    """Per model: achieved and reference peak tip speed (m/s), y-z RMSE (mm and % of L) over the
    whole burst, and the fraction of actuation samples at the actuator limit."""
    rows = []
    for model, run in runs.items():
        rmse = tracking_rmse(run["states"], reference.states, reference.mask, axes=(1, 2))
        rows.append(
            dict(
                model=model,
                peak_speed=peak_speed(run["states"], reference.mask),
                reference_peak_speed=peak_speed(reference.states, reference.mask),
                rmse_yz_mm=1e3 * rmse,
                rmse_pct_L=100 * rmse / length,
                saturated=float(np.mean(np.abs(run["u"]) >= u_limit - 1e-9)),
            )
        )
    return pd.DataFrame(rows).set_index("model")


def burst_breakdown(reference: Reference, runs: dict, length: float, centre=(0.0, 0.0)) -> pd.DataFrame:
    """Per model and complete revolution: its period (s), the reference's peak speed (m/s)
    and the y-z RMSE (mm and % of L) of the open-loop run over that revolution."""
    turn = revolutions(reference, centre)
    rows = []
    for k in range(turn.max()):  # the last, unfinished revolution is left out
        inside = turn == k
        for model, run in runs.items():
            rmse = tracking_rmse(run["states"], reference.states, inside, axes=(1, 2))
            rows.append(
                dict(
                    model=model,
                    revolution=k,
                    t_start=np.argmax(inside) * DT,
                    period_s=inside.sum() * DT,
                    reference_speed=peak_speed(reference.states, inside),
                    rmse_yz_mm=1e3 * rmse,
                    rmse_pct_L=100 * rmse / length,
                )
            )
    return pd.DataFrame(rows)


def break_points(breakdown: pd.DataFrame, fraction: float = BREAK_FRACTION) -> pd.DataFrame:
    """Per model: the first revolution whose RMSE exceeds ``fraction`` of L, with its period and
    speed; NaN where a model never breaks on the reference."""
    rows = []
    for model, runs in breakdown.groupby("model", sort=False):
        broken = runs[runs.rmse_pct_L > 100 * fraction]
        first = broken.iloc[0] if len(broken) else None
        rows.append(
            dict(
                model=model,
                breaks_at_revolution=np.nan if first is None else first.revolution,
                period_s=np.nan if first is None else first.period_s,
                reference_speed=np.nan if first is None else first.reference_speed,
            )
        )
    return pd.DataFrame(rows).set_index("model")


def per_revolution(breakdown: pd.DataFrame, models) -> pd.DataFrame:
    """y-z RMSE (mm) per revolution (rows) and model (columns), and which model is lower on it."""
    table = breakdown.pivot(index=["revolution", "period_s", "reference_speed"], columns="model", values="rmse_yz_mm")[
        list(models)
    ]
    return table.assign(lower=table.idxmin(axis=1))


def actuation_spread(samples: np.ndarray) -> np.ndarray:
    """Per-step spread (N) of plans drawn with different noise, (n, T, 2) -> (T,): the norm of
    the per-channel standard deviation over the draws."""
    samples = np.asarray(samples, float)
    if samples.ndim != 3 or samples.shape[-1] != 2 or len(samples) < 2:
        raise ValueError(f"samples must have shape (n >= 2, T, 2); got {samples.shape}")
    return np.linalg.norm(samples.std(0), axis=-1)


def spread_vs_error(spread: pd.Series, error: pd.Series) -> dict:
    """Does a larger spread go with a larger tracking error? Spearman and Pearson correlation
    over references (both indexed by reference name)."""
    spread, error = spread.align(error, join="inner")
    if len(spread) < 3:
        raise ValueError(f"need at least 3 references present in both series; got {len(spread)}")
    return dict(
        n=len(spread),
        spearman=float(stats.spearmanr(spread, error).statistic),
        pearson=float(stats.pearsonr(spread, error).statistic),
    )
