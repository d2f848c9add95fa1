"""Closed-loop tracking: every DT, the inverse model's u for the next reference state (from
the reference's current state, or from the estimated one), plus a correction of the
estimated tip error, sent to the robot.

One function, ``run_loop``, drives the hardware twin (``hardware.TwinRig``) and a real rig
alike: it only calls ``measure()``, which returns the camera frames that arrived since the
last call as (time taken, (3,) position) pairs, and ``command(u)``, which applies u for one
control period (a real rig paces the loop there; the twin advances its clock). A frame
without the marker (NaN), or a ``measure()`` that raises, is a lost frame; when more than
``watchdog_frames`` frames in a row are lost, the loop holds the last command it sent with
the marker in sight and records the event, until the marker is back.

The correction is PI on the tip error through the statics: du = J^+ (kp e + ki int e), J the
rod's static Jacobian dp/du at the current input (the same map the ILC floor learns
through), integrating only while the command is not clipped (anti-windup). Across
repetitions of the same reference, ``learn_by_repetition`` adds a feedforward learned from
each run's camera error (ILC).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from softflow.checks import check_choice
from softflow.control import floor
from softflow.control.estimation import TipEstimator
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, U_MAX

WATCHDOG_FRAMES = 5  # lost frames in a row (1/6 s at 30 fps) before the loop holds its command
# s: learning across repetitions ramps in over this window. A rig starts from its own rest,
# which a reality gap puts away from the reference's first state (35 mm in z on the
# horizontal twin); no input removes that in the first tenths of a second, and learning it
# pumped the first inputs into the actuator limits a little more every repetition.
SETTLE = (0.3, 1.0)


@dataclass(frozen=True)
class PI:
    """Gains of the tip-error correction (dimensionless kp, ki in 1/s: the share of the static
    error corrected per step, and per second of accumulated error). kp = ki = 0: none.
    Default: integral action alone, slow (ki = 0.5/s), because the correction acts through the
    rod's lightly damped first mode and the camera's delay: ki = 2/s already rings on a hold
    (tests/test_loop.py) and kp = 0.05 made the twin's tracking worse (docs/assumptions.md)."""

    kp: float = 0.0
    ki: float = 0.5

    def __post_init__(self):
        if not (math.isfinite(self.kp) and math.isfinite(self.ki) and self.kp >= 0 and self.ki >= 0):
            raise ValueError(f"PI gains must be finite and >= 0; got kp={self.kp!r}, ki={self.ki!r}")


NO_CORRECTION = PI(0.0, 0.0)


@dataclass
class LoopRun:
    """What a closed-loop run did: commands (T, 2), estimated states (T, 6), the frames it
    received (time taken, position), and the counts a run report needs."""

    u: np.ndarray
    estimates: np.ndarray
    frames: list = field(default_factory=list)
    clipped: int = 0  # commands clipped to the actuator range (per channel)
    watchdog_events: int = 0  # times the marker was lost long enough to hold the command
    held_steps: int = 0  # control steps spent holding
    lost_frames: int = 0  # frames without a marker, and measure() calls that raised


CONDITIONS = ("reference", "estimate")


def run_loop(
    controller,
    reference,
    measure,
    command,
    *,
    correction: PI = PI(),
    condition: str = "reference",
    feedforward=None,
    watchdog_frames: int = WATCHDOG_FRAMES,
    u_limit: float = U_MAX,
    estimator_options: dict | None = None,
    calibration=None,
) -> LoopRun:
    """Track ``reference`` (a ``trajectories.Reference`` that starts at the rod's rest) in
    closed loop; see the module docstring. ``feedforward`` (T, 2) is added to every command
    (e.g. learned across repetitions). ``condition``: the inverse model's u for (x*_t, x*_t+1),
    the plan, so that feedback comes from the correction alone ("reference"), or for
    (estimated x_t, x*_t+1) ("estimate"). A reference outside the model's workspace is refused
    before the first command. ``estimator_options`` go to ``estimation.TipEstimator``.
    ``calibration`` (a ``calibration.Calibration``): the model's u is mapped to the identified
    rod, and the correction acts through that rod's statics; the rig's ``command`` should
    then be made through it too (``Calibration.step_commands``)."""
    check_choice(condition, "condition", CONDITIONS)
    X = reference.states
    controller.check_workspace(X)
    if not controller.has_step:
        raise ValueError(f"{controller.name} has no one-transition step; closed loop needs an MLP or RF model")
    if not (isinstance(watchdog_frames, int) and watchdog_frames >= 1):
        raise ValueError(f"watchdog_frames must be a positive integer; got {watchdog_frames!r}")
    T = reference.n_steps
    extra = np.zeros((T, 2)) if feedforward is None else np.asarray(feedforward, float)
    if extra.shape != (T, 2):
        raise ValueError(f"feedforward must have shape ({T}, 2); got {extra.shape}")
    table = _rod(controller, calibration).static_table()
    estimator = TipEstimator(X[0, :3], **(estimator_options or {}))
    run = LoopRun(np.zeros((T, 2)), np.zeros((T, 6)))
    integral, u_prev, safe = np.zeros(3), np.zeros(2), np.zeros(2)
    lost_in_a_row, holding = 0, False
    for t in range(T):
        frames = _frames(measure)
        for taken, position in frames or ():
            estimator.update(taken, position)
            run.frames.append((taken, position))
        for found in [False] if frames is None else [np.all(np.isfinite(p)) for _, p in frames]:
            lost_in_a_row = 0 if found else lost_in_a_row + 1
            run.lost_frames += not found
        x_hat = estimator.state(max(t * DT, estimator.t if estimator.t is not None else 0.0))
        run.estimates[t] = x_hat
        if lost_in_a_row > watchdog_frames:
            run.watchdog_events += not holding
            run.held_steps += 1
            holding, u = True, safe
        else:
            holding = False
            error = X[t, :3] - x_hat[:3]
            wanted = controller.step(x_hat if condition == "estimate" else X[t], X[t + 1], clip=False)
            if calibration is not None:
                wanted = calibration.actuation(wanted[None], t)[0]
            wanted = wanted + extra[t]
            if correction != NO_CORRECTION:
                _, J = table.tip(np.clip(u_prev, -table.u_range, table.u_range)[None])
                wanted = wanted + np.linalg.pinv(J[0]) @ (correction.kp * error + correction.ki * integral)
            u = np.clip(wanted, -u_limit, u_limit)
            run.clipped += int(np.sum(u != wanted))
            if np.array_equal(u, wanted):  # anti-windup: no integration into saturation
                integral += error * DT
            safe = u
        command(u)
        run.u[t], u_prev = u, u
    return run


def _rod(controller, calibration) -> Simulator:
    """The rod a loop corrects through: the identified one if calibrated, else the model's."""
    return Simulator(controller.robot, controller.gravity) if calibration is None else calibration.rod


def _frames(measure):
    """The frames ``measure()`` returns; None when it raised (a camera that fails is a lost
    frame for the watchdog, not a crash)."""
    try:
        return [(float(taken), np.asarray(position, float).reshape(3)) for taken, position in measure()]
    except Exception:
        return None


def learn_by_repetition(
    controller, reference, make_rig, *, repetitions: int = 5, gain: float = 0.5, settle=SETTLE, **loop_options
) -> list:
    """Run ``reference`` ``repetitions`` times, each from rest on a fresh ``make_rig()`` (an
    object with ``measure`` and ``command``), each with a feedforward learned from the previous
    runs' camera-measured tip error: iterative learning control across repetitions, with the
    ILC floor's learning law through the model rod, or the identified one when
    ``calibration`` is among the loop options (``floor.correction``). The error is learnt with
    a weight that ramps in smoothly over ``settle`` (s; see SETTLE). The loop's own correction
    still acts within each run. Returns [(LoopRun, rig)] per repetition."""
    if not (isinstance(repetitions, int) and repetitions >= 1 and 0 < gain <= 1):
        raise ValueError(f"need an integer repetitions >= 1 and 0 < gain <= 1; got {repetitions!r}, {gain!r}")
    if not 0 <= settle[0] < settle[1]:
        raise ValueError(f"settle must be a window (start, end) in s with 0 <= start < end; got {settle!r}")
    sim = _rod(controller, loop_options.get("calibration"))
    learning = floor.learning_filter(sim, reference.n_steps) if repetitions > 1 else None  # a rollout: only if used
    ramp = np.clip((np.arange(1, reference.n_steps + 1) * DT - settle[0]) / (settle[1] - settle[0]), 0.0, 1.0)
    weight = (ramp * ramp * (3 - 2 * ramp))[:, None]  # smoothstep: no kink for the learning filter to ring on
    feedforward, runs = np.zeros((reference.n_steps, 2)), []
    for _ in range(repetitions):
        if runs:  # learn from the last run
            last = runs[-1][0]
            error = weight * (reference.states[1:, :3] - _measured_path(last.frames, reference.n_steps))
            feedforward = feedforward + gain * floor.correction(sim.static_table(), last.u, error, learning)
        rig = make_rig()
        runs.append(
            (run_loop(controller, reference, rig.measure, rig.command, feedforward=feedforward, **loop_options), rig)
        )
    return runs


def _measured_path(frames, n_steps: int) -> np.ndarray:
    """Tip positions at samples 1..n_steps, interpolated between the frames that found the marker."""
    taken = np.array([t for t, p in frames if np.all(np.isfinite(p))])
    seen = np.array([p for t, p in frames if np.all(np.isfinite(p))])
    times = np.arange(1, n_steps + 1) * DT
    return np.stack([np.interp(times, taken, seen[:, k]) for k in range(3)], -1)
