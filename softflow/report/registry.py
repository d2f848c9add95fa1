"""Which committed result files are made from the studies' shipped rows alone, and by what: each
entry names the studies whose rows it reads and the function that turns them into the table a
notebook writes. A test regenerates every entry from `figures/sweeps/` and fails where a committed
file differs, so a table cannot go stale behind the rows it claims to show."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pandas as pd

from softflow.profiles import Profile
from softflow.report import study_tables
from softflow.report.tables import read_sweep
from softflow.studies import one_step, trunk


@dataclass(frozen=True)
class StudyTable:
    """A table made from the rows of ``studies`` (in that order) by ``make``; ``index``: whether
    the notebook writes the frame's index."""

    studies: tuple[str, ...]
    make: Callable[..., pd.DataFrame]
    index: bool = True


def _part(summarise: Callable, name: str) -> Callable:
    return lambda rows: summarise(rows)[name]


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
    for suffix in ("", "_paper"):  # notebooks 14 and 15 write their paper tables under both names
        for name in ("judged", "judge_check", "flow_rule", "per_step", "spread"):
            files[f"14_{name}{suffix}.csv"] = StudyTable(("trunk",), _part(trunk.summarise, name))
        for name in ("rmse", "parity", "tip_win", "collapse"):
            files[f"15_one_step_{name}{suffix}.csv"] = StudyTable(
                ("one_step",), _part(one_step.summarise, name), index=False
            )
    return files


FILES = _per_study_files()


def regenerate(name: str, profile: Profile) -> pd.DataFrame:
    """The table of the registered file ``name`` made anew from ``profile``'s shipped rows."""
    if name not in FILES:
        raise ValueError(f"{name!r} is not a registered result file; expected one of {sorted(FILES)}")
    entry = FILES[name]
    return entry.make(*(read_sweep(profile, study) for study in entry.studies))
