"""Which committed result files are made from the studies' shipped rows alone, and by what: each
entry names the studies whose rows it reads and the function that turns them into the table.
Notebooks make and write these tables only through ``written``, and a test regenerates every entry
from `figures/sweeps/` and fails where a committed file differs, so a table cannot go stale behind
the rows it claims to show."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pandas as pd

from softflow.profiles import Profile
from softflow.report import study_tables
from softflow.report.tables import read_sweep
from softflow.store import write_text
from softflow.studies import loop, one_step, trunk, trunk_v2


@dataclass(frozen=True)
class StudyTable:
    """A table made from the rows of ``studies`` (in that order) by ``make``, or, where ``part``
    names one, that part of the tables ``make`` returns (a study's ``summarise``); ``index``:
    whether the file holds the frame's index."""

    studies: tuple[str, ...]
    make: Callable[..., pd.DataFrame | dict[str, pd.DataFrame]]
    index: bool = True
    part: str | None = None


# study: (its summarise, the prefix of its files, the parts each is a file of, whether they hold the index)
SUMMARIES = {
    "trunk": (trunk.summarise, "14_", ("judged", "judge_check", "flow_rule", "per_step", "spread"), True),
    "trunk_v2": (
        trunk_v2.summarise,
        "14_v2_",
        ("judge_free", "per_input", "spread", "provenance", "floors", "resolution", "judged", "flow_rule"),
        True,
    ),
    "one_step": (one_step.summarise, "15_one_step_", ("rmse", "parity", "tip_win", "collapse"), False),
    "loop": (loop.summarise, "16_loop_", ("tracking", "rule"), False),
}


def _per_study_files() -> dict[str, StudyTable]:
    files = {
        "08_differences.csv": StudyTable(("table1",), study_tables.best_against_best),
        "09_data_size_effects.csv": StudyTable(("data_size",), study_tables.size_effects),
        "09_regime_map.csv": StudyTable(
            ("ambiguity", "two_segment"), lambda a, b: study_tables.regime_map(study_tables.regime_rows(a, b))
        ),
        "10_table3_extended.csv": StudyTable(("closed_loop",), study_tables.closed_loop_table),
        "11_fwd_lambda_decision.csv": StudyTable(("fwd_lambda",), lambda rows: study_tables.lambda_decision(rows)[0]),
        "12_table1.csv": StudyTable(("two_segment",), study_tables.two_segment_table),
        "12_differences.csv": StudyTable(("two_segment",), study_tables.two_segment_differences),
        "12_per_step.csv": StudyTable(("two_segment",), study_tables.two_segment_per_step),
        "12_spread.csv": StudyTable(("two_segment",), study_tables.two_segment_spread),
        "13_table.csv": StudyTable(("recorded",), study_tables.recorded_table),
        "13_recording_rule.csv": StudyTable(("recorded",), study_tables.recording_rule),
        "13_model_rule.csv": StudyTable(("recorded",), study_tables.recorded_model_rule),
        "13_spread.csv": StudyTable(("recorded",), study_tables.recorded_spread),
        "13_per_step.csv": StudyTable(("recorded",), study_tables.recorded_per_step),
    }
    for study, (summarise, prefix, parts, index) in SUMMARIES.items():
        for suffix in ("", "_paper"):  # notebooks 14 to 16 write their paper tables under both names
            for part in parts:
                files[f"{prefix}{part}{suffix}.csv"] = StudyTable((study,), summarise, index, part)
    return files


FILES = _per_study_files()


def _entries(names) -> list[StudyTable]:
    if unknown := [name for name in names if name not in FILES]:
        raise ValueError(f"{unknown} not a registered result file; expected some of {sorted(FILES)}")
    return [FILES[name] for name in names]


def _tables(names, rows) -> dict[str, pd.DataFrame]:
    """The registered tables ``names`` from ``rows`` ({study: its rows}); each ``make`` runs once."""
    made, tables = {}, {}  # (make, studies) -> what it returned
    for name, entry in zip(names, _entries(names)):
        key = (entry.make, entry.studies)
        if key not in made:
            made[key] = entry.make(*(rows[study] for study in entry.studies))
        tables[name] = made[key] if entry.part is None else made[key][entry.part]
    return tables


def regenerate(name: str, profile: Profile) -> pd.DataFrame:
    """The table of the registered file ``name`` made anew from ``profile``'s shipped rows."""
    (entry,) = _entries([name])
    return _tables([name], {study: read_sweep(profile, study) for study in entry.studies})[name]


def written(name: str, profile: Profile, *rows: pd.DataFrame) -> pd.DataFrame:
    """The registered table ``name`` made from ``rows`` (the rows of its studies, in the entry's
    order) and written under the profile's output folder, as a notebook shows and writes it: by
    construction what ``regenerate`` makes from the same rows."""
    (entry,) = _entries([name])
    if len(rows) != len(entry.studies):
        raise ValueError(f"{name} is made from the rows of {list(entry.studies)}; got {len(rows)} frames of rows")
    table = _tables([name], dict(zip(entry.studies, rows)))[name]
    _write(profile, name, table)
    return table


def written_summary(study: str, profile: Profile, rows: pd.DataFrame, suffix: str = "") -> dict[str, pd.DataFrame]:
    """``written`` for every part of a study's ``summarise`` (``SUMMARIES``), each in its file,
    ``summarise`` run once (``suffix``: "_paper" for the paper profile's tables beside a ci run's):
    {part: table}."""
    if study not in SUMMARIES:
        raise ValueError(f"study must be one of {sorted(SUMMARIES)}; got {study!r}")
    _, prefix, parts, _ = SUMMARIES[study]
    names = [f"{prefix}{part}{suffix}.csv" for part in parts]
    tables = _tables(names, {study: rows})
    for name in names:
        _write(profile, name, tables[name])
    return {part: tables[name] for part, name in zip(parts, names)}


def _write(profile: Profile, name: str, table: pd.DataFrame) -> None:
    write_text(profile.output_dir / name, table.to_csv(index=FILES[name].index))
