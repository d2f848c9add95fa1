"""The twin as a recording rig: runs of random actuation, filmed, written as recordings
(docs/recordings.md) that ``softflow.recordings.load_dataset`` reads and the models train on.

Each run: a random polynomial u (``data.excitation.polynomial_excitation``, the training
family, one draw per run seeded by (seed, run)) is made into motor commands through the model
rod (``commands.cable_commands``, as the replay makes them), replayed from rest on the plant across
the gap (cable friction by default) and filmed by the twin's camera: every frame rendered and
its marker tracked (``twin.observe_run``, the open-loop replay's camera), at 30 fps. Frames
are stamped ``latency`` s after they were taken (0: a camera that stamps frames when taken); a
share ``dropped`` of them is lost, its row left with empty tip cells.

Runs are simulated eight at a time (runs 0-7, 8-15, ...: always the whole chunk, so a run's
numbers do not depend on which runs were already there), then filmed one by one.

File ``run0000.csv`` ... one per run, written whole or not at all (temp file + rename): rows in
time order, a command row every DT (``u1_N, u2_N``: the planned differential tensions;
``l1_mm, l2_mm, l3_mm``: the motor commands sent, cable pulled in per motor relative to the
slack-free straight rod, in ``robot.cable_angles`` order) and a frame row every 1/30 s
(``x_m, y_m, z_m``, the tracked tip in the robot frame). ``load_dataset(folder)`` trains on u;
``inputs=motor_columns(robot)`` on the motors. ``recorder.json`` in the folder holds the
settings: a rerun with the same ones skips the runs present and records the rest.
"""

from __future__ import annotations

import json
import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from softflow.data.excitation import polynomial_excitation
from softflow.hardware.commands import cable_commands
from softflow.hardware.gap import FRICTION_GAP, RealityGap
from softflow.hardware.plant import CablePlant
from softflow.hardware.twin import observe_run, twin_camera
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT, Robot
from softflow.store import write_text

RECORDER_VERSION = 1  # bump when a run's numbers or the file layout change
SETTINGS = "recorder.json"
CHUNK = 8  # runs simulated in one batch: runs 0-7, 8-15, ..., always all eight
TIP_COLUMNS = ("x_m", "y_m", "z_m")


def run_path(folder, run: int) -> Path:
    """Where run ``run`` is written: four digits, so the names sort in run order."""
    return Path(folder) / f"run{run:04d}.csv"


def input_columns(robot: Robot) -> list[str]:
    """The planned differential tensions, N: what ``load_dataset`` takes as inputs by default."""
    return [f"u{i + 1}_N" for i in range(robot.n_inputs)]


def motor_columns(robot: Robot) -> list[str]:
    """The motor commands, mm pulled in: pass as ``inputs=`` to train on what the motors were sent."""
    return [f"l{c + 1}_mm" for c in range(robot.n_cables)]


def record_runs(
    folder,
    n_runs: int,
    seconds: float,
    *,
    robot: Robot = HW_ROBOT,
    gravity: str,
    gap: RealityGap = FRICTION_GAP,
    seed: int = 0,
    latency: float = 0.0,
    dropped: float = 0.0,
    workers: int = 1,
    progress: bool = True,
) -> list[Path]:
    """Record ``n_runs`` runs of ``seconds`` s each on the twin of ``robot`` (the hardware rod:
    the twin's cables, camera and gap are made for it) mounted as ``gravity`` says, across
    ``gap``, into ``folder`` (format: module docstring). Resumable: runs already in the folder
    are kept and skipped, and each run depends only on (seed, run), so an interrupted call,
    rerun, writes the same files. ``workers`` > 1: the missing chunks are shared among that many
    processes of one thread each (the same files as one process writes; a script calls it under
    ``if __name__ == "__main__":``, as any process pool needs). Returns the paths of all
    ``n_runs`` files."""
    if not (isinstance(n_runs, (int, np.integer)) and not isinstance(n_runs, bool) and n_runs >= 1):
        raise ValueError(f"n_runs must be a whole number of runs >= 1; got {n_runs!r}")
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds >= 10 * DT):
        raise ValueError(f"seconds must be a run length of at least {10 * DT} s (ten commands); got {seconds!r}")
    if not isinstance(gap, RealityGap):
        raise ValueError(f"gap must be a RealityGap (e.g. FRICTION_GAP); got {type(gap).__name__}")
    if robot.n_inputs != 2:
        raise ValueError(f"the twin makes commands for two-input rods; {robot.name!r} has {robot.n_inputs} inputs")
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
        raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
    if not (isinstance(latency, (int, float)) and math.isfinite(latency) and latency >= 0):
        raise ValueError(f"latency must be a time >= 0 s; got {latency!r}")
    if not (isinstance(dropped, (int, float)) and 0 <= dropped < 1):
        raise ValueError(f"dropped must be a share of frames in [0, 1); got {dropped!r}")
    if not (isinstance(workers, (int, np.integer)) and not isinstance(workers, bool) and workers >= 1):
        raise ValueError(f"workers must be a whole number of processes >= 1; got {workers!r}")
    Simulator(robot, gravity)  # checks gravity
    folder = Path(folder)
    _claim(folder, settings(robot, gravity, gap, seconds, seed, latency, dropped))
    paths = [run_path(folder, run) for run in range(n_runs)]
    missing = [run for run, path in enumerate(paths) if not path.is_file()]
    rig = _Rig(folder, robot, gravity, gap, float(seconds), int(seed), float(latency), float(dropped))
    by_chunk = {}  # first run of a chunk: its missing runs, in order
    for run in missing:
        by_chunk.setdefault(run - run % CHUNK, []).append(run)
    chunks = list(by_chunk.values())
    with tqdm(total=n_runs, initial=n_runs - len(missing), desc="recording", unit="run", disable=not progress) as bar:
        if workers == 1 or len(chunks) < 2:
            for runs in chunks:
                bar.update(rig.record(runs))
        else:
            spawn = multiprocessing.get_context("spawn")  # no fork of a parent's threads
            with ProcessPoolExecutor(
                min(workers, len(chunks)), spawn, initializer=threadpool_limits, initargs=(1,)
            ) as pool:
                for done in as_completed([pool.submit(rig.record, runs) for runs in chunks]):
                    bar.update(done.result())
    return paths


def settings(robot: Robot, gravity: str, gap: RealityGap, seconds, seed, latency, dropped) -> dict:
    """What a folder's runs were recorded with, as its ``recorder.json`` claims it (through JSON,
    so tuples and lists compare equal): a rerun must ask for the same to add runs to it."""
    made = dict(
        version=RECORDER_VERSION,
        robot=robot.name,
        robot_parameters=robot.parameters(),
        gravity=gravity,
        gap=gap.parameters(),
        seconds=float(seconds),
        seed=int(seed),
        latency=float(latency),
        dropped=float(dropped),
        excitation="polynomial_excitation, degrees (1, 8), peaks (0.5, U_MAX) N",
    )
    return json.loads(json.dumps(made, default=str))


@dataclass(frozen=True)
class _Rig:
    """What a recording process needs to record runs of one folder (picklable, for workers)."""

    folder: Path
    robot: Robot
    gravity: str
    gap: RealityGap
    seconds: float
    seed: int
    latency: float
    dropped: float

    def record(self, runs: list[int]) -> int:
        """Simulate the chunk of ``runs`` (all in one chunk), film and write each; how many."""
        model = Simulator(self.robot, self.gravity)
        plant, camera = CablePlant(self.robot, self.gravity, self.gap), twin_camera(model, self.gap)
        first = runs[0] - runs[0] % CHUNK
        chunk = _simulate(range(first, first + CHUNK), model, plant, self.seconds, self.seed)
        for run in runs:
            table = _film(chunk[run - first], plant, camera, self.latency, self.dropped)
            write_text(run_path(self.folder, run), table.to_csv(index=False, float_format="%.6f"))
        return len(runs)


def _claim(folder: Path, wanted: dict) -> None:
    """Write the folder's settings, or check that it holds runs recorded with the same ones:
    runs of other settings are never mixed into one folder."""
    file = folder / SETTINGS
    if file.is_file():
        try:
            found = json.loads(file.read_text())
        except (OSError, ValueError) as error:
            raise ValueError(f"{file} is not a readable recorder settings file ({error})") from error
        if found != wanted:
            differ = sorted(k for k in wanted.keys() | found.keys() if wanted.get(k) != found.get(k))
            raise ValueError(
                f"{folder} holds runs recorded with other settings ({', '.join(differ)} differ: "
                f"{ {k: found.get(k) for k in differ} } there, { {k: wanted.get(k) for k in differ} } asked); "
                "record into another folder"
            )
        return
    if folder.is_dir() and any(folder.glob("*.csv")):
        raise ValueError(f"{folder} holds CSV files but no {SETTINGS}: record into an empty or a new folder")
    write_text(file, json.dumps(wanted, indent=1, sort_keys=True) + "\n")


def _simulate(runs, model, plant, seconds, seed) -> list[dict]:
    """The runs of one chunk, all of them, in one batch (the model rod's commands, the plant's
    replay): so a run's numbers never depend on which others were missing. Per run: its
    Generator (after the excitation's draw), u (T, 2), commands (T, C) m and rod q (T+1, nq)."""
    n_steps = int(round(seconds / DT))
    rngs = [np.random.default_rng([seed, run]) for run in runs]
    u = np.concatenate([polynomial_excitation(1, n_steps, rng, n_inputs=model.robot.n_inputs) for rng in rngs])
    commands = cable_commands(u, model)  # (B, T, C) m
    q = plant.replay(commands)["q"]  # (B, T+1, nq)
    return [dict(rng=rng, u=u[k], commands=commands[k], q=q[k]) for k, rng in enumerate(rngs)]


def _film(run: dict, plant, camera, latency, dropped) -> pd.DataFrame:
    """One simulated run filmed and tracked, as its table: command rows every DT, frame rows
    every 1/fps, in time order."""
    rng = run["rng"]
    frame_times, tip = observe_run(plant.sim, run["q"], camera, seed=int(rng.integers(2**32)))  # (K,), (K, 3)
    tip[rng.random(len(tip)) < dropped] = np.nan
    sent = pd.DataFrame(np.concatenate([run["u"], 1e3 * run["commands"]], -1), columns=_inputs(plant.robot))
    sent.insert(0, "time_s", np.arange(len(run["u"])) * DT)
    seen = pd.DataFrame(tip, columns=list(TIP_COLUMNS))
    seen.insert(0, "time_s", frame_times + latency)
    return pd.concat([sent, seen], ignore_index=True).sort_values("time_s", kind="stable", ignore_index=True)


def _inputs(robot: Robot) -> list[str]:
    return input_columns(robot) + motor_columns(robot)
