"""Every committed file that `make reproduce` reuses or resumes from is one today's code asks for
(``softflow.report.shipped``, the run-time checks made without running), and each check fails
on the defect it is there for: a claim, a cache file, a checkpoint or rows made by older code."""

import json
import shutil

import pandas as pd
import pytest

from softflow.models import checkpoints
from softflow.report import shipped
from softflow.store import REPO, cache_file, content_key, spec_file

ARTEFACTS = shipped.artefacts()
CLAIM = REPO / "figures" / "13_recording" / "recorder.json"


@pytest.mark.parametrize("artefact", ARTEFACTS, ids=lambda a: str(a.path.relative_to(REPO)))
def test_every_shipped_artefact_is_one_todays_code_asks_for(artefact):
    assert artefact.problem(REPO) is None


def test_the_walk_finds_every_kind_and_every_file():
    kinds = {kind: {a.path for a in ARTEFACTS if a.kind == kind} for kind in {a.kind for a in ARTEFACTS}}
    assert kinds == {
        "recording claim": {CLAIM},
        "study rows": set((REPO / "figures" / "sweeps").glob("*.csv")),
        "cache": set((REPO / "cache").glob("*.npz")),
        "checkpoint": set((REPO / "checkpoints").rglob("*.pt")),
    }


def test_a_claim_of_the_recorder_before_sliding_length_and_cable_anchors_fails(tmp_path):
    """The claim as the committed tree had it when make reproduce stopped at notebook 13."""
    claim = json.loads(CLAIM.read_text())
    del claim["gap"]["sliding_length"], claim["robot_parameters"]["cable_anchors"]
    old = tmp_path / CLAIM.relative_to(REPO)
    old.parent.mkdir(parents=True)
    old.write_text(json.dumps(claim))
    (problem,) = shipped.problems(tmp_path).values()
    assert "gap.sliding_length: None there, 0.0005 asked today" in problem
    assert "robot_parameters.cable_anchors: None there, [] asked today" in problem
    claim["gap"]["friction_of_old"] = 1.0  # a term today's gap does not have
    old.write_text(json.dumps(claim))
    assert "cannot rebuild what made it (TypeError" in shipped.problems(tmp_path)["figures/13_recording/recorder.json"]


def test_a_cache_file_made_for_an_older_rod_or_without_its_spec_fails(tmp_path):
    (table,) = [a.path for a in ARTEFACTS if a.path.name.startswith("static-table-610e")]
    spec = json.loads(spec_file(table).read_text())
    del spec["simulator"]["robot"]["cable_anchors"]  # the rod's parameters before cable_anchors
    old = cache_file(tmp_path / "cache", "static-table", spec)
    old.parent.mkdir()
    shutil.copy(table, old)
    assert shipped.problems(tmp_path) == {
        f"cache/{old.name}": f"no {spec_file(old).name} beside it: copy the one the run wrote beside it in data/"
    }
    spec_file(old).write_text(json.dumps(spec))
    assert (
        "simulator.robot.cable_anchors: None there, [] asked today" in shipped.problems(tmp_path)[f"cache/{old.name}"]
    )
    renamed = old.with_name(f"static-table-{'0' * 16}.npz")
    old.rename(renamed), spec_file(old).rename(spec_file(renamed))
    assert shipped.problems(tmp_path)[f"cache/{renamed.name}"] == (
        f"its spec's key is {content_key(spec)}, not the {'0' * 16} in its name"
    )


def test_a_checkpoint_of_other_data_or_of_no_rod_of_today_fails(tmp_path):
    checkpoint = checkpoints.load_checkpoint(REPO / "checkpoints" / "mlp.pt")
    checkpoints.save_checkpoint(
        dict(checkpoint, data_key="dataset-paper-0000000000000000"), tmp_path / "checkpoints" / "mlp.pt"
    )
    hardware = REPO / "checkpoints" / "hw-vertical-5e469dc9" / "rf-fwd.pt"
    (tmp_path / "checkpoints" / "hw-vertical-00000000").mkdir()
    shutil.copy(hardware, tmp_path / "checkpoints" / "hw-vertical-00000000" / "rf-fwd.pt")
    found = shipped.problems(tmp_path)
    assert found.keys() == {"checkpoints/mlp.pt", "checkpoints/hw-vertical-00000000/rf-fwd.pt"}
    assert "data_key: 'dataset-paper-0000000000000000' there" in found["checkpoints/mlp.pt"]
    assert "is the folder of no rod today" in found["checkpoints/hw-vertical-00000000/rf-fwd.pt"]


def test_rows_under_a_key_of_no_cell_of_todays_grid_fail(tmp_path):
    rows = pd.read_csv(REPO / "figures" / "sweeps" / "table1-ci.csv", dtype={"key": str})
    rows.loc[rows.key == rows.key.iloc[0], "key"] = "0" * 16
    (tmp_path / "figures" / "sweeps").mkdir(parents=True)
    rows.to_csv(tmp_path / "figures" / "sweeps" / "table1-ci.csv", index=False)
    assert shipped.problems(tmp_path) == {
        "figures/sweeps/table1-ci.csv": "1 cells under keys that no cell of today's grid has"
    }


def test_a_file_no_check_knows_fails(tmp_path):
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "notes.txt").write_text("")
    assert shipped.problems(tmp_path)["cache/notes.txt"].startswith("not a cache file")
