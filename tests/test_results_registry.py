"""Every committed result file that is made from the studies' shipped rows alone is what those
rows make today: a table left behind by a change of its rule or of its rows (as
`08_differences.csv` once was) fails here, not in a reader's hands."""

import io

import pandas as pd
import pytest

from softflow.profiles import get_profile
from softflow.report import registry
from softflow.store import REPO

FIGURES = REPO / "figures"


@pytest.mark.parametrize("name", sorted(registry.FILES))
def test_a_committed_table_is_what_the_shipped_rows_make(name):
    entry = registry.FILES[name]
    fresh = registry.regenerate(name, get_profile("paper"))
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
        registry.regenerate("99_nothing.csv", get_profile("paper"))
