"""Every committed result file (figures/*.csv), what makes it and which notebook writes it.

A ``StudyTable`` is made from the studies' shipped rows alone: the entry names the studies whose
rows it reads and the function that turns them into the table; notebooks make and write these only
through ``write_table``, and a test regenerates every one from `figures/sweeps/` and fails where a
committed file differs, so a table cannot go stale behind the rows it claims to show. A
``Written`` file is one no test regenerates (rollouts of the shipped models, a simulation, a wall
time, or a notebook's own table that nothing in the report reads): the entry names its notebook
and what it is made from; a test checks that it is there and that its notebook writes it.
``writer`` answers from here which notebook to run for a file."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pandas as pd

from softflow.profiles import Profile
from softflow.report import study_tables
from softflow.report.tables import read_sweep
from softflow.store import write_text
from softflow.studies import loop, one_step, trunk, trunk_v2
from softflow.studies.catalogue import STUDIES


@dataclass(frozen=True)
class StudyTable:
    """A table made from the rows of ``studies`` (in that order) by ``make``, or, where ``part``
    names one, that part of the tables ``make`` returns (a study's ``summarise``); ``index``:
    whether the file holds the frame's index."""

    studies: tuple[str, ...]
    make: Callable[..., pd.DataFrame | dict[str, pd.DataFrame]]
    index: bool = True
    part: str | None = None
    writer: str = ""  # the notebook that writes it, where it is not its first study's

    @property
    def notebook(self) -> str:
        return self.writer or STUDIES[self.studies[0]].notebook


@dataclass(frozen=True)
class Written:
    """A file ``notebook`` writes that no test regenerates, and what it is made from: what a test
    cannot redo (rollouts, simulations, wall times), or a study's rows in a table of the notebook's
    own that nothing in the report reads (moving that code into ``study_tables`` would make it a
    ``StudyTable``)."""

    notebook: str
    made_from: str


ROLLOUTS = "rollouts of the shipped models in the simulator"
TIMED = "wall times measured as the notebook runs"
WRITTEN = {
    "results_baselines.csv": Written("03_baselines.ipynb", ROLLOUTS),
    "training_baselines.csv": Written("03_baselines.ipynb", "the shipped checkpoints' training logs"),
    "latency_baselines.csv": Written("03_baselines.ipynb", TIMED),
    "baseline_sizes.csv": Written("03_baselines.ipynb", ROLLOUTS + " (checkpoints/variants)"),
    "results_rf.csv": Written("04_rf_variants.ipynb", ROLLOUTS),
    "training_rf.csv": Written("04_rf_variants.ipynb", "the shipped checkpoints' training logs"),
    "euler_sweep.csv": Written("04_rf_variants.ipynb", f"{ROLLOUTS}, and {TIMED}"),
    **{
        f"stress_{name}.csv": Written("05_stress_tests.ipynb", ROLLOUTS)
        for name in ("burst", "burst_revolutions", "beyond_revolutions", "break_points", "complex3d", "uncertainty")
    },
    "stress_plan_choice.csv": Written("05_stress_tests.ipynb", ROLLOUTS),
    "twin_results.csv": Written("06_hardware_replay.ipynb", "the twin's camera runs of the shipped twin models"),
    "table3_twin.csv": Written("06_hardware_replay.ipynb", "the twin's camera runs of the shipped twin models"),
    **{
        f"{name}.csv": Written("07_comparison_tables.ipynb", "the result files above, beside the paper's numbers")
        for name in ("table1_tracking", "table2_inputs", "table3_hardware", "table4_literature")
    },
    "10_identified.csv": Written("10_closed_loop.ipynb", "a simulated identification run through the camera"),
    "11_fwd_lambda_diagnostics.csv": Written("11_consistency_weight.ipynb", "the fwd_lambda rows and forward.pt"),
    "12_checks.csv": Written("12_two_segment.ipynb", "the two-segment rod's simulated modes against closed forms"),
    "13_hysteresis.csv": Written("13_recorded_runs.ipynb", "the twin's simulated hysteresis loops"),
    "14_runs.csv": Written("14_real_robot.ipynb", "the ASL trunk's runs (datasets/asl_trunk/), read and smoothed"),
}


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
        "08_table1_ci.csv": StudyTable(("table1",), study_tables.table1_summaries),
        "08_table2_ci.csv": StudyTable(("table1",), study_tables.table2_ci),
        "08_protocol.csv": StudyTable(("protocol",), study_tables.protocol_table),
        "08_speed.csv": StudyTable(("protocol",), study_tables.speed_table),
        "design_sweep.csv": StudyTable(("design",), study_tables.design_table),
        "twin_sensitivity.csv": StudyTable(
            ("closed_loop",), study_tables.gap_sensitivity, writer="06_hardware_replay.ipynb"
        ),
        "08_differences.csv": StudyTable(("table1",), study_tables.best_against_best, index=False),
        "09_data_size.csv": StudyTable(("data_size",), study_tables.data_size_table),
        "09_data_size_per_step.csv": StudyTable(("data_size",), study_tables.data_size_per_step),
        "09_ambiguity_per_step.csv": StudyTable(("ambiguity",), study_tables.ambiguity_per_step),
        "09_ambiguity_tracking.csv": StudyTable(("ambiguity",), study_tables.ambiguity_tracking),
        "10_latency.csv": StudyTable(("closed_loop",), study_tables.latency_table),
        "10_gap_sensitivity.csv": StudyTable(("closed_loop",), study_tables.gap_modes_table),
        "10_burst_revolutions.csv": StudyTable(("twin_burst",), study_tables.burst_revolutions),
        "10_burst_breaks.csv": StudyTable(("twin_burst",), study_tables.burst_breaks),
        "11_fwd_lambda.csv": StudyTable(("fwd_lambda",), study_tables.lambda_table),
        "09_data_size_effects.csv": StudyTable(("data_size",), study_tables.size_effects, index=False),
        "09_regime_map.csv": StudyTable(
            ("ambiguity", "two_segment"),
            lambda a, b: study_tables.regime_map(study_tables.regime_rows(a, b)),
            index=False,
        ),
        "10_table3_extended.csv": StudyTable(("closed_loop",), study_tables.closed_loop_table),
        "11_fwd_lambda_decision.csv": StudyTable(
            ("fwd_lambda",), lambda rows: study_tables.lambda_decision(rows)[0], index=False
        ),
        "12_table1.csv": StudyTable(("two_segment",), study_tables.two_segment_table),
        "12_differences.csv": StudyTable(("two_segment",), study_tables.two_segment_differences, index=False),
        "12_per_step.csv": StudyTable(("two_segment",), study_tables.two_segment_per_step),
        "12_spread.csv": StudyTable(("two_segment",), study_tables.two_segment_spread),
        "13_table.csv": StudyTable(("recorded",), study_tables.recorded_table),
        "13_recording_rule.csv": StudyTable(("recorded",), study_tables.recording_rule, index=False),
        "13_model_rule.csv": StudyTable(("recorded",), study_tables.recorded_model_rule, index=False),
        "13_spread.csv": StudyTable(("recorded",), study_tables.recorded_spread),
        "13_per_step.csv": StudyTable(("recorded",), study_tables.recorded_per_step),
    }
    for study, (summarise, prefix, parts, index) in SUMMARIES.items():
        for suffix in ("", "_paper"):  # notebooks 14 to 16 write their paper tables under both names
            for part in parts:
                files[f"{prefix}{part}{suffix}.csv"] = StudyTable((study,), summarise, index, part)
    return files


FILES = _per_study_files()  # the study tables
RESULT_FILES = {**FILES, **WRITTEN}  # every committed result file


def writer(name: str) -> str:
    """The notebook that writes the result file ``name``: the one to run when it is missing."""
    if name not in RESULT_FILES:
        raise ValueError(f"{name!r} is not a registered result file; expected one of {sorted(RESULT_FILES)}")
    return RESULT_FILES[name].notebook


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


def write_table(name: str, profile: Profile, *rows: pd.DataFrame) -> pd.DataFrame:
    """The registered table ``name`` made from ``rows`` (the rows of its studies, in the entry's
    order) and written under the profile's output folder, as a notebook shows and writes it: by
    construction what ``regenerate`` makes from the same rows."""
    (entry,) = _entries([name])
    if len(rows) != len(entry.studies):
        raise ValueError(f"{name} is made from the rows of {list(entry.studies)}; got {len(rows)} frames of rows")
    table = _tables([name], dict(zip(entry.studies, rows)))[name]
    _write(profile, name, table)
    return table


def write_summary(study: str, profile: Profile, rows: pd.DataFrame, suffix: str = "") -> dict[str, pd.DataFrame]:
    """``write_table`` for every part of a study's ``summarise`` (``SUMMARIES``), each in its file,
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
