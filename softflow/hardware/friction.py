"""Cable friction in the spacer disks' holes: Dahl's rate-independent friction state and the
capstan law that turns it into tensions along a cable (``plant.CablePlant`` uses both)."""

from __future__ import annotations

import numpy as np


def dahl_state(state, sliding, sliding_length: float):
    """The friction state z (B, C) in [-1, 1] after each cable slid by ``sliding`` (B, C) m
    (positive: towards its motor). Dahl's model dz/dx = (1 - z sgn(dx)) / x_s, solved exactly
    over a step of one sign: z' = s + (z - s) exp(-|dx| / x_s), s = sgn(dx). Sticking (|dx| <<
    x_s) barely moves z; sliding (|dx| >> x_s) takes it to +-1. Rate-independent, smooth, and
    bounded for any step, so it needs no finer time step than the plant's."""
    direction = np.sign(sliding)
    return direction + (state - direction) * np.exp(-np.abs(sliding) / sliding_length)


def capstan_tensions(base, turning, friction: float, state):
    """Tension at the anchored end and mean tension along the cable (B, C) each, for the
    tension ``base`` at the motor end, the cable's total turning ``turning`` (rad) through the
    disks, the friction coefficient and the friction state z (all (B, C) or broadcastable).

    Capstan: where the cable slides towards its motor (z = 1) the tension falls along it as
    exp(-mu phi), phi the turning from the base, so the anchored end carries T_b exp(-mu theta);
    sliding away (z = -1) it rises as exp(+mu phi); in between z scales the exponent,
    a = mu theta z. Turning grows along an arc at a constant rate, so the mean along the cable
    is T_b (1 - exp(-a)) / a (series below |a| = 1e-4, never divided by a small a)."""
    exponent = friction * np.asarray(turning) * state  # (B, C)
    small = np.abs(exponent) < 1e-4
    safe = np.where(small, 1.0, exponent)
    mean_factor = np.where(small, 1 - exponent / 2 + exponent**2 / 6, -np.expm1(-safe) / safe)
    return base * np.exp(-exponent), base * mean_factor
