"""Motor commands: made from planned tensions through the model rod, and written to and read
from the files a motor controller replays.

The model is driven by differential tensions u, the robot by motors that hold cable
positions, so commands are made *through the model*: the tension-driven twin's rod shape
gives each cable's path-length change Delta_c(q) (``cables.cable_displacements``), and a
cable of stiffness k carries k (l_c + Delta_c(q)) when its motor has pulled in l_c. To
produce the planned tensions T_c(u) (u split over the cables above a pretension,
``cables.cable_tensions``) the motor pulls in l_c = T_c / k - Delta_c(q), with Delta_c
averaged over the control step (``cable_commands`` for a plan, ``StepCommands`` for a loop).

Command files (CSV, for a motor controller replaying at 100 Hz): header
``time_s,l1_mm,l2_mm,l3_mm``, one row per 0.01 s; l_c is the cable length pulled in by
motor c (mm) relative to the slack-free straight rod; cables in the order of
``robot.cable_angles`` (cable 1 at +y, then 120 degree steps towards +z).

Recordings of a real run (``load_recording``): a marker CSV ``time_s,x_m,y_m,z_m`` in the
robot frame, or an RGB-D ``.npz`` in the ``vision.write_rgbd`` format, tracked here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from softflow.checks import as_real_array
from softflow.hardware import vision
from softflow.rod.cables import cable_displacements, cable_tensions
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT
from softflow.store import write_text

CABLE_STIFFNESS = 1000.0  # N/m, line + guides + motor mount in series (assumed; docs/assumptions.md)
PRETENSION = 1.0  # N, the slackest cable's tension: keeps every cable taut


def cable_commands(
    u, sim: Simulator, stiffness: float = CABLE_STIFFNESS, pretension: float = PRETENSION, lead: float = 0.0
):
    """Planned actuation (B, T, 2) -> motor commands (B, T, C) in m, through the tension-driven
    model ``sim`` (the rod shape it predicts for the plan). ``lead`` (s): each command leads
    by that much of its rate of change, undoing a motor lag of that time constant."""
    u, _ = as_real_array(u, "u", (None, None, 2))
    _check_cables(stiffness, lead)
    B, T, _ = u.shape
    q, _ = sim.integrate(u, sim.rest_q(), np.zeros(sim.nq))
    delta = cable_displacements(sim.bend_angles(q.reshape(-1, sim.nq)), sim.robot).reshape(B, T + 1, -1)
    tensions = cable_tensions(u.reshape(-1, 2), sim.robot, pretension).reshape(B, T, -1)
    commands = tensions / stiffness - 0.5 * (delta[:, :-1] + delta[:, 1:])
    rest = np.broadcast_to(rest_command(sim, stiffness, pretension), (B, 1, commands.shape[2]))
    return commands + lead / DT * np.diff(commands, axis=1, prepend=rest)


def rest_command(sim: Simulator, stiffness: float = CABLE_STIFFNESS, pretension: float = PRETENSION) -> np.ndarray:
    """The motor commands (C,) in m that hold ``sim``'s rod at rest with every cable at its pretension."""
    return pretension / stiffness - cable_displacements(sim.bend_angles(sim.rest_q()[None]), sim.robot)[0]


def _check_cables(stiffness: float, lead: float):
    if not stiffness > 0:
        raise ValueError(f"stiffness must be positive; got {stiffness!r}")
    if not (np.isfinite(lead) and lead >= 0):
        raise ValueError(f"lead must be a finite time >= 0 s; got {lead!r}")


class StepCommands:
    """Motor commands one control step at a time, for a loop: ``commands(u)`` (2,) -> (C,) in
    m, through the model rod ``sim`` integrated alongside, exactly as ``cable_commands`` turns
    a whole plan (the cable path change averaged over the step, the same ``lead``)."""

    def __init__(
        self, sim: Simulator, stiffness: float = CABLE_STIFFNESS, pretension: float = PRETENSION, lead: float = 0.0
    ):
        _check_cables(stiffness, lead)
        self.sim, self.stiffness, self.pretension, self.lead = sim, stiffness, pretension, lead
        self.q, self.qd = sim.rest_q()[None], np.zeros((1, sim.nq))
        self.last = rest_command(sim, stiffness, pretension)

    def __call__(self, u) -> np.ndarray:
        u, _ = as_real_array(np.reshape(u, (1, 1, 2)), "u", (1, 1, 2))
        q, qd = self.sim.integrate(u, self.q, self.qd)
        delta = cable_displacements(self.sim.bend_angles(q[0]), self.sim.robot)  # (2, C): the step's ends
        self.q, self.qd = q[:, -1], qd[:, -1]
        command = cable_tensions(u[0], self.sim.robot, self.pretension)[0] / self.stiffness - 0.5 * (
            delta[0] + delta[1]
        )
        led, self.last = command + self.lead / DT * (command - self.last), command
        return led


def write_commands(path, commands, dt: float = DT):
    """Motor commands (T, C) in m -> the CSV a motor controller replays (format: module docstring)."""
    commands, _ = as_real_array(commands, "commands", (None, None))
    frame = pd.DataFrame(1e3 * commands, columns=[f"l{c + 1}_mm" for c in range(commands.shape[1])])
    frame.insert(0, "time_s", np.arange(len(commands)) * dt)
    write_text(Path(path), frame.to_csv(index=False, float_format="%.4f"))


def read_commands(path) -> np.ndarray:
    """A command CSV -> (T, C) in m."""
    frame = _read_csv(Path(path), "time_s")
    columns = [c for c in frame.columns if c.startswith("l") and c.endswith("_mm")]
    if not columns:
        raise ValueError(f"{path}: expected columns time_s,l1_mm,l2_mm,...; got {list(frame.columns)}")
    return 1e-3 * frame[columns].to_numpy(float)


def write_marker_csv(path, times, positions):
    """A marker track (K,) times and (K, 3) robot-frame positions -> the recording CSV format."""
    positions, _ = as_real_array(positions, "positions", (len(times), 3))
    frame = pd.DataFrame(positions, columns=["x_m", "y_m", "z_m"])
    frame.insert(0, "time_s", np.asarray(times, float))
    write_text(Path(path), frame.to_csv(index=False, float_format="%.6f"))


def load_recording(path):
    """A run of a real (or twin) robot -> (times (K,), marker positions (K, 3)) in the robot
    frame: a marker CSV as is, an RGB-D .npz through the same tracking as the twin. Times
    must be finite and strictly increasing; a bad file is a ValueError naming it (and the
    data row, counted from 1 below the header)."""
    path = _existing_file(path)
    if path.suffix == ".npz":
        times, frames, camera = vision.read_rgbd(path)
        times = np.asarray(times, float)
        _check_increasing(path, "times", times)
        return times, vision.track(frames, camera)
    frame = _read_csv(path, "time_s")
    missing = {"x_m", "y_m", "z_m"} - set(frame.columns)
    if missing:
        raise ValueError(f"{path}: expected columns time_s,x_m,y_m,z_m; missing {sorted(missing)}")
    return frame.time_s.to_numpy(float), frame[["x_m", "y_m", "z_m"]].to_numpy(float)


def _existing_file(path) -> Path:
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a directory; expected a recording or command file")
    if not path.is_file():
        raise ValueError(f"no such file: {path}")
    return path


def _read_csv(path: Path, first: str) -> pd.DataFrame:
    """A CSV of finite numbers whose column ``first`` (time) increases strictly."""
    path = _existing_file(path)
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as error:
        raise ValueError(f"{path} is not a readable CSV: {error}") from error
    if first not in frame.columns:
        raise ValueError(f"{path}: expected a '{first}' column; got {list(frame.columns)}")
    if frame.empty:
        raise ValueError(f"{path}: has a header but no samples")
    for column in frame.columns:
        values = pd.to_numeric(frame[column], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise ValueError(
                f"{path}: data row {bad[0] + 1}, column {column!r}: '{frame[column].iloc[bad[0]]}' "
                f"is not a finite number"
            )
        frame[column] = values
    _check_increasing(path, first, frame[first].to_numpy())
    return frame


def _check_increasing(path: Path, name: str, times: np.ndarray):
    """Time must run forwards without repeats: a recording's samples are in order."""
    backwards = np.flatnonzero(np.diff(times) <= 0)
    if len(backwards):
        row = backwards[0] + 2  # data rows from 1: the second of the offending pair
        raise ValueError(
            f"{path}: {name} must increase strictly; data row {row} ({times[row - 1]:g}) does not "
            f"follow row {row - 1} ({times[row - 2]:g})"
        )
