"""Where the results were measured: the machine, the commit and each notebook's wall time."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pandas as pd

from softflow.machine import description
from softflow.store import REPO, write_text

WALL_TIME_COLUMNS = ["minutes", "machine", "date", "commit"]
CODE = ("softflow", "notebooks", "Makefile", "environment.lock", "checkpoints")  # what decides the results


def recorded_wall_times(run_dir: Path, file: Path, running: str = "07") -> pd.DataFrame:
    """Minutes per notebook of its last timed run, with where it ran (columns minutes, machine,
    date, commit): the notebooks of this papermill run (``notebook_wall_times``) replace their
    rows of ``file`` (a CSV, written back), the others keep theirs. So a run of a few notebooks
    never drops the measured times of the rest, and each time says what it was measured on."""
    file, minutes = Path(file), notebook_wall_times(run_dir, running)
    kept = (
        pd.read_csv(file, index_col="notebook", dtype={"commit": str})
        if file.is_file()
        else pd.DataFrame(columns=WALL_TIME_COLUMNS)
    )
    if len(minutes):
        stamp = dict(machine=description(), date=pd.Timestamp.now(tz="UTC").strftime("%Y-%m-%d"), commit=commit())
        fresh = pd.DataFrame([dict(minutes=m, **stamp) for m in minutes], index=minutes.index)
        kept = pd.concat([kept.drop(fresh.index, errors="ignore"), fresh]).sort_index().rename_axis("notebook")
        write_text(file, kept.to_csv())
    return kept


def notebook_wall_times(run_dir: Path, running: str = "07") -> pd.Series:
    """Minutes per notebook of a papermill run (from each executed notebook's metadata), but
    the one numbered ``running`` (it runs last and has no duration yet)."""
    minutes = {}
    for path in sorted(Path(run_dir).glob("[0-9]*.ipynb")):
        if path.name.startswith(running):
            continue
        duration = json.loads(path.read_text()).get("metadata", {}).get("papermill", {}).get("duration")
        if duration is not None:
            minutes[path.name] = duration / 60
    return pd.Series(minutes, name="minutes", dtype=float)


def commit() -> str:
    """The git commit of the code ('+changes' when the code differs from it), or 'unknown'."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", *CODE],
            cwd=REPO,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+changes" if dirty else "")
