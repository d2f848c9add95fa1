"""The paper's Tables I-IV from the CSV results of notebooks 03-06, beside the paper's own
numbers, as CSV and Markdown, and the results page docs/results.md.

Nothing here recomputes a result: a missing CSV is an error that names the notebook
that writes it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from softflow.control.metrics import table_rows
from softflow.models.specs import MODELS as MODEL_SPECS
from softflow.profiles import Profile
from softflow.rod.robots import HW_ROBOT
from softflow.store import DATA_DIR, write_text
from softflow.studies.catalogue import STUDIES
from softflow.studies.study import FLOOR

COLUMNS = {
    "rmse_shape_mm": "shape_mm",
    "rmse_random_mm": "random_mm",
    "phase_lag_shape_s": "phase_lag_s",
    "input_energy_random": "input_energy",
}  # metrics.table_rows -> the paper's table headings
TABLE1_MODELS = ["mlp", "lstm", "transformer", "rf", "rf-physical", "rf-fwd"]
BASELINES = [name for name in TABLE1_MODELS if MODEL_SPECS[name].group == "regression"]  # Table I's groups
RF_FAMILY = [name for name in TABLE1_MODELS if MODEL_SPECS[name].group == "flow"]

LABELS = {name: spec.label for name, spec in MODEL_SPECS.items() if spec.label} | {FLOOR: "ILC floor (true simulator)"}
# The paper's numbers (Tables I-IV of the paper in ../shared/paper).
PAPER_TABLE1 = pd.DataFrame(
    {"shape_mm": [23.1, 15.6, 13.4, 6.7, 6.8, 5.0], "random_mm": [30.6, 8.4, 12.7, 5.2, 4.0, 3.5]},
    index=["mlp", "lstm", "transformer", "rf", "rf-physical", "rf-fwd"],
)
PAPER_TABLE2 = pd.DataFrame(
    {"phase_lag_s": [0.0575, 0.0775, 0.0475, 0.0450], "input_energy": [26.47, 16.56, 20.70, 17.04]},
    index=["mlp", "lstm", "transformer", "rf-fwd"],
)
PAPER_TABLE3 = pd.DataFrame(
    {"vertical": [3.83, 4.94, 3.95, 4.46, 4.30], "horizontal": [3.96, 6.52, 8.65, 6.47, 6.40]},
    index=["star", "spiral", "circle", "heart", "mean"],
)
PAPER_TABLE4 = pd.DataFrame(
    [
        ("OL-LSTM (Centurelli 2021)", "Feedforward", "--", "0.035-0.045 (0.18-0.23)", "~3.2 (1.6%)", "--"),
        ("Dyn. Oper. (Haggerty 2023)", "Feedback", "--", "1.50 (3.23)", "--", "<5"),
        ("DKoopman (Feizi 2025)", "Feedback", "0.44±0.14", "--", "1.79±1.26 (3.25%)", "--"),
        ("Hyb. MLNN (Huang 2025)", "Feedback", "<3.0", "0.005-0.080 (0.03-0.46)", "0.4-1.1 (0.23-0.63%)", "--"),
        ("PINN-MPC (Licher 2025)", "Feedback", "--", "--", "<3.0 (2.3%)", ">11520"),
        ("RF-FWD (paper)", "Feedforward", "0.995", "1.14 (2.53)", "4.3-6.4 (0.96-1.42%)", "20"),
    ],
    columns=["method", "control", "inference_ms", "speed_m_s (v/L 1/s)", "error_mm (%L)", "train_min"],
).set_index("method")


def read_result(profile: Profile, name: str, **read_options) -> pd.DataFrame:
    """A result CSV of a profile (``read_options`` go to pandas), or a ValueError naming the
    notebook that writes it."""
    path = profile.output_dir / name
    if not path.exists():
        from softflow.report.result_files import writer  # result_files reads sweeps through this module

        notebook = writer(name)
        raise ValueError(
            f"{path} is missing: run notebooks/{notebook} with profile {profile.name!r} first "
            f"(make reproduce runs every notebook in order)"
        )
    return pd.read_csv(path, **read_options)


def read_sweep(profile: Profile, study: str) -> pd.DataFrame:
    """A study's rows for a profile: shipped under the output folder's sweeps/ (the paper
    profile's, figures/sweeps/), else the sweep cache's; or a ValueError naming the notebook
    that runs the study."""
    name = f"{study}-{profile.name}.csv"
    for path in (profile.output_dir / "sweeps" / name, DATA_DIR / "sweeps" / name):
        if path.exists():
            return pd.read_csv(path)
    notebook = STUDIES[study].notebook if study in STUDIES else ""
    notebook = notebook or "the notebook that runs it"
    raise ValueError(
        f"no rows of study {study!r} for profile {profile.name!r}: run notebooks/{notebook} "
        f"(or `python -m softflow sweep {study} --profile {profile.name}`) first"
    )


def machine_counts(rows: pd.DataFrame) -> pd.Series:
    """How many of ``rows`` each CPU computed (their ``machine`` column), most first; rows from
    before the column existed say "unknown", as the shipped rows do."""
    named = rows["machine"] if "machine" in rows else pd.Series("unknown", index=rows.index)
    return named.fillna("unknown").value_counts()


def computed_rows(profile: Profile, study: str) -> pd.DataFrame:
    """``read_sweep``'s rows, or an empty frame (its ``key`` column only) where the study has not
    run in this profile: what a page shows of a study as far as it is computed."""
    try:
        return read_sweep(profile, study)
    except ValueError:
        return pd.DataFrame(columns=["key"])


def our_table(profile: Profile) -> pd.DataFrame:
    frame = pd.concat([read_result(profile, "results_baselines.csv"), read_result(profile, "results_rf.csv")])
    return table_rows(frame).rename(columns=COLUMNS).reindex(TABLE1_MODELS)


def table1(profile: Profile) -> pd.DataFrame:
    """Tracking RMSE (mm), shapes / random references: ours beside the paper's."""
    ours = our_table(profile)[["shape_mm", "random_mm"]]
    return _beside(ours, PAPER_TABLE1)


def table2(profile: Profile) -> pd.DataFrame:
    """Phase lag on shapes (s) and input energy on random references: ours beside the paper's."""
    ours = our_table(profile)[["phase_lag_s", "input_energy"]]
    return _beside(ours, PAPER_TABLE2.reindex(TABLE1_MODELS))


def table3(profile: Profile) -> pd.DataFrame:
    """Hardware(-twin) tracking RMSE (mm), vertical / horizontal: ours beside the paper's."""
    ours = read_result(profile, "table3_twin.csv").set_index("reference")[["vertical", "horizontal"]]
    return _beside(ours, PAPER_TABLE3)


def table4(profile: Profile) -> pd.DataFrame:
    """The paper's literature comparison with our measured RF-FWD row appended."""
    sweep = read_result(profile, "euler_sweep.csv").set_index("steps")
    training = read_result(profile, "training_rf.csv").set_index("model").minutes
    twin = read_result(profile, "twin_results.csv")
    burst = twin[twin.family == "burst"]
    errors = read_result(profile, "table3_twin.csv").set_index("reference").loc["mean", ["vertical", "horizontal"]]
    speed = burst.peak_speed.max()
    low, high = errors.min(), errors.max()
    length_mm = 1e3 * HW_ROBOT.length
    ours = pd.DataFrame(
        [
            (
                "RF-FWD (this repo, twin)",
                "Feedforward",
                f"{sweep.latency_ms.loc[4]:.3f}",
                f"{speed:.2f} ({speed / HW_ROBOT.length:.2f})",
                f"{low:.1f}-{high:.1f} ({100 * low / length_mm:.2f}-{100 * high / length_mm:.2f}%)",
                f"{training.loc['rf-fwd'] + training.loc['forward']:.0f}",
            )
        ],
        columns=PAPER_TABLE4.columns.insert(0, "method"),
    ).set_index("method")
    return pd.concat([PAPER_TABLE4, ours])


def _beside(ours: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Columns (quantity, "ours" / "paper"), rows in our order."""
    return (
        pd.concat({"ours": ours, "paper": paper.reindex(ours.index)}, axis=1)
        .swaplevel(axis=1)
        .sort_index(axis=1, level=0, sort_remaining=False)[
            [(c, who) for c in ours.columns for who in ("ours", "paper")]
        ]
    )


def markdown(table: pd.DataFrame, digits: int = 2) -> str:
    """A GitHub-flavoured Markdown table: model names as their labels, NaN as "--", "|" escaped,
    cells unpadded (``DataFrame.to_markdown`` needs tabulate, pads every cell to its column's
    width and knows no labels)."""
    columns = [" ".join(map(str, c)) if isinstance(c, tuple) else str(c) for c in table.columns]
    rows = [
        [" ".join(map(str, index)) if isinstance(index, tuple) else LABELS.get(str(index), str(index))]
        + [_cell(v, digits) for v in values]
        for index, values in zip(table.index, table.values)
    ]
    name = ", ".join(n or "" for n in table.index.names)
    lines = ["| " + " | ".join([name] + columns) + " |", "|" + "---|" * (len(columns) + 1)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def _cell(value, digits: int) -> str:
    """A value as Markdown table text: floats to ``digits``, a "|" inside escaped (it would split the cell)."""
    if isinstance(value, (float, np.floating)):
        return "--" if np.isnan(value) else f"{value:.{digits}f}"
    return str(value).replace("|", "\\|")


def save_table(profile: Profile, table: pd.DataFrame, name: str, digits: int = 2) -> str:
    """Write a table as CSV and Markdown under the profile's output folder; return the Markdown."""
    write_text(profile.output_dir / f"{name}.csv", table.to_csv())
    text = markdown(table, digits)
    write_text(profile.output_dir / f"{name}.md", text + "\n")
    return text
