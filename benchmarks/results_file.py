"""Where every benchmark leaves its numbers: figures/bench/<name>.csv (committed), one row per
measured quantity, each with the machine, the date and the commit it was measured on, so every
speed the README quotes comes from a file anyone can regenerate with ``make bench``."""

from __future__ import annotations

import os
import platform
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from softflow.machine import cpu_model

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "figures" / "bench"


def _flat(results: dict, prefix: str = "") -> dict:
    """{"a": {"b": 1}} -> {"a.b": 1}: one quantity per leaf."""
    out = {}
    for key, value in results.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flat(value, f"{name}."))
        else:
            out[name] = value
    return out


def machine() -> str:
    memory = ""
    if Path("/proc/meminfo").exists():
        memory = f", {int(Path('/proc/meminfo').read_text().split()[1]) / 2**20:.0f} GiB"
    cpu = cpu_model()  # the same sandbox has come with CPUs of very different speeds: name the one measured
    named = f"{platform.machine()} ({cpu})" if cpu else platform.machine()
    return f"{named}, {os.cpu_count()} cores{memory}, Python {platform.python_version()}"


def commit() -> str:
    out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def write_results(name: str, results: dict) -> Path:
    """figures/bench/<name>.csv: quantity, value, machine, date (UTC), commit."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    stamp = dict(machine=machine(), date=datetime.now(UTC).strftime("%Y-%m-%d"), commit=commit())
    rows = [dict(quantity=k, value=v, **stamp) for k, v in _flat(results).items()]
    path = RESULTS / f"{name}.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    return path
