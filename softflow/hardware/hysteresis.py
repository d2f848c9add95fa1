"""The hysteresis loop cable friction leaves in the twin (notebook 13): u1 cycled slowly on the
plant, the tip's lateral position against it, with the effects of the cycle's rate removed."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from softflow.hardware.commands import cable_commands
from softflow.hardware.gap import RealityGap
from softflow.hardware.plant import CablePlant
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT, U_MAX, Robot

LOOP_PERIOD = 20.0  # s, the slower of hysteresis_loop's two cycles (10 s rings the rod: docs/assumptions.md)


@dataclass(frozen=True)
class HysteresisLoop:
    """The plant's tip against a slowly cycled input (``hysteresis_loop``): what friction leaves
    of the cycle once the effects of its rate are removed."""

    u: np.ndarray  # (K,) N, the inputs where the branches are compared
    gap: np.ndarray  # (K,) down minus up branch, lateral tip, rate effects removed, fraction of the reach
    width: float  # the largest |gap|: the loop's width as a fraction of the reach
    reach: float  # m, half the tip's lateral span over the slower cycle
    down: np.ndarray  # (T, 2): u (N) and lateral tip (m) along the slower cycle's down branch
    up: np.ndarray  # (T, 2): the same along its up branch


def _branch_run(period: float, sign: float, n_steps: int, u_max: float) -> np.ndarray:
    """One input (T,) N: from 0 to sign u_max over period / 2, then to -sign u_max over the next
    half (the branch), each a half cosine (no jump in rate, so the rod is barely set ringing),
    then held."""
    t = np.arange(n_steps) * DT
    half = period / 2
    approach = sign * u_max * (1 - np.cos(np.pi * np.minimum(t, half) / half)) / 2
    branch = sign * u_max * np.cos(np.pi * np.clip(t - half, 0.0, half) / half)
    return np.where(t < half, approach, branch)


@functools.lru_cache(maxsize=4)
def _loop_commands(robot: Robot, gravity: str, period: float, u_max: float):
    """The four runs of ``hysteresis_loop``, u (4, T, 2) and motor commands (4, T, C), kept for
    the next gap (they depend on the model rod only, and cost as much as a replay)."""
    n_steps = int(round(period / DT)) + 1
    u = np.zeros((4, n_steps, 2))  # (4, T, 2): rods (period / 2: down, up; period: down, up)
    for rod, (cycle, sign) in enumerate([(period / 2, 1.0), (period / 2, -1.0), (period, 1.0), (period, -1.0)]):
        u[rod, :, 0] = _branch_run(cycle, sign, n_steps, u_max)
    commands = cable_commands(u, Simulator(robot, gravity))
    u.setflags(write=False)
    commands.setflags(write=False)
    return u, commands


def hysteresis_loop(
    gap: RealityGap,
    *,
    robot: Robot = HW_ROBOT,
    gravity: str = "vertical",
    period: float = LOOP_PERIOD,
    u_max: float = U_MAX,
) -> HysteresisLoop:
    """The loop the plant across ``gap`` draws when u1 is cycled over [-u_max, u_max] (u2 = 0),
    made into motor commands through the model rod (``cable_commands``), the tip's lateral y
    against u1: its width is the largest gap between the down and the up branch at the same u1,
    as a fraction of the reach (half the lateral span).

    Four rods in one batch: a down branch (0 -> u_max -> -u_max) and an up branch (0 -> -u_max
    -> u_max) at cycle periods ``period`` and ``period`` / 2. A lag tau (Kelvin-Voigt creep, motor
    lag) puts the branches tau du/dt apart, which halves when the period doubles, so the
    gap 2 g(period) - g(period / 2) keeps only what does not depend on the rate: the friction's.
    What is left of the rate, the rod's ringing, is 0.1-0.2 % of the reach at 20 s."""
    friction = gap.cable_friction
    return hysteresis_loops(gap, [friction], robot=robot, gravity=gravity, period=period, u_max=u_max)[friction]


def hysteresis_loops(
    gap: RealityGap,
    frictions,
    *,
    robot: Robot = HW_ROBOT,
    gravity: str = "vertical",
    period: float = LOOP_PERIOD,
    u_max: float = U_MAX,
) -> dict[float, HysteresisLoop]:
    """``hysteresis_loop`` of ``gap`` with each cable friction coefficient of ``frictions`` in
    its place: {mu: loop}, every plant in one batch (a replay costs per step, hardly per rod),
    each loop the one ``hysteresis_loop`` draws alone, bit for bit."""
    if robot.n_inputs != 2:
        raise ValueError(f"hysteresis_loop cycles u1 of a two-input rod; {robot.name!r} has {robot.n_inputs} inputs")
    if not (np.isfinite(period) and period >= 4 * DT and np.isfinite(u_max) and u_max > 0):
        raise ValueError(f"need a period of at least {4 * DT} s and u_max > 0 N; got {period!r} s, {u_max!r} N")
    frictions = [float(mu) for mu in frictions]
    if not frictions or len(set(frictions)) < len(frictions):
        raise ValueError(f"frictions must hold at least one coefficient, each once; got {frictions}")
    u, commands = _loop_commands(robot, gravity, float(period), float(u_max))  # (4, T, 2), (4, T, C)
    per_rod = np.repeat(frictions, len(commands))  # (4 F,): the four runs at each friction
    plant = CablePlant(robot, gravity, gap, cable_friction=per_rod)
    lateral = plant.replay(np.tile(commands, (len(frictions), 1, 1)))["states"][:, 1:, 1]  # (4 F, T), after each u_t
    return {mu: _loop(u, runs, period, u_max) for mu, runs in zip(frictions, np.split(lateral, len(frictions)))}


def _loop(u, lateral, period: float, u_max: float) -> HysteresisLoop:
    """The loop of the four runs' lateral tips (4, T) against their u1 (4, T, 2)."""
    grid = np.linspace(-u_max, u_max, 41)[1:-1]  # (K,) inside the turns, where the branches meet
    gaps, branches = [], []
    for first, cycle in ((0, period / 2), (2, period)):
        start, end = int(round(cycle / 2 / DT)), int(round(cycle / DT)) + 1
        down = np.stack([u[first, start:end, 0], lateral[first, start:end]], -1)  # (T', 2), u falling
        up = np.stack([u[first + 1, start:end, 0], lateral[first + 1, start:end]], -1)  # (T', 2), u rising
        gaps.append(np.interp(grid, *down[::-1].T) - np.interp(grid, *up.T))
        branches = [down, up]
    reach = float(np.ptp(lateral[2:])) / 2
    quasi_static = (2 * gaps[1] - gaps[0]) / reach  # (K,)
    return HysteresisLoop(grid, quasi_static, float(np.abs(quasi_static).max()), reach, *branches)
