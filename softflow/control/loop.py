"""The control loop of a model of recorded runs, one period defined once: a torch module
(``Period``) that a Python loop runs as it is and a robot's computer runs exported as one ONNX
graph, its memory (filter, frames, inputs in flight) explicit input and output.

Each period, in order:

1. **Estimate** (``Estimator``): the frame of every observed column folds into the same
   constant-acceleration Kalman filter the offline smoother runs forward (``smoothing``: its
   model, its levels fitted to the recordings), so the loop's state is the smoother's forward
   pass. A frame not finite, or a point whose coordinates all repeat the last frame's (a
   tracker holding its value), is lost: the filter predicts across it.
2. **Predict** (``Predictor``): the model learnt u sent d periods before each step (the rig's
   delay), so the input sent now acts on the step from x_{t+d}; a linear forward model of the
   recordings, fitted to their training episodes, carries the estimate d periods ahead through
   the d inputs already in flight.
3. **Step** (``control.step.Step``): u = g(x', x*_{t+d+1} + c), the model's step with each
   input's limits from the recordings (``InputLimits``), where x' is the wanted x*_{t+d} moved
   towards the predicted state by ``Feedback.blend`` (0 by default: a one-step inverse shown a
   state far from the wanted path asks for transitions it never learnt) plus c, and c is
   ``Feedback.integral`` times the integrated position error now, x*_t - x_t (integral action).
4. **Safety**: u moves from the last input sent by at most each input's largest change per
   period in the recordings; the safe input (by default the recordings' median) is sent
   instead while the estimate, or the state predicted d periods ahead, is outside the
   workspace, not yet known, or stale (no fresh frame of some point for ``watchdog`` s).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import onnx
import torch
from torch import nn

from softflow.control.planning import input_box
from softflow.control.step import Step, export_graph, real_time_session
from softflow.data.dataset import Dataset
from softflow.data.recordings import tip_points
from softflow.data.smoothing import PRIOR_ACCELERATION, PRIOR_SPEED, transition

# s: how long a point may go without a fresh frame before the loop sends the safe input: three
# periods of the trunk, over which the filter's prediction drifts from the smoother's states by
# about as much as the predictor's own error five periods ahead (figures/bench/loop_parts_trunk.csv).
WATCHDOG = 0.03
PREDICTOR_RIDGE = 1e-6  # ridge of the forward model on standardised features (a share of the rows)


@dataclass(frozen=True)
class InputLimits:
    """Per input (m,) each: the range it may take (``low``, ``high``), its largest change per
    period (``rate``), and the safe input, all in the recordings' units."""

    low: np.ndarray
    high: np.ndarray
    rate: np.ndarray
    safe: np.ndarray

    @classmethod
    def of(cls, dataset: Dataset, *, u_range=None, safe_input=None, rate=None) -> InputLimits:
        """The limits the training episodes of recorded ``dataset`` show: each input's [min, max],
        its largest change between periods, and its median as the safe input. ``u_range``
        (low, high), each a number or one per input, ``safe_input`` (m,) and ``rate`` (a number or
        one per input) override them."""
        u = dataset.u[dataset.train]  # (E, T, m)
        m = u.shape[-1]
        low, high = u.min((0, 1)), u.max((0, 1))
        if u_range is not None:
            low, high = input_box(u_range, m)
        median = np.clip(np.median(u.reshape(-1, m), 0), low, high)
        safe = median if safe_input is None else np.asarray(safe_input, np.float64)
        if safe.shape != (m,) or not ((low <= safe) & (safe <= high)).all():
            raise ValueError(f"safe_input must be {m} values, each inside its input's range; got {safe_input!r}")
        if rate is None:
            rate = np.abs(np.diff(u, axis=1)).max((0, 1))  # (m,)
        rate = np.broadcast_to(np.asarray(rate, np.float64), (m,)).copy()
        if not (np.isfinite(rate).all() and (rate > 0).all()):
            raise ValueError(f"rate must be a positive change per period, one for all inputs or one each; got {rate!r}")
        return cls(low, high, rate, safe)

    def violations(self, u, names=None) -> list[str]:
        """What in a plan u (T, m) leaves these limits, one sentence per input that does (samples
        outside its range, steps faster than its rate); [] for a plan inside them."""
        u = np.asarray(u, np.float64)
        names = names or [f"input {i + 1}" for i in range(u.shape[1])]
        out = []
        for i, name in enumerate(names):
            outside = int(np.sum((u[:, i] < self.low[i]) | (u[:, i] > self.high[i])))
            fast = int(np.sum(np.abs(np.diff(u[:, i])) > self.rate[i]))
            if outside or fast:
                out.append(
                    f"{name}: {outside} of {len(u)} samples outside {self.low[i]:g} to {self.high[i]:g}, {fast} steps "
                    f"faster than {self.rate[i]:g} per period"
                )
        return out


@dataclass(frozen=True)
class Feedback:
    """How the loop corrects: ``blend`` (positions, velocities), the share of the predicted state's
    departure from the wanted one the model is shown (a model shown estimates trains on the
    filter's states, ``causal=True``); ``integral`` (1/s), the gain of the integrated position
    error now added to the wanted states. The default, chosen on a pilot before the loop study's
    first row (docs/assumptions.md): integral action alone, as the twin's loop."""

    blend: tuple[float, float] = (0.0, 0.0)
    integral: float = 2.0

    def __post_init__(self):
        if not (len(self.blend) == 2 and all(0 <= b <= 1 for b in self.blend) and 0 <= self.integral < math.inf):
            raise ValueError(f"blend must be two shares in [0, 1] and integral a gain >= 0 in 1/s; got {self!r}")


class Estimator(nn.Module):
    """The smoother's Kalman filter run forward, one period at a time, for k observed columns:
    ``forward(frame (B, k), x (B, k, 3), P (B, k, 3, 3), fresh (B, k))`` -> (x, P), float64. A
    column whose x is NaN is not yet known: its first fresh frame starts it, as the smoother's
    first frame does (at rest, its prior spread)."""

    def __init__(self, dt: float, noise, jerk):
        super().__init__()
        noise, jerk = np.asarray(noise, np.float64), np.asarray(jerk, np.float64)  # (k,) each
        F, Q = transition(dt)
        self.register_buffer("F", torch.as_tensor(F))  # (3, 3)
        self.register_buffer("Q", torch.as_tensor(jerk[:, None, None] ** 2 * Q))  # (k, 3, 3)
        self.register_buffer("R", torch.as_tensor(noise**2))  # (k,)
        start = np.zeros((len(noise), 3, 3))
        start[:, 0, 0], start[:, 1, 1], start[:, 2, 2] = noise**2, PRIOR_SPEED**2, PRIOR_ACCELERATION**2
        self.register_buffer("P_start", torch.as_tensor(start))  # (k, 3, 3)

    def forward(self, frame, x, P, fresh):
        x, P = x @ self.F.T, self.F @ P @ self.F.T + self.Q  # predicted
        S = P[..., 0, 0] + self.R  # (B, k) innovation variance, H = [1, 0, 0]
        gain = P[..., :, 0] / S.unsqueeze(-1)  # (B, k, 3)
        innovation = torch.where(fresh, frame, 0.0) - x[..., 0]
        x_new = x + gain * innovation.unsqueeze(-1)
        P_new = P - gain.unsqueeze(-1) * P[..., 0, :].unsqueeze(-2)
        P_new = (P_new + P_new.transpose(-1, -2)) / 2
        known = torch.isfinite(x[..., 0])
        start = torch.stack([frame, torch.zeros_like(frame), torch.zeros_like(frame)], -1)
        x = torch.where((fresh & known).unsqueeze(-1), x_new, torch.where(fresh.unsqueeze(-1), start, x))
        P = torch.where((fresh & known)[..., None, None], P_new, torch.where(fresh[..., None, None], self.P_start, P))
        return x, P


class Predictor(nn.Module):
    """The state ``steps`` periods ahead from a state x (B, d) and the inputs in flight (B, steps,
    m), oldest first, by a linear forward model of the recordings iterated ``steps`` times,
    written as one affine map: x_{t+1} = x_t + W [x_t, u_t, 1] (standardised features, ridge)."""

    def __init__(self, step_map: np.ndarray, input_map: np.ndarray, offset: np.ndarray):
        super().__init__()
        self.register_buffer("step_map", torch.as_tensor(step_map))  # (d, d)
        self.register_buffer("input_map", torch.as_tensor(input_map))  # (steps * m, d)
        self.register_buffer("offset", torch.as_tensor(offset))  # (d,)

    @classmethod
    def fit(cls, dataset: Dataset, steps: int, *, ridge: float = PREDICTOR_RIDGE) -> Predictor:
        """The forward model of ``dataset``'s training episodes (each step with its paired input),
        composed over ``steps`` periods."""
        u, X = dataset.u[dataset.train], dataset.states[dataset.train]  # (E, T, m), (E, T+1, d)
        d, m = X.shape[-1], u.shape[-1]
        features = np.concatenate([X[:, :-1].reshape(-1, d), u.reshape(-1, m)], 1)  # (N, d + m)
        change = np.diff(X, axis=1).reshape(-1, d)  # (N, d)
        mean, spread = features.mean(0), features.std(0)
        spread = np.where(spread > 0, spread, 1.0)
        A = np.column_stack([(features - mean) / spread, np.ones(len(features))])
        W = np.linalg.solve(A.T @ A + ridge * len(A) * np.eye(d + m + 1), A.T @ change)  # (d + m + 1, d)
        scaled = W[:-1] / spread[:, None]  # (d + m, d) on raw features
        one_step, by_input = np.eye(d) + scaled[:d], scaled[d:]  # x_{t+1} = x_t one_step + u_t by_input + bias
        bias = W[-1] - mean @ scaled
        powers = [np.eye(d)]
        for _ in range(steps):
            powers.append(powers[-1] @ one_step)
        input_map = (
            np.concatenate([by_input @ powers[steps - 1 - i] for i in range(steps)]) if steps else np.zeros((0, d))
        )
        return cls(powers[steps], input_map, bias @ sum(powers[:steps], np.zeros((d, d))))

    def forward(self, x, in_flight):
        return x @ self.step_map + in_flight.flatten(1) @ self.input_map + self.offset


def point_matrix(points, k: int) -> torch.Tensor:
    """(k, k) float64: 1 where two of the k observed columns are coordinates of one point (``points``:
    ``recordings.tip_points``)."""
    same = torch.zeros(k, k, dtype=torch.float64)
    for columns in points:
        same[np.ix_(columns, columns)] = 1.0
    return same


def fresh_frames(frame, last_frame, same_point):
    """(B, k) bool: the columns of ``frame`` (B, k) that are finite and not of a point whose
    coordinates all repeat ``last_frame``'s (a tracker holding its value; a planar rig's constant
    coordinate alone is not)."""
    repeated = (frame == last_frame).to(torch.float64) @ same_point  # (B, k): the point's columns repeating
    return torch.isfinite(frame) & (repeated < same_point.sum(0))


def track(estimator: Estimator, same_point, frame, x, P, last_frame, stale):
    """One period's estimate from the newest ``frame`` (B, k): the filter folds in the fresh
    columns (``fresh_frames``) and predicts across the others; returns (x, P, the last frame
    received, the periods since each column's last fresh frame)."""
    fresh = fresh_frames(frame, last_frame, same_point)  # (B, k)
    x, P = estimator(frame, x, P, fresh)
    return x, P, torch.where(torch.isfinite(frame), frame, last_frame), torch.where(fresh, 0, stale + 1)


MEMORY = ("x", "P", "last_frame", "stale", "sent", "integral")  # a period's memory, the graph's order


class Period(nn.Module):
    """One period of the loop: ``forward(frame, reference, *memory)`` -> (u, holding, *memory).
    ``frame`` (B, k) float64: the observed columns' newest values (NaN: none); ``reference``
    (B, 3, d) float32: the states wanted now, d and d + 1 periods ahead, x*_t, x*_{t+d}, x*_{t+d+1};
    memory (``MEMORY``): the filter's x (B, k, 3) and P (B, k, 3, 3), the last frame (B, k), the
    periods since each column's last fresh frame (B, k) int64, the last max(d, 1) inputs sent
    (B, max(d, 1), m) float32, oldest first, and the integral of the position error
    (B, k) float32, m s. ``u`` (B, m) is sent now; ``holding`` (B,) whether it is the safe input.

    Feedback (``Feedback``): the model is asked for the transition from the wanted state moved
    towards the predicted one by ``blend`` (positions, velocities), to the wanted state, both
    shifted by ``integral`` (1/s) times the integral of the position error now, x*_t - x_t."""

    def __init__(
        self,
        step: Step,
        estimator: Estimator,
        predictor: Predictor,
        limits: InputLimits,
        *,
        points,
        delay: int,
        watchdog: int,
        dt: float,
        input_columns=(),
        anchor=None,
        feedback: Feedback | None = None,
    ):
        super().__init__()
        k = len(estimator.R)
        feedback = feedback or Feedback()
        anchor = np.zeros(k) if anchor is None else np.asarray(anchor, np.float64)
        self.register_buffer("anchor", torch.as_tensor(anchor))  # (k,) m added to every frame (a new session's)
        blend = np.repeat(np.asarray(feedback.blend, np.float32), k)  # (d,): positions', then velocities'
        self.register_buffer("blend", torch.as_tensor(blend))
        self.step, self.estimator, self.predictor = step, estimator, predictor
        self.delay, self.watchdog, self.input_columns = delay, watchdog, tuple(input_columns)
        self.dt, self.integral_gain = float(dt), float(feedback.integral)
        self.register_buffer("same_point", point_matrix(points, k))
        self.register_buffer("rate", torch.as_tensor(limits.rate, dtype=torch.float32))  # (m,)

    def forward(self, frame, reference, x, P, last_frame, stale, sent, integral):
        x, P, last_frame, stale = track(self.estimator, self.same_point, frame + self.anchor, x, P, last_frame, stale)
        now = torch.cat([x[..., 0], x[..., 1]], -1)  # (B, d): positions, then velocities
        ahead = self.predictor(now, sent[:, sent.shape[1] - self.delay :].double()) if self.delay else now
        ahead, (wanted, now_wanted, next_wanted) = ahead.float(), reference.unbind(1)
        k = integral.shape[1]
        summed = integral + self.dt * (wanted - now.float())[:, :k]  # (B, k): the position error now
        shift = torch.cat([self.integral_gain * summed, torch.zeros_like(summed)], 1)  # (B, d): positions only
        start = now_wanted + self.blend * (ahead - now_wanted)
        u, outside = self.step(start + shift, next_wanted + shift)
        outside = outside | self.step.outside(ahead, next_wanted)
        previous = sent[:, -1]
        u = torch.minimum(torch.maximum(u, previous - self.rate), previous + self.rate)
        holding = outside | (stale > self.watchdog).any(-1)
        u = torch.where(holding.unsqueeze(-1), self.step.safe, u)
        integral = torch.where(holding.unsqueeze(-1), integral, summed)  # no integration while holding
        return u, holding, x, P, last_frame, stale, torch.cat([sent[:, 1:], u.unsqueeze(1)], 1), integral

    def memory(self, batch: int = 1) -> dict:
        """The memory a loop starts from: nothing known, every column stale, the safe input sent."""
        k, m = len(self.estimator.R), len(self.step.safe)
        return dict(
            x=torch.full((batch, k, 3), torch.nan, dtype=torch.float64),
            P=torch.zeros(batch, k, 3, 3, dtype=torch.float64),
            last_frame=torch.full((batch, k), torch.nan, dtype=torch.float64),
            stale=torch.full((batch, k), self.watchdog + 1, dtype=torch.int64),
            sent=self.step.safe.expand(batch, max(self.delay, 1), m).clone(),
            integral=torch.zeros(batch, k),
        )


def loop_of(
    controller,
    dataset: Dataset,
    *,
    watchdog: float = WATCHDOG,
    u_range=None,
    safe_input=None,
    rate=None,
    anchor=None,
    feedback: Feedback | None = None,
) -> Loop:
    """The loop of ``controller``, a model trained on the recorded ``dataset``, on the rig that
    recorded it (the smoother's levels, the delay, the limits and the forward model come from
    it); ``u_range``, ``safe_input`` and ``rate`` override the recordings' limits, median and
    rates (``InputLimits.of``). ``anchor`` (k,) m is added to every frame: a new session's
    offset from the recordings' (``recordings.rest_offset``)."""
    if dataset.robot is not None or dataset.levels is None:
        raise ValueError(
            "the loop is for a model of recorded runs: give the Dataset of recordings.load_dataset, which carries "
            "the smoother's levels; a simulated rod's closed loop is control.closed_loop.run_loop"
        )
    if controller.model.dims.state != dataset.dims.state or controller.model.dims.inputs != dataset.dims.inputs:
        raise ValueError(
            f"{controller.name} reads {controller.model.dims.state} states and writes {controller.model.dims.inputs} "
            f"inputs; these recordings have {dataset.dims.state} and {dataset.dims.inputs}"
        )
    k = len(dataset.tip_columns)
    if anchor is not None and not (np.shape(anchor) == (k,) and np.isfinite(anchor).all()):
        raise ValueError(f"anchor must be {k} finite offsets in m, one per tip column; got {anchor!r}")
    if not (isinstance(watchdog, (int, float)) and math.isfinite(watchdog) and watchdog >= 0):
        raise ValueError(f"watchdog must be a duration >= 0 in s; got {watchdog!r}")
    feedback = feedback or Feedback()
    if any(feedback.blend) and not dataset.causal:
        warnings.warn(
            f"{controller.name} is shown the loop's estimates (blend {feedback.blend}) but was trained on the "
            "smoother's states, which use frames after each step: train it on recordings read with causal=True "
            "(--causal)",
            stacklevel=2,
        )
    limits = InputLimits.of(dataset, u_range=u_range, safe_input=safe_input, rate=rate)
    limited = controller.limited((limits.low, limits.high), limits.safe)
    noise, jerk = dataset.levels
    period = Period(
        limited.step_module,
        Estimator(dataset.dt, noise, jerk),
        Predictor.fit(dataset, dataset.delay_steps),
        limits,
        points=tip_points(dataset.tip_columns),
        delay=dataset.delay_steps,
        watchdog=int(round(watchdog / dataset.dt)),
        dt=dataset.dt,
        input_columns=dataset.input_columns,
        anchor=anchor,
        feedback=feedback,
    )
    return Loop(period, limited)


class Loop:
    """A period with its memory: ``loop(frame, reference)`` -> u (m,) float64 runs one period in
    torch (the definition); ``graph()`` is the same period as one ONNX graph. ``controller``:
    the model's, with the loop's input limits and safe input."""

    def __init__(self, period: Period, controller):
        self.period, self.controller = period.eval(), controller
        self.memory = period.memory()
        self.holding = True

    def __call__(self, frame, reference) -> np.ndarray:
        frame = torch.as_tensor(np.asarray(frame, np.float64)).reshape(1, -1)
        reference = torch.as_tensor(np.asarray(reference, np.float32)).reshape(1, 3, -1)
        with torch.no_grad():
            u, holding, *memory = self.period(frame, reference, *self.memory.values())
        self.memory, self.holding = dict(zip(MEMORY, memory)), bool(holding[0])
        return u[0].double().numpy()

    @property
    def input_columns(self) -> tuple[str, ...]:
        return self.period.input_columns

    def graph(self) -> onnx.ModelProto:
        """The period as one graph: inputs frame, reference and the memory, outputs u, holding and
        the memory (names ``MEMORY``, the outputs prefixed ``next_``); batch as the first axis."""
        k, d = self.period.same_point.shape[0], self.period.step.box_low.shape[0] // 2
        example = (torch.zeros(2, k, dtype=torch.float64), torch.zeros(2, 3, d), *self.period.memory(2).values())
        return export_graph(
            self.period,
            example,
            ["frame", "reference", *MEMORY],
            ["u", "holding", *(f"next_{name}" for name in MEMORY)],
        )


class GraphLoop:
    """``loop``'s period as its exported graph in onnxruntime (one thread), for B rigs at once:
    ``graph_loop(frames (B, k), references (B, d))`` -> u (B, m) float64; ``holding`` (B,)
    after each call. What examples/run_loop.py does on a robot, batched."""

    def __init__(self, loop: Loop, batch: int = 1):
        self.session = real_time_session(loop.graph())
        self.memory = {name: value.numpy() for name, value in loop.period.memory(batch).items()}
        self.holding = np.ones(batch, bool)

    def __call__(self, frames, references) -> np.ndarray:
        feed = dict(frame=np.asarray(frames, np.float64), reference=np.asarray(references, np.float32), **self.memory)
        u, self.holding, *memory = self.session.run(None, feed)
        self.memory = dict(zip(MEMORY, memory))
        return u.astype(np.float64)
