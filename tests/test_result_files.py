"""Every committed result file that is made from the studies' shipped rows alone is what those
rows make today: a table left behind by a change of its rule or of its rows (as
`08_differences.csv` once was) fails here, not in a reader's hands."""

import io

import pandas as pd
import pytest

from softflow import profiles
from softflow.profiles import get_profile
from softflow.report import result_files
from softflow.store import REPO

FIGURES = REPO / "figures"


@pytest.mark.parametrize("name", sorted(result_files.FILES))
def test_a_committed_table_is_what_the_shipped_rows_make(name):
    entry = result_files.FILES[name]
    fresh = result_files.regenerate(name, get_profile("paper"))
    written, committed = fresh.to_csv(index=entry.index), (FIGURES / name).read_text()  # as the notebook writes it
    if not fresh.size or not committed.strip():  # an empty table: nothing to compare but the text
        assert written.strip() == committed.strip(), f"{name} is stale: rerun its notebook"
        return
    pd.testing.assert_frame_equal(  # within rounding: a CPU's summation order may move a last bit
        pd.read_csv(io.StringIO(written)),
        pd.read_csv(io.StringIO(committed)),
        check_dtype=False,
        rtol=1e-12,
        obj=f"{name} (stale: rerun its notebook)",
    )


def test_an_unregistered_name_is_refused():
    with pytest.raises(ValueError, match="not a registered result file"):
        result_files.regenerate("99_nothing.csv", get_profile("paper"))


def test_a_notebook_writes_what_the_registry_regenerates(tmp_path, monkeypatch):
    """``write_table`` makes a table from the rows it is handed and writes it where the profile's
    results go; from the shipped rows that is, to the byte, what ``regenerate`` makes."""
    paper = get_profile("paper")
    names = [f"15_one_step_{part}_paper.csv" for part in ("rmse", "parity", "tip_win", "collapse")]
    expected = {name: result_files.regenerate(name, paper).to_csv(index=False) for name in names}
    expected["12_differences.csv"] = result_files.regenerate("12_differences.csv", paper).to_csv(index=False)
    one_step, two_segment = (pd.read_csv(FIGURES / "sweeps" / f"{s}-paper.csv") for s in ("one_step", "two_segment"))
    monkeypatch.setattr(profiles, "REPO", tmp_path)  # the profile's results go to tmp_path/figures
    (tmp_path / "figures").mkdir()
    made = result_files.write_summary("one_step", paper, one_step, "_paper")
    assert list(made) == ["rmse", "parity", "tip_win", "collapse"]
    result_files.write_table("12_differences.csv", paper, two_segment)
    assert {name: (tmp_path / "figures" / name).read_text() for name in expected} == expected
    with pytest.raises(ValueError, match=r"made from the rows of \['ambiguity', 'two_segment'\]; got 1"):
        result_files.write_table("09_regime_map.csv", paper, one_step)
    with pytest.raises(ValueError, match="study must be one of"):
        result_files.write_summary("table1", paper, one_step)
