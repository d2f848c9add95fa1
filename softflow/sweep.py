"""Sweeps: a study's grid of independent cells (model, seed, condition, ...), one Dask task
per cell, each result row cached by the content key of what made it.

A rerun loads the cached rows and computes only the missing cells, so an interrupted sweep
resumes where it stopped; a cell that raises is reported by name while the others still
return. Rows are gathered into one tidy CSV, ``data/sweeps/<study>-<profile>.csv``.
Without a running cluster the cells run on a ``LocalCluster`` of single-threaded worker
processes; ``client=None`` runs them in this process, one after another (for debugging).
A new study is one entry in ``STUDIES``.
"""
from __future__ import annotations

import json
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd
import torch
from dask.system import CPU_COUNT
from distributed import Client, LocalCluster, as_completed
from tqdm import tqdm

from . import data, train
from .checks import check_choice
from .profiles import DATA_DIR, Profile, TrainConfig, get_profile
from .store import content_key, write_text

SWEEPS_DIR = DATA_DIR / "sweeps"  # cached rows, the study's datasets and models, result CSVs
DEVICES = ("auto", "cpu", "cuda", "mps")


@dataclass(frozen=True)
class Study:
    """A grid of cells and the function that turns one cell into measurements.

    ``cells(profile_name)``: JSON-able dicts, each naming its study, model, seed and condition.
    ``run_cell(cell, profile_name, device, workdir, key)``: a dict of JSON-able measurements
    that depends on nothing but its arguments (its row is cached by them). ``workdir`` is the
    study's folder, for files cells share (datasets) or own (name those by ``key``).
    ``version``: bump it when a change alters the numbers run_cell returns; every cached row
    of the study is then recomputed.
    """

    cells: Callable[[str], list[dict]]
    run_cell: Callable[[dict, str, str, Path, str], dict]
    version: int = 1


@dataclass(frozen=True)
class Failure:
    cell: dict
    error: str  # "ExceptionType: message"


@dataclass(frozen=True)
class SweepResult:
    csv: Path  # the rows that succeeded, in grid order
    rows: pd.DataFrame
    failures: list[Failure]
    cached: int  # rows loaded from the cache
    computed: int  # cells run (or attempted) this time


def resolve_device(name: str) -> str:
    """The torch device cells train on: "auto" is CUDA if present, else MPS (Apple), else CPU."""
    check_choice(name, "device", DEVICES)
    available = dict(cuda=torch.cuda.is_available(), mps=torch.backends.mps.is_available(), cpu=True)
    if name == "auto":
        return next(device for device, present in available.items() if present)
    if not available[name]:
        raise ValueError(f"device {name!r} is not available to torch {torch.__version__} on this machine")
    return name


@contextmanager
def connect(scheduler_file: str | None = None, scheduler: str | None = None, workers: int | None = None):
    """A Dask client of the running cluster behind ``scheduler_file`` or ``scheduler`` (an
    address such as tcp://host:8786); else of a new LocalCluster of ``workers`` single-threaded
    processes (default: one per core), closed on exit. Processes, not threads: training holds
    the GIL and torch runs best on one thread per core."""
    if scheduler_file and scheduler:
        raise ValueError("give a scheduler file or a scheduler address, not both")
    if workers is not None and (scheduler_file or scheduler):
        raise ValueError("workers sizes a new local cluster; a running cluster has its own workers")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers must be a positive integer (local worker processes); got {workers!r}")
    if scheduler_file or scheduler:
        with Client(scheduler, scheduler_file=scheduler_file) as client:
            yield client
        return
    with LocalCluster(n_workers=workers or CPU_COUNT, threads_per_worker=1, processes=True) as cluster, \
            Client(cluster) as client:
        yield client


def cell_key(study: str, cell: dict, profile_name: str, device: str) -> str:
    """What a cached row depends on: the cell, the profile, the study's version and whether
    it trained on a CPU or a GPU (GPU arithmetic differs in the last bits)."""
    spec = dict(cell=cell, profile=profile_name, version=STUDIES[study].version,
                device_class="cpu" if device == "cpu" else "gpu")
    return content_key(spec)


def run_sweep(study: str, profile_name: str, *, client: Client | None, device: str = "auto",
              root: Path | str | None = None, progress: bool = True) -> SweepResult:
    """Run every cell of ``study`` that has no cached row, on ``client``'s cluster (``None``:
    here, one after another), and write the tidy CSV of all rows.

    ``root``: the sweep cache (default ``data/sweeps``). ``device`` is resolved where the
    cells run (on a worker of the cluster). A failing cell becomes a ``Failure`` in the result;
    the rows of the others are cached and written.
    """
    check_choice(study, "study", STUDIES)
    get_profile(profile_name)
    root = Path(SWEEPS_DIR if root is None else root)
    workdir = root / study
    device = resolve_device(device) if client is None else client.submit(resolve_device, device, pure=False).result()
    cells = STUDIES[study].cells(profile_name)
    keys = [cell_key(study, cell, profile_name, device) for cell in cells]
    if len(set(keys)) != len(keys):
        raise ValueError(f"study {study!r} yields duplicate cells for profile {profile_name!r}")

    rows = {key: row for key in keys if (row := _cached_row(workdir / f"{key}.json")) is not None}
    missing = [(key, cell) for key, cell in zip(keys, cells) if key not in rows]
    failures = []
    bar = tqdm(total=len(cells), initial=len(rows), desc=f"sweep {study}", unit="cell", disable=not progress)
    for key, cell, outcome in _outcomes(study, missing, profile_name, device, workdir, client):
        if isinstance(outcome, Exception):
            failures.append(Failure(cell, f"{type(outcome).__name__}: {outcome}"))
        else:
            write_text(workdir / f"{key}.json", outcome)
            rows[key] = json.loads(outcome)
        bar.update(1)
    bar.close()

    table = pd.DataFrame([rows[key] for key in keys if key in rows])
    csv = root / f"{study}-{profile_name}.csv"
    write_text(csv, table.to_csv(index=False))
    return SweepResult(csv, table, failures, cached=len(cells) - len(missing), computed=len(missing))


def _cached_row(path: Path) -> dict | None:
    """A cached row, or None when it is missing or unreadable (then the cell runs again)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _outcomes(study: str, missing, profile_name: str, device: str, workdir: Path, client: Client | None):
    """(key, cell, row JSON or the exception it raised) for each missing cell, as each finishes."""
    run_cell = STUDIES[study].run_cell
    if client is None:
        for key, cell in missing:
            try:
                yield key, cell, _row(run_cell, cell, profile_name, device, workdir, key)
            except Exception as error:
                yield key, cell, error
        return
    # A cell that raises gets two more tries (a busy node's out-of-memory error, say); one whose
    # worker dies is rescheduled by the scheduler. Either way its model resumes from its last epoch.
    futures = {client.submit(_row, run_cell, cell, profile_name, device, workdir, key, key=f"{study}-{key}",
                             retries=2, pure=False): (key, cell) for key, cell in missing}
    for future in as_completed(futures):
        key, cell = futures[future]
        try:
            yield key, cell, future.result()
        except Exception as error:
            yield key, cell, error
        future.release()


def _row(run_cell, cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> str:
    """One cell's row as JSON text, made where the cell runs: a row that is not JSON-able
    fails its own cell, and a fresh row reads back exactly like a cached one."""
    measured = run_cell(cell, profile_name, device, workdir, key)
    fields = {**cell, "profile": profile_name, "device": device, "key": key}
    if clash := sorted(set(measured) & set(fields)):
        raise ValueError(f"run_cell returned columns {clash} that name the cell")
    return json.dumps({**fields, **measured})


# ---------------------------------------------------------------------------- studies
SMOKE_DATA = Profile("smoke", n_episodes=20, episode_seconds=1.0)  # 16 / 2 / 2 episodes: train / val / test


def _smoke_cells(profile_name: str) -> list[dict]:
    return [dict(study="smoke", model="mlp", hidden=16, seed=seed, condition="tiny") for seed in (0, 1)]


def _smoke_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> dict:
    """A tiny MLP on a tiny dataset, scored per step on the test episodes: seconds per cell,
    the same for every profile (it tries the machinery, not the science)."""
    dataset = data.load_dataset(SMOKE_DATA, data_dir=workdir / "data", progress=False)  # shared; safe to race
    config = TrainConfig(epochs=2, steps_per_epoch=20, batch_size=64, warmup_steps=5, val_samples=200,
                         seed=cell["seed"])
    model, checkpoint = train.train(cell["model"], dataset, config, workdir / "models" / f"{key}.pt",
                                    model_kwargs={"hidden": cell["hidden"]}, device=device, progress=False)
    n_steps = dataset.u.shape[1]
    episodes, steps = np.repeat(dataset.test, n_steps), np.tile(np.arange(n_steps), len(dataset.test))
    window = torch.as_tensor(train.gather_windows(dataset.states, episodes, steps, model.context), dtype=torch.float32)
    with torch.no_grad():
        u_hat = model.predict(window).numpy()
    return dict(best_val=float(checkpoint["best_val"]), epochs_run=int(checkpoint["epochs_run"]),
                u_rmse=float(np.sqrt(np.mean((u_hat - dataset.u[episodes, steps]) ** 2))))


STUDIES = {
    "smoke": Study(_smoke_cells, _smoke_run),
}
