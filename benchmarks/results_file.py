"""Where every benchmark leaves its numbers: figures/bench/<name>.csv (committed), one row per
measured quantity, each with the machine, the date and the commit it was measured on, so every
speed the README quotes comes from a file anyone can regenerate with ``make bench``."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from softflow.machine import description
from softflow.report.provenance import commit

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


def write_results(name: str, results: dict, measured: str | None = None) -> Path:
    """figures/bench/<name>.csv: quantity, value, machine, date (UTC), commit (``measured``: the
    commit measured where it is not this checkout's, e.g. a clone's)."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    stamp = dict(machine=description(), date=datetime.now(UTC).strftime("%Y-%m-%d"), commit=measured or commit())
    rows = [dict(quantity=k, value=v, **stamp) for k, v in _flat(results).items()]
    path = RESULTS / f"{name}.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    return path


def trained_controller(name: str, profile: str):
    """The controller of model ``name`` of a profile on the paper rod: the shipped weights for
    ``paper`` (what a user runs), else the profile's, trained first if missing."""
    from softflow import control, data, training
    from softflow.profiles import get_profile

    if profile == "paper":
        return control.load_controller(name)
    P = get_profile(profile)
    return control.Controller(training.ensure_trained(name, P, data.load_dataset(P, progress=False))[0], name)
