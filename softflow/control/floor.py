"""The open-loop floor: how well any plan can track a reference in this simulator, measured
by iterative learning control (ILC) on the true simulator itself.

A learned inverse model is judged against it: the gap between a model's RMSE and the floor
is what a better model could still win; an RMSE near the floor cannot improve open loop.
ILC refines one plan per reference from its own rollouts (an exact model, many trials), so
it is a floor for the rod and the reference, not a controller a robot could run once:

    u_{k+1} = u_k + gain F^-1[ Q(w) / H(w) F[ J(u_k)^+ e_k ] ]

e_k the tip-position error of trial k, J = dp/du the static Jacobian at the current input
(the learning direction and its static gain; on a rod with more inputs than two, which has no
static table, a damped inverse at the quasi-static plan, fixed over the trials, see
``least_norm_start``), H the rod's measured small-signal frequency
response from u to the tip normalised to H(0) = 1 (its first bending mode near 1.7 Hz
resonates, so a static learning law alone diverges above it), and Q a low-pass filter
(Butterworth magnitude, zero phase) that keeps the plan smooth and the iteration from
amplifying what the rod cannot follow. The inverse is non-causal, as ILC may be: a whole
trial is known before the next.
"""

from __future__ import annotations

import numpy as np
from tqdm import tqdm

from softflow.control.metrics import tracking_rmse
from softflow.control.planning import pad_plans
from softflow.rod import statics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, U_MAX

ITERATIONS = 40
CUTOFF_HZ = 5.0  # Q's cutoff: the references hold nothing above 2 Hz
GAIN = 1.0  # the full model-inverse step; 0.5 roughly halved the rate of convergence
# A rod with more inputs than two (docs/assumptions.md, two_segment):
COARSE = 10  # steps between the least-norm equilibria of its start (0.1 s; linear in between)
DAMPING = 0.1  # of |J|: its learning direction's damping (0.03 let a random reference diverge)
_STATIC_CHUNK = 128  # points fitted together by the least-norm statics


def ilc_plans(
    sim: Simulator,
    references,
    *,
    iterations: int = ITERATIONS,
    cutoff_hz: float = CUTOFF_HZ,
    gain: float = GAIN,
    u_limit: float = U_MAX,
    start_q=None,
    progress: bool = False,
):
    """The best plan ILC finds for each reference within ``iterations`` trials, all references
    in one batched rollout per trial (from rest, or from ``start_q`` as in ``control.evaluate``).
    Starts from the quasi-static plan: the inverse statics of the reference tip (the static
    table's on a two-input rod, ``least_norm_start`` on one with more inputs). Returns the best
    plans, the states they reach (one (T+1, 6) per reference) and the history of each
    reference's RMSE in mm, (iterations + 1, R)."""
    if not (isinstance(iterations, int) and iterations >= 0):
        raise ValueError(f"iterations must be a non-negative integer; got {iterations!r}")
    if not (0 < cutoff_hz < 0.5 / DT and 0 < gain <= 1):
        raise ValueError(f"need 0 < cutoff_hz < {0.5 / DT:g} and 0 < gain <= 1; got {cutoff_hz!r}, {gain!r}")
    learning = learning_filter(sim, max(r.n_steps for r in references), cutoff_hz)
    if sim.n_inputs == 2:
        table = sim.static_table()
        plans = [np.clip(table.inverse(r.states[1:, :3]), -u_limit, u_limit) for r in references]

        def step(k, u, error):
            return correction(table, u, error, learning)
    else:
        starts, inverses = least_norm_start(sim, references)
        plans = [np.clip(u, -u_limit, u_limit) for u in starts]

        def step(k, u, error):
            return filtered(np.einsum("tij,tj->ti", inverses[k], error), learning)

    best, best_rmse, history = [None] * len(plans), np.full(len(references), np.inf), []
    for _ in tqdm(range(iterations + 1), desc="ILC floor", unit="trial", disable=not progress):
        _, padded = pad_plans(plans)
        achieved = sim.rollout(padded, start_q=start_q)
        rmse = np.array(
            [1e3 * tracking_rmse(X[: r.n_steps + 1], r.states, r.mask) for r, X in zip(references, achieved)]
        )
        history.append(rmse)
        best = [
            (u, X[: r.n_steps + 1]) if now < before else kept
            for u, X, r, now, before, kept in zip(plans, achieved, references, rmse, best_rmse, best)
        ]
        best_rmse = np.minimum(rmse, best_rmse)
        plans = [
            np.clip(u + gain * step(k, u, r.states[1:, :3] - X[1 : r.n_steps + 1, :3]), -u_limit, u_limit)
            for k, (u, r, X) in enumerate(zip(plans, references, achieved))
        ]
    best_plans, reached = zip(*best)
    return list(best_plans), list(reached), np.array(history)


def least_norm_start(sim: Simulator, references):
    """Per reference: the least-norm equilibrium whose tip has the reference tip's lateral (y, z),
    at every ``COARSE``-th step and linear in between (T, m), and the damped pseudo-inverse of the
    static Jacobian d p / d u there, J^T (J J^T + mu^2 I)^-1 with mu = DAMPING |J| (T, m, 3): the
    floor's start and learning direction on a rod with more inputs than two, which has no static
    table. Lateral, because a hanging rod's depth does not change to first order at rest, where
    a least-norm fit of all three coordinates is singular; damped, because the plain inverse of
    that nearly singular depth row throws the plan into the actuator limits. A step whose fit
    does not converge (far out, where the least-norm iteration can cycle) is left out, and the
    start runs linear between its neighbours, as between every ``COARSE``-th step."""
    steps = [np.unique(np.append(np.arange(0, r.n_steps, COARSE), r.n_steps - 1)) for r in references]
    tips = np.concatenate([r.states[1:, :3][k] for r, k in zip(references, steps)])  # (K, 3)
    u, J, fitted = map(
        np.concatenate,
        zip(*(_lateral_fit(sim, tips[i : i + _STATIC_CHUNK]) for i in range(0, len(tips), _STATIC_CHUNK))),
    )
    inverse = np.full(J.transpose(0, 2, 1).shape, np.nan)  # (K, m, 3)
    J = J[fitted]
    damping = (DAMPING * np.linalg.norm(J, ord=2, axis=(1, 2)))[:, None, None] ** 2 * np.eye(3)
    inverse[fitted] = J.transpose(0, 2, 1) @ np.linalg.inv(J @ J.transpose(0, 2, 1) + damping)
    ends = np.cumsum([len(k) for k in steps])[:-1]
    starts, inverses = [], []
    for r, k, ok, values, inverse_k in zip(references, steps, *(np.split(a, ends) for a in (fitted, u, inverse))):
        if not ok.any():
            raise ValueError(
                f"reference {r.name!r}: no least-norm equilibrium reaches any of its tip's lateral positions"
            )
        starts.append(_between(k[ok], values[ok], r.n_steps))
        inverses.append(_between(k[ok], inverse_k[ok], r.n_steps))
    return starts, inverses


def _lateral_fit(sim: Simulator, p):
    """The least-norm u (b, m) whose equilibrium tip has p's (y, z), d p / d u there (b, 3, m) and
    which points converged (b,): fitted together, a batch that fails is halved until the points
    that do not converge stand alone (their u and J are NaN)."""
    try:
        u, _, J = statics.fit_static(sim, p, [1, 2], statics.arc_actuation(sim.robot, p), u_limit=sim.u_bound)
        return u, J, np.ones(len(p), bool)
    except (RuntimeError, np.linalg.LinAlgError):
        if len(p) == 1:
            return np.full((1, sim.n_inputs), np.nan), np.full((1, 3, sim.n_inputs), np.nan), np.zeros(1, bool)
    half = len(p) // 2
    return tuple(np.concatenate(parts) for parts in zip(_lateral_fit(sim, p[:half]), _lateral_fit(sim, p[half:])))


def _between(known, values, n: int) -> np.ndarray:
    """``values`` (K, ...) given at the steps ``known``, linear in between: (n, ...) at steps 0..n-1."""
    flat = np.reshape(values, (len(known), -1))
    linear = np.stack([np.interp(np.arange(n), known, column) for column in flat.T], -1)
    return linear.reshape((n,) + np.shape(values)[1:])


def learning_filter(sim: Simulator, n_steps: int, cutoff_hz: float = CUTOFF_HZ) -> np.ndarray:
    """Q(w) / H_k(w) per input k, (n_freq, m), for plans of up to ``n_steps`` steps, on the
    rfft grid of 2 n_steps samples (zero padding: no wrap-around). H_k from a small step of
    u_k at rest: the tip's motion along the axis that input moves it most (y for u1, z for
    u2; on the two-segment rod also u3, u4), unit static gain; in the horizontal configuration
    gravity makes them differ. Q a 4th-order Butterworth magnitude."""
    n_fft, m = 2 * n_steps, sim.n_inputs
    steps = np.zeros((m, n_fft, m))
    steps[np.arange(m), :, np.arange(m)] = 0.05  # N: small, so the response is linear
    tip = sim.rollout(steps)[..., :3]
    moved = tip - tip[:, :1]
    along = moved[np.arange(m), :, np.argmax(np.abs(moved[:, -1]), axis=-1)]
    impulse = np.diff(along, axis=1) / along[:, -1:]  # unit static gain; the record must have settled
    H = np.fft.rfft(impulse, n_fft, axis=1).T
    f = np.fft.rfftfreq(n_fft, DT)
    Q = 1 / np.sqrt(1 + (f / cutoff_hz) ** 8)
    return Q[:, None] / H


def correction(table, u, error, learning) -> np.ndarray:
    """The ILC step for a (T, 2) plan from its (T, 3) tip error (reference - achieved): the
    static inverse of the error, filtered by ``learning`` (from ``learning_filter``)."""
    _, J = table.tip(np.clip(u, -table.u_range, table.u_range))
    return filtered(np.einsum("tij,tj->ti", np.linalg.pinv(J), error), learning)


def filtered(static, learning) -> np.ndarray:
    """A static correction (T, m) filtered by ``learning`` (n_freq, m) (zero-padded, so no wrap-around)."""
    n_fft = 2 * (len(learning) - 1)
    return np.fft.irfft(np.fft.rfft(static, n_fft, axis=0) * learning, n_fft, axis=0)[: len(static)]
