"""Where the results were measured: the machine, the commit and each notebook's wall time."""

from __future__ import annotations

import json
import os
import platform
import subprocess
from pathlib import Path

import pandas as pd

from softflow.store import REPO

CODE = ("softflow", "notebooks", "Makefile", "environment.lock", "checkpoints")  # what decides the results


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


def machine() -> str:
    """One line about the machine the results were measured on."""
    memory = ""
    if Path("/proc/meminfo").exists():
        kib = int(Path("/proc/meminfo").read_text().split()[1])
        memory = f", {kib / 2**20:.0f} GiB memory"
    return (
        f"{platform.machine()} {platform.processor() or ''}".strip() + f", {os.cpu_count()} cores{memory}, "
        f"Python {platform.python_version()}, {platform.system()}"
    )


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
