"""Sweeps: a study's grid of independent cells (model, seed, condition, ...), one Dask task
per cell, each cell's result rows cached by the content key of what made them.

A rerun loads the cached rows and computes only the missing cells, so an interrupted sweep
resumes where it stopped; a cell that raises is reported by name while the others still
return. Rows are gathered into one tidy CSV, ``data/sweeps/<study>-<profile>.csv``; they
also ship, as ``figures/sweeps/<study>-<profile>.csv``, and count as cached wherever their keys
match, so a fresh clone recomputes nothing (``shipped=False`` recomputes them): the paper rows
are the results, the ci rows what the ci notebooks show (``make test`` reads them; a test
recomputes one cell of each study against them). Without a running cluster the cells run on a
``LocalCluster`` of single-threaded worker processes; ``client=None`` runs them in this
process, one after another (for debugging). The studies themselves live in ``studies``.
"""

from __future__ import annotations

import json
import platform
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import torch
from dask.system import CPU_COUNT
from distributed import Client, LocalCluster, as_completed
from tqdm import tqdm

from softflow.checks import check_choice
from softflow.machine import cpu_model
from softflow.profiles import STUDY_PROFILES, get_profile
from softflow.store import DATA_DIR, REPO, content_key, write_text
from softflow.studies.catalogue import STUDIES

SWEEPS_DIR = DATA_DIR / "sweeps"  # cached rows, the study's datasets and models, result CSVs
SHIPPED_RESULTS = REPO / "figures" / "sweeps"  # every profile's rows, committed
DEVICES = ("auto", "cpu", "cuda", "mps")


@dataclass(frozen=True)
class Failure:
    cell: dict
    error: str  # "ExceptionType: message"


@dataclass(frozen=True)
class SweepResult:
    csv: Path  # the rows that succeeded, in grid order
    rows: pd.DataFrame  # one or more per cell
    failures: list[Failure]
    cached: int  # cells whose rows came from the cache
    computed: int  # cells run (or attempted) this time
    missing: int = 0  # cells without rows: failed, or not run (compute_missing=False)


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
    with (
        LocalCluster(n_workers=workers or CPU_COUNT, threads_per_worker=1, processes=True) as cluster,
        Client(cluster) as client,
    ):
        yield client


def cell_key(study: str, cell: dict, profile_name: str, device: str) -> str:
    """What a cached row depends on: the cell, the profile's name and the knobs that make its
    data (a changed dataset recomputes a row instead of serving one made on the old data), the
    resolved arguments and budgets of the cell's models, the study's version and whether it
    trained on a CPU or a GPU (GPU arithmetic differs in the last bits)."""
    profile = get_profile(profile_name)
    spec = dict(
        cell=cell,
        profile=profile_name,
        data=dict(profile.data_spec, identification_seconds=profile.identification_seconds),
        models=STUDIES[study].models(cell, profile_name),
        version=STUDIES[study].version,
        device_class="cpu" if device == "cpu" else "gpu",
    )
    return content_key(spec)


def run_sweep(
    study: str,
    profile_name: str,
    *,
    client: Client | None,
    device: str = "auto",
    root: Path | str | None = None,
    shipped: bool = True,
    progress: bool = True,
    compute_missing: bool = True,
    where: dict | None = None,
) -> SweepResult:
    """Run every cell of ``study`` that has no cached rows, on ``client``'s cluster (``None``:
    here, one after another), and write the tidy CSV of all rows.

    ``root``: the sweep cache (default ``data/sweeps``; only the default one reads and writes
    the shipped rows, and only with ``shipped``). ``device`` is resolved where the cells
    run (on a worker of the cluster). A failing cell becomes a ``Failure`` in the result; the
    rows of the others are cached and written. ``compute_missing=False`` only reads: the rows
    present (shipped and cached) in grid order, ``missing`` says how many cells have none, and
    nothing runs or is written (a notebook shows a study of hours that a cluster, or a sweep
    still running, computes; that sweep owns the CSVs). ``where``: compute only the cells whose
    fields take one of the given values ({field: [values]}, e.g. the cheap cells of a study of
    hours first); the CSV still holds every cell's rows present, and ``missing`` counts the rest.
    """
    check_choice(study, "study", STUDIES)
    check_choice(profile_name, "profile", STUDY_PROFILES)
    shipped_csv = SHIPPED_RESULTS / f"{study}-{profile_name}.csv" if root is None else None
    root = Path(SWEEPS_DIR if root is None else root)
    workdir = root / study
    device = resolve_device(device) if client is None else client.submit(resolve_device, device, pure=False).result()
    cells = STUDIES[study].cells(profile_name)
    keys = [cell_key(study, cell, profile_name, device) for cell in cells]
    if len(set(keys)) != len(keys):
        raise ValueError(f"study {study!r} yields duplicate cells for profile {profile_name!r}")

    csv = root / f"{study}-{profile_name}.csv"
    rows, stale = _shipped_rows(shipped_csv, keys) if shipped and shipped_csv is not None else ({}, set())
    if stale and compute_missing:
        warnings.warn(
            f"{shipped_csv} holds rows of {len(stale)} cells that are not cells of this grid (another grid, "
            "study version or key): it is left as it is, so none of them is lost; this sweep's rows go to "
            f"{csv}. Migrate their keys, or recompute (--recompute replaces "
            "it once every cell is computed).",
            stacklevel=2,
        )
        shipped_csv = None
    rows.update({key: cached for key in keys if (cached := _cached_rows(workdir / f"{key}.json")) is not None})
    missing = [(key, cell) for key, cell in zip(keys, cells) if key not in rows]
    if not compute_missing:
        return SweepResult(
            csv, _table(rows, keys), [], cached=len(cells) - len(missing), computed=0, missing=len(missing)
        )
    where = _checked_where(where, cells)
    todo = [(key, cell) for key, cell in missing if _selected(cell, where)]
    failures = []
    bar = tqdm(total=len(rows) + len(todo), initial=len(rows), desc=f"sweep {study}", unit="cell", disable=not progress)
    for key, cell, outcome in _outcomes(study, todo, profile_name, device, workdir, client):
        if isinstance(outcome, Exception):
            failures.append(Failure(cell, f"{type(outcome).__name__}: {outcome}"))
        else:
            write_text(workdir / f"{key}.json", outcome)
            rows[key] = json.loads(outcome)
            rows |= _finished_elsewhere(rows, keys, workdir)
            _write_tables(rows, keys, csv, shipped_csv, shipped)  # as they come: a long sweep can be committed
        bar.update(1)
    bar.close()
    elsewhere = _finished_elsewhere(rows, keys, workdir)  # since this sweep's last cell
    rows |= elsewhere
    table = _write_tables(rows, keys, csv, shipped_csv if elsewhere or not shipped else None, shipped)
    return SweepResult(
        csv,
        table,
        failures,
        cached=len(cells) - len(missing),
        computed=len(todo),
        missing=len(missing) - len(todo) + len(failures),
    )


def shipped_rows(study: str, profile_name: str) -> pd.DataFrame:
    """The rows of ``study`` that ship with the repository (``figures/sweeps/<study>-<profile>.csv``),
    or an empty frame: what a notebook shows of another notebook's study without depending on
    what this machine has computed."""
    check_choice(study, "study", STUDIES)
    csv = SHIPPED_RESULTS / f"{study}-{get_profile(profile_name).name}.csv"
    return pd.read_csv(csv) if csv.exists() else pd.DataFrame()


def _checked_where(where: dict | None, cells: list[dict]) -> dict:
    """``where`` ({field: values}) with each field one that the study's cells have; else ValueError."""
    fields = {name for cell in cells for name in cell}
    if unknown := sorted(set(where or {}) - fields):
        raise ValueError(f"where: no cell of this study has the field(s) {unknown}; expected some of {sorted(fields)}")
    return where or {}


def _selected(cell: dict, where: dict) -> bool:
    """Whether ``cell`` takes one of the given values in every field of ``where``; values compare
    as text, so a command line's "60" picks runs=60."""
    return all(str(cell.get(field)) in {str(value) for value in values} for field, values in where.items())


def _write_tables(rows: dict, keys, csv: Path, shipped_csv: Path | None, shipped: bool) -> pd.DataFrame:
    """The rows so far in grid order, written to the CSV and to the shipped CSV, which is
    replaced only by a superset: these rows include its rows unless the sweep recomputes them
    (shipped=False) and has not finished."""
    table = _table(rows, keys)
    write_text(csv, table.to_csv(index=False))
    if shipped_csv is not None and len(table) and (shipped or len(rows) == len(keys)):
        write_text(shipped_csv, table.to_csv(index=False))
    return table


def _finished_elsewhere(rows: dict, keys, workdir: Path) -> dict:
    """The cached rows of cells that another sweep of the same cache (``--where`` on disjoint
    cells, in another process) finished after this one read the cache: the CSVs this one writes
    hold them too, so the last sweep to finish does not drop the others' rows."""
    return {key: cached for key in keys if key not in rows and (cached := _cached_rows(workdir / f"{key}.json"))}


def _table(rows: dict, keys) -> pd.DataFrame:
    """The rows of the cells in ``keys`` that have some, in grid order (no columns without rows)."""
    return pd.DataFrame([row for key in keys for row in rows.get(key, [])])


def _cached_rows(path: Path) -> list[dict] | None:
    """A cell's cached rows, or None when they are missing or unreadable (then it runs again)."""
    try:
        rows = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return rows if isinstance(rows, list) else None


def _shipped_rows(csv: Path, keys) -> tuple[dict, set]:
    """{key: rows} of the shipped CSV's cells that are in ``keys``, every row with all of the
    CSV's columns in its order, so that the rows written back keep it; and the keys of its
    other cells (an older grid or version: never served, and never dropped by a rewrite)."""
    if not csv.exists():
        return {}, set()
    table = pd.read_csv(csv, dtype={"key": str})
    known = table["key"].isin(keys)
    rows = {key: group.to_dict("records") for key, group in table[known].groupby("key", sort=False)}
    return rows, set(table.loc[~known, "key"])


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
    futures = {
        client.submit(
            _row, run_cell, cell, profile_name, device, workdir, key, key=f"{study}-{key}", retries=2, pure=False
        ): (key, cell)
        for key, cell in missing
    }
    for future in as_completed(futures):
        key, cell = futures[future]
        try:
            yield key, cell, future.result()
        except Exception as error:
            yield key, cell, error
        future.release()


def _row(run_cell, cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> str:
    """One cell's rows as JSON text (a list), made where the cell runs: rows that are not
    JSON-able fail their own cell, and fresh rows read back exactly like cached ones. Each row
    carries the cell's wall time (``cell_seconds``, what sizes a study for a cluster) and the CPU
    that computed it (``machine``)."""
    start = time.perf_counter()
    measured = run_cell(cell, profile_name, device, workdir, key)
    fields = {
        **cell,
        "profile": profile_name,
        "device": device,
        "key": key,
        "cell_seconds": round(time.perf_counter() - start, 1),
        "machine": cpu_model() or platform.machine(),  # rows made on several machines say which made each
    }
    rows = [measured] if isinstance(measured, dict) else list(measured)
    if clash := sorted({name for row in rows for name in row} & set(fields)):
        raise ValueError(f"run_cell returned columns {clash} that name the cell")
    return json.dumps([{**fields, **row} for row in rows])
