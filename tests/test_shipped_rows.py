"""The shipped study rows are what today's code computes: for each study with a cell that needs
no training (a shipped model scored), that cell is recomputed in the paper profile and compared
with the shipped rows found by today's key. This pins both the numbers and the keys (a key that
changed without a migration would find no rows). Other studies train in every cell (data_size,
ambiguity, fwd_lambda) or score the coverage by the paper dataset's 3000 episodes (protocol),
which a fresh clone would simulate first: they are left to ``make study``.

The cell runs through its own ``run`` on a few of its references (references are scored
independently: a plan, a replay and the camera's noise per reference), which keeps the test to
seconds where the whole cell takes minutes.

The ci rows ship too (the ci notebooks show them, so ``make test`` reads them instead of
computing every ci cell): one cell of every study, among its cheapest by the shipped
``cell_seconds``, is recomputed whole, training included, and compared with its shipped rows
(the recorded study's in its own test, which runs its whole ci study)."""

import numpy as np
import pandas as pd
import pytest
from small_runs import assert_like_shipped

from softflow.studies import STUDIES, closed_loop, sweep, table1

CELLS = {
    "table1": dict(study="table1", model="mlp", seed=0),
    "closed_loop": STUDIES["closed_loop"].cells("paper")[0],  # open loop on the vertical twin
}


def _fewer_references(monkeypatch, study):
    """The cell's reference list cut to a shape and a random reference (table1) or to the first
    (closed_loop), in the module the cell reads it from."""
    if study == "table1":
        every = table1.table1_references

        def a_shape_and_a_random(sim, profile_name):
            made = every(sim, profile_name)
            return [made[0], made[-1]]

        monkeypatch.setattr(table1, "table1_references", a_shape_and_a_random)
    else:
        every = closed_loop.hardware_references
        monkeypatch.setattr(closed_loop, "hardware_references", lambda sim: every(sim)[:1])


@pytest.mark.parametrize("study", CELLS)
def test_a_cheap_paper_cell_reproduces_its_shipped_rows(study, tmp_path, monkeypatch):
    cell = CELLS[study]
    assert cell in STUDIES[study].cells("paper")
    key = sweep.cell_key(study, cell, "paper", "cpu")
    shipped = pd.read_csv(sweep.SHIPPED_RESULTS / f"{study}-paper.csv", dtype={"key": str})
    shipped = shipped[shipped.key == key].set_index("reference")
    assert len(shipped), f"no shipped row has today's key {key} for {cell}"
    _fewer_references(monkeypatch, study)
    rows = pd.DataFrame(STUDIES[study].run_cell(cell, "paper", "cpu", tmp_path, key)).set_index("reference")
    assert 0 < len(rows) < len(shipped) and set(rows.index) <= set(shipped.index)
    for column in rows.columns:
        if column in shipped and pd.api.types.is_numeric_dtype(rows[column]):
            # BLAS kernels differ across CPUs: on an AVX-512 Xeon the old and the new code alike give
            # Table I RMSEs 1.2e-5 (relative) from rows made on another CPU (docs/assumptions.md)
            np.testing.assert_allclose(
                rows[column].to_numpy(float),
                shipped.loc[rows.index, column].to_numpy(float),
                rtol=1e-4,
                atol=1e-7,
                err_msg=column,
            )


CI_CELLS = {  # study: the fields that pick one of its cheapest ci cells (shipped cell_seconds)
    "ambiguity": dict(model="mlp", variant="position-only"),
    "closed_loop": dict(mode="open", gap="typical"),
    "data_size": dict(model="mlp", episodes=100),
    "design": dict(variant="rf (λ = 0)"),
    "fwd_lambda": dict(consistency=0.0),
    "loop": dict(model="mlp"),
    "one_step": dict(model="rf-1"),
    "protocol": dict(model="rf", condition="speed-0.5"),
    "table1": dict(model="mlp", seed=0),
    "trunk_v2": dict(model="delay 2"),  # a referee cell: no training
    "twin_burst": dict(mode="closed"),
    "two_segment": dict(model="rf"),
}
# recorded: its whole ci study runs in tests/test_recorded_study.py, against the shipped rows;
# trunk: its ci cells read and smooth every run (minutes), so tests/test_trunk.py checks its rows.
ELSEWHERE = {"recorded", "trunk"}


def test_every_study_ships_ci_rows_and_one_cell_is_tested():
    shipped = {path.name.removesuffix("-ci.csv") for path in sweep.SHIPPED_RESULTS.glob("*-ci.csv")}
    assert shipped == set(CI_CELLS) | ELSEWHERE == {name for name in STUDIES if name != "smoke"}


@pytest.mark.parametrize("study", CI_CELLS)
def test_a_ci_cell_reproduces_its_shipped_rows(study, tmp_path):
    (cell,) = [c for c in STUDIES[study].cells("ci") if {k: c.get(k) for k in CI_CELLS[study]} == CI_CELLS[study]]
    key = sweep.cell_key(study, cell, "ci", "cpu")
    shipped = sweep.shipped_rows(study, "ci").astype({"key": str})
    shipped = shipped[shipped.key == key].reset_index(drop=True)
    assert len(shipped), f"no shipped ci row has today's key {key} for {cell}"
    assert_like_shipped(pd.DataFrame(STUDIES[study].run_cell(cell, "ci", "cpu", tmp_path, key)), shipped)
