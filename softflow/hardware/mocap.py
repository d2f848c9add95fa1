"""The twin behind a real rig's faults, for the loop of a model of recorded runs: motor commands
that act ``delay`` s after they are sent, and a motion-capture camera at the commands' rate that
sees the tip with noise, sometimes holds its last value and sometimes loses the marker.

``read()`` and ``send(u)`` (motor commands in mm, as the recordings give them) are the plant
interface of ``examples/run_loop.py``, for B rigs at once; ``record_runs`` writes runs of random
actuation from it as recordings (docs/recordings.md: a row per period, the frame taken just
before the command of that row was sent, as the ASL trunk's logger writes them)."""

from __future__ import annotations

import math
from collections import deque
from pathlib import Path

import numpy as np
import pandas as pd

from softflow.data.excitation import polynomial_excitation
from softflow.hardware.commands import cable_commands
from softflow.hardware.gap import RealityGap
from softflow.hardware.plant import CablePlant
from softflow.hardware.recorder import TIP_COLUMNS, motor_columns, run_path
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT, Robot
from softflow.store import write_text

DELAY = 0.2  # s: from a command sent to the motors acting on it (a serial bus, a motor driver's buffer)
NOISE = 2e-4  # m: the camera's noise per coordinate
HELD = 0.01  # share of frames the tracker holds (the last value repeated)
LOST = 0.01  # share of frames without the marker (NaN)
MM = 1e-3  # m per mm


class MocapRig:
    """B twins of ``robot`` across ``gap``, each behind the same faults (``DELAY``, ``NOISE``,
    ``HELD``, ``LOST``), from rest; the true tip states (B, 6) of every period are kept in ``states``."""

    def __init__(
        self,
        gap: RealityGap,
        *,
        robot: Robot = HW_ROBOT,
        gravity: str = "vertical",
        batch: int = 1,
        delay: float = DELAY,
        noise: float = NOISE,
        held: float = HELD,
        lost: float = LOST,
        seed: int = 0,
    ):
        for name, value in dict(delay=delay, noise=noise).items():
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a number >= 0; got {value!r}")
        if not (0 <= held < 1 and 0 <= lost < 1 and held + lost < 1):
            raise ValueError(f"held and lost must be shares of the frames summing below 1; got {held!r}, {lost!r}")
        self.plant = CablePlant(robot, gravity, gap)
        self.plant.reset(batch)
        self.rest = MM**-1 * self.plant.motor.copy()  # (B, C) mm: the commands that hold the rest pose
        self.queue = deque([self.rest] * int(round(delay / DT)))  # commands sent, not yet acting
        self.noise, self.held, self.lost = noise, held, lost
        self.rng = np.random.default_rng(seed)
        self.frame = None
        self.states = [self.plant.tip_state()]  # (B, 6) per period

    def read(self) -> np.ndarray:
        """The newest frame (B, 3) in m: the tip now, with noise; held or lost as the camera does."""
        draw = self.rng.random(len(self.rest))
        tip = self.states[-1][:, :3]
        frame = tip + self.noise * self.rng.standard_normal(tip.shape)
        if self.frame is not None:
            frame = np.where((draw < self.held)[:, None], self.frame, frame)
        frame[(draw >= self.held) & (draw < self.held + self.lost)] = np.nan
        self.frame = np.where(np.isfinite(frame), frame, self.frame if self.frame is not None else np.nan)
        return frame

    def send(self, commands) -> None:
        """Send motor commands (B, C) in mm; the plant moves one period on the command sent
        ``delay`` earlier."""
        self.queue.append(np.asarray(commands, float).reshape(self.rest.shape))
        self.plant.step(MM * self.queue.popleft())
        self.states.append(self.plant.tip_state())


def record_runs(folder, n_runs: int, seconds: float, gap: RealityGap, *, seed: int = 0, **rig_options) -> list[Path]:
    """Record ``n_runs`` runs of ``seconds`` s of random actuation (the training family's
    polynomial tensions, made into motor commands through the model rod) on a ``MocapRig``
    across ``gap``, all at once, into ``folder`` (run0000.csv, ...; files already there are
    kept: a run depends on (seed, n_runs) alone). Returns the paths."""
    paths = [run_path(folder, run) for run in range(n_runs)]
    if all(path.is_file() for path in paths):
        return paths
    rig = MocapRig(gap, batch=n_runs, seed=seed, **rig_options)
    model = Simulator(rig.plant.robot, rig.plant.sim.gravity)
    steps = int(round(seconds / DT))
    rng = np.random.default_rng(seed)
    u = polynomial_excitation(n_runs, steps, rng, n_inputs=model.robot.n_inputs)  # (B, T, m) N
    commands = MM**-1 * cable_commands(u, model)  # (B, T, C) mm, as the plant takes them
    frames = []
    for t in range(steps):
        frames.append(rig.read())
        rig.send(commands[:, t])
    frames.append(rig.read())
    frames = np.stack(frames, 1)  # (B, T+1, 3)
    for run, path in enumerate(paths):
        table = pd.DataFrame(frames[run], columns=list(TIP_COLUMNS))
        for c, name in enumerate(motor_columns(rig.plant.robot)):
            table.insert(c, name, np.append(commands[run, :, c], np.nan))
        table.insert(0, "time_s", np.arange(steps + 1) * DT)
        write_text(path, table.to_csv(index=False, float_format="%.6f"))
    return paths
