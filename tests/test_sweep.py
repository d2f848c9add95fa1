"""The sweep runner: a cluster gives the rows of a sequential run, a rerun computes nothing,
a failing cell is named while the others return, and the CLI runs on a cluster someone
else started (through its scheduler file)."""

from __future__ import annotations

import dataclasses
import platform

import pandas as pd
import pytest
from distributed import Client, LocalCluster

from softflow import cli, profiles
from softflow.machine import cpu_model
from softflow.studies import sweep
from softflow.studies.study import Study


@pytest.fixture(scope="module")
def scheduler_file(tmp_path_factory):
    return tmp_path_factory.mktemp("cluster") / "scheduler.json"


@pytest.fixture(scope="module")
def client(scheduler_file):
    """Two single-threaded worker processes, shared by the tests (starting one takes seconds).
    Its scheduler writes ``scheduler_file`` on start, as ``dask scheduler --scheduler-file`` does
    (``Client.write_scheduler_file`` can fail on worker metrics with tuple keys once tasks ran)."""
    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            scheduler_kwargs=dict(scheduler_file=str(scheduler_file)),
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


@pytest.fixture
def sweep_dirs(tmp_path, monkeypatch):
    """The sweep cache (returned) and the shipped rows in ``tmp_path``: a test never reads or
    writes the committed rows or this machine's cache."""
    monkeypatch.setattr(sweep, "SWEEPS_DIR", tmp_path / "cache")
    monkeypatch.setattr(sweep, "SHIPPED_RESULTS", tmp_path / "shipped")
    return tmp_path / "cache"


def _flaky_cells(profile_name):
    return [
        dict(study="flaky", model="none", seed=seed, condition=condition)
        for seed, condition in [(0, "ok"), (1, "bad"), (2, "ok")]
    ]


def _flaky_run(cell, profile_name, device, workdir, key):
    if cell["condition"] == "bad":
        raise RuntimeError("cell exploded")
    return dict(score=10 * cell["seed"])


def measured(rows):
    """Rows without their wall times, which differ from run to run."""
    return rows.drop(columns="cell_seconds")


def _must_not_run(*args):
    raise AssertionError("run_cell called for a cached cell")


def test_cluster_gives_the_rows_of_a_sequential_run(client, tmp_path):
    sequential = sweep.run_sweep("smoke", "ci", client=None, device="cpu", root=tmp_path / "here", progress=False)
    distributed = sweep.run_sweep("smoke", "ci", client=client, device="cpu", root=tmp_path / "dask", progress=False)
    assert sequential.failures == distributed.failures == []
    assert len(sequential.rows) >= 2 and sequential.rows["seed"].nunique() >= 2
    assert (sequential.rows["cell_seconds"] >= 0).all()
    assert (sequential.rows["machine"] == (cpu_model() or platform.machine())).all()  # which CPU made each row
    pd.testing.assert_frame_equal(measured(sequential.rows), measured(distributed.rows))
    pd.testing.assert_frame_equal(measured(pd.read_csv(distributed.csv)), measured(pd.read_csv(sequential.csv)))
    assert distributed.csv == tmp_path / "dask" / "smoke-ci.csv"
    assert len(list((tmp_path / "dask" / "smoke" / "models").glob("*.pt"))) == len(distributed.rows)


def test_rerun_computes_nothing_and_resumes_a_missing_cell(tmp_path, monkeypatch):
    first = sweep.run_sweep("smoke", "ci", client=None, device="cpu", root=tmp_path, progress=False)
    smoke = sweep.STUDIES["smoke"]
    monkeypatch.setitem(sweep.STUDIES, "smoke", dataclasses.replace(smoke, run_cell=_must_not_run))
    again = sweep.run_sweep("smoke", "ci", client=None, device="cpu", root=tmp_path, progress=False)
    assert (again.cached, again.computed, again.failures) == (len(first.rows), 0, [])
    pd.testing.assert_frame_equal(first.rows, again.rows)

    (tmp_path / "smoke" / f"{first.rows['key'][0]}.json").unlink()  # as if interrupted before this cell finished
    calls = []
    monkeypatch.setitem(
        sweep.STUDIES,
        "smoke",
        dataclasses.replace(smoke, run_cell=lambda cell, *args: calls.append(cell) or smoke.run_cell(cell, *args)),
    )
    resumed = sweep.run_sweep("smoke", "ci", client=None, device="cpu", root=tmp_path, progress=False)
    assert (resumed.computed, len(calls), resumed.failures) == (1, 1, [])
    pd.testing.assert_frame_equal(measured(first.rows), measured(resumed.rows))


def test_failing_cell_is_named_and_the_others_return(client, sweep_dirs, monkeypatch, capsys):
    monkeypatch.setitem(sweep.STUDIES, "flaky", Study(_flaky_cells, _flaky_run))
    result = sweep.run_sweep("flaky", "ci", client=client, device="cpu", root=sweep_dirs, progress=False)
    assert result.failures == [sweep.Failure(_flaky_cells("ci")[1], "RuntimeError: cell exploded")]
    assert result.rows["score"].tolist() == [0, 20]
    assert pd.read_csv(result.csv)["seed"].tolist() == [0, 2]

    # The CLI on the same cluster by address: the good rows come from the cache, the bad cell
    # runs again, is named on stderr, and the exit status says the sweep is incomplete.
    with pytest.raises(SystemExit) as exit:
        cli.main(["sweep", "flaky", "--profile", "ci", "--scheduler", client.scheduler.address, "--device", "cpu"])
    assert exit.value.code == 1
    out, err = capsys.readouterr()
    assert "'condition': 'bad'" in err and "RuntimeError: cell exploded" in err
    assert "2 cached" in out and out.strip().splitlines()[-1] == str(result.csv)


def test_cli_runs_on_a_cluster_through_its_scheduler_file(client, scheduler_file, sweep_dirs, capsys):
    cli.main(["sweep", "smoke", "--profile", "ci", "--scheduler-file", str(scheduler_file), "--device", "cpu"])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last == str(sweep_dirs / "smoke-ci.csv")
    table = pd.read_csv(last)
    assert table["u_rmse"].notna().all() and table["u_rmse"].gt(0).all() and len(table) >= 2


def _per_reference_cells(profile_name):
    return [dict(study="multi", model="none", seed=seed) for seed in (0, 1)]


def _per_reference_run(cell, profile_name, device, workdir, key):
    return [dict(reference=f"R{r}", score=cell["seed"] + r / 4) for r in range(3)]


def test_cells_with_several_rows_ship_and_read_back_from_the_shipped_csv(tmp_path, sweep_dirs, monkeypatch):
    """A paper-profile sweep writes its rows to the shipped CSV too; on a fresh clone (no
    cache) those rows count as cached, unless the sweep is told to recompute them."""
    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, _per_reference_run))
    first = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False)
    assert first.rows["score"].tolist() == [0, 0.25, 0.5, 1, 1.25, 1.5]
    assert first.rows["reference"].tolist() == ["R0", "R1", "R2"] * 2
    shipped = tmp_path / "shipped" / "multi-paper.csv"
    pd.testing.assert_frame_equal(pd.read_csv(shipped), pd.read_csv(first.csv))

    for cached in (sweep_dirs / "multi").glob("*.json"):
        cached.unlink()  # a fresh clone: only the shipped CSV
    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, _must_not_run))
    fresh = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False)
    assert (fresh.cached, fresh.computed) == (2, 0)
    pd.testing.assert_frame_equal(fresh.rows, first.rows)
    recomputed = sweep.run_sweep("multi", "paper", client=None, device="cpu", shipped=False, progress=False)
    assert recomputed.computed == 2 and recomputed.failures[0].error.startswith("AssertionError")
    pd.testing.assert_frame_equal(pd.read_csv(shipped), first.rows)  # not replaced by nothing


def test_a_sweep_never_drops_shipped_rows_of_cells_it_does_not_know(tmp_path, sweep_dirs, monkeypatch):
    """Shipped rows under a key that is no cell of today's grid (another grid, study version or
    key scheme) stay: the sweep warns, computes what it lacks and writes its rows beside, never a
    shipped CSV without them."""
    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, _per_reference_run))
    sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False)
    shipped = tmp_path / "shipped" / "multi-paper.csv"
    table = pd.read_csv(shipped)
    table.loc[table.seed == 1, "key"] = "0123456789abcdef"  # the second cell's rows under a key of another scheme
    shipped.write_text(table.to_csv(index=False))
    committed = shipped.read_bytes()
    for cached in (sweep_dirs / "multi").glob("*.json"):
        cached.unlink()  # a fresh clone: only the shipped CSV
    with pytest.warns(UserWarning, match="holds rows of 1 cells that are not cells of this grid"):
        again = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False)
    assert (again.cached, again.computed) == (1, 1)
    assert shipped.read_bytes() == committed
    assert pd.read_csv(again.csv)["score"].tolist() == [0, 0.25, 0.5, 1, 1.25, 1.5]


def test_two_sweeps_on_disjoint_cells_ship_each_others_rows(tmp_path, sweep_dirs, monkeypatch):
    """Two processes sweeping disjoint cells of one study (``where``) share the cache; whichever
    finishes last writes the shipped CSV, and it must hold the rows the other computed meanwhile."""

    def run_and_meanwhile_the_other_sweep_finishes(cell, profile_name, device, workdir, key):
        if cell["seed"] == 0:  # the other process: seed 1's cell lands in the cache while seed 0 runs
            other = _per_reference_cells(profile_name)[1]
            other_key = sweep.cell_key("multi", other, profile_name, device)
            rows = sweep._row(_per_reference_run, other, profile_name, device, workdir, other_key)
            workdir.mkdir(parents=True, exist_ok=True)
            (workdir / f"{other_key}.json").write_text(rows)  # the cache both sweeps share
        return _per_reference_run(cell, profile_name, device, workdir, key)

    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, run_and_meanwhile_the_other_sweep_finishes))
    done = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False, where={"seed": ["0"]})
    assert (done.computed, done.missing, done.failures) == (1, 1, [])  # it counts what it computed
    shipped = pd.read_csv(tmp_path / "shipped" / "multi-paper.csv")
    assert shipped["seed"].tolist() == [0, 0, 0, 1, 1, 1]  # both sweeps' rows, in grid order
    assert shipped["score"].tolist() == [0, 0.25, 0.5, 1, 1.25, 1.5]


def test_a_sweep_that_must_not_compute_returns_the_rows_present_and_writes_nothing(tmp_path, sweep_dirs, monkeypatch):
    """compute_missing=False (a notebook showing a study of hours): no cell runs, the rows present
    come back in grid order with the number of cells that have none, and no CSV is written (a
    sweep still running elsewhere owns them); the shipped paper rows count as present."""
    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, _must_not_run))
    empty = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False, compute_missing=False)
    assert (len(empty.rows), empty.cached, empty.computed, empty.missing, empty.failures) == (0, 0, 0, 2, [])
    assert not sweep_dirs.exists() and not (tmp_path / "shipped").exists()

    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, _per_reference_run))
    full = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False)
    assert full.missing == 0
    shipped, csv = tmp_path / "shipped" / "multi-paper.csv", full.csv
    (sweep_dirs / "multi" / f"{full.rows['key'][0]}.json").unlink()
    shipped.write_text(pd.read_csv(shipped).iloc[3:].to_csv(index=False))  # only the second cell's rows
    (sweep_dirs / "multi" / f"{full.rows['key'][3]}.json").unlink()  # ... which only ship
    before = {path: path.read_bytes() for path in (shipped, csv)}
    monkeypatch.setitem(sweep.STUDIES, "multi", Study(_per_reference_cells, _must_not_run))
    part = sweep.run_sweep("multi", "paper", client=None, device="cpu", progress=False, compute_missing=False)
    assert (part.cached, part.computed, part.missing, part.failures) == (1, 0, 1, [])
    pd.testing.assert_frame_equal(part.rows, pd.read_csv(shipped))
    assert {path: path.read_bytes() for path in before} == before


def _gappy_run(cell, profile_name, device, workdir, key):  # the first row lacks a middle column, as Table I's shapes do
    return [
        dict(reference="R0", mae=float("nan"), score=0.1 + cell["seed"]),
        dict(reference="R1", mae=1 / 3, score=2 / 3 + cell["seed"]),
    ]


def test_reading_the_shipped_rows_leaves_the_shipped_csv_as_it_was(tmp_path, sweep_dirs, monkeypatch):
    """make reproduce on a fresh clone reads the shipped rows: the committed CSV must not change,
    not even in its column order or the last digit of a float."""
    monkeypatch.setitem(sweep.STUDIES, "gappy", Study(_per_reference_cells, _gappy_run))
    sweep.run_sweep("gappy", "paper", client=None, device="cpu", progress=False)
    shipped = tmp_path / "shipped" / "gappy-paper.csv"
    committed = shipped.read_bytes()
    assert committed.splitlines()[0].endswith(b",reference,mae,score")

    for cached in (sweep_dirs / "gappy").glob("*.json"):
        cached.unlink()  # a fresh clone: only the shipped CSV
    monkeypatch.setitem(sweep.STUDIES, "gappy", Study(_per_reference_cells, _must_not_run))
    fresh = sweep.run_sweep("gappy", "paper", client=None, device="cpu", progress=False)
    assert fresh.computed == 0 and shipped.read_bytes() == committed
    assert (sweep_dirs / "gappy-paper.csv").read_bytes() == committed


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="study"):
        sweep.run_sweep("no-such-study", "ci", client=None, device="cpu")
    for profile in ("no-such-profile", "quick"):  # quick sizes a user's own models, no study's grid
        with pytest.raises(ValueError, match="profile"):
            sweep.run_sweep("smoke", profile, client=None, device="cpu")
    with pytest.raises(ValueError, match="device"):
        sweep.resolve_device("tpu")
    assert sweep.resolve_device("cpu") == "cpu" and sweep.resolve_device("auto") in ("cuda", "mps", "cpu")
    for bad in [
        dict(workers=0),
        dict(workers=2, scheduler="tcp://127.0.0.1:8786"),
        dict(scheduler_file="s.json", scheduler="tcp://127.0.0.1:8786"),
    ]:
        with pytest.raises(ValueError), sweep.connect(**bad):
            pass
    with pytest.raises(SystemExit):
        cli.main(["sweep", "smoke", "--profile", "ci", "--workers", "0"])


def test_where_computes_only_the_cells_asked_for(client, sweep_dirs, monkeypatch, capsys):
    """A study of hours can run its cheap cells first: ``where`` picks cells by their fields (as
    text, as a command line gives them); the others stay missing, and a later run completes it."""
    monkeypatch.setitem(sweep.STUDIES, "flaky", Study(cells=_flaky_cells, run_cell=_flaky_run))
    picked = sweep.run_sweep(
        "flaky", "ci", client=None, device="cpu", root=sweep_dirs, progress=False, where={"seed": ["0", "2"]}
    )
    assert (picked.computed, picked.missing, picked.failures) == (2, 1, [])
    assert picked.rows["seed"].tolist() == [0, 2] and picked.rows["score"].tolist() == [0, 20]
    with pytest.raises(ValueError, match=r"no cell of this study has the field\(s\) \['runs'\]"):
        sweep.run_sweep("flaky", "ci", client=None, device="cpu", root=sweep_dirs, where={"runs": ["60"]})
    address = client.scheduler.address
    cli.main(
        ["sweep", "flaky", "--profile", "ci", "--scheduler", address, "--device", "cpu", "--where", "condition=ok"]
    )
    assert "(2 cached, 0 computed, 0 failed, 1 cells not asked for)" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        cli.main(["sweep", "flaky", "--profile", "ci", "--where", "seed"])


def test_shipped_rows_are_the_committed_csv_and_nothing_else(tmp_path, sweep_dirs):
    """A notebook that shows another notebook's study reads its shipped rows only: what this
    machine has computed (data/sweeps/) never changes its output."""
    sweep.run_sweep("smoke", "ci", client=None, device="cpu", root=sweep_dirs, progress=False)  # cached, none shipped
    assert sweep.shipped_rows("smoke", "ci").empty
    (tmp_path / "shipped").mkdir()
    pd.DataFrame({"key": ["a"], "score": [1.5]}).to_csv(tmp_path / "shipped" / "smoke-paper.csv", index=False)
    assert sweep.shipped_rows("smoke", "paper").to_dict("records") == [{"key": "a", "score": 1.5}]
    with pytest.raises(ValueError, match="study"):
        sweep.shipped_rows("no-such-study", "paper")


def test_a_profile_with_other_data_keys_its_rows_anew(monkeypatch):
    """Rows made on one dataset are never served for another: the profile's data knobs (and the
    identification run's length) are in every cell's key; a knob no study reads is not."""
    cell = sweep.STUDIES["table1"].cells("ci")[0]
    today = sweep.cell_key("table1", cell, "ci", "cpu")
    ci = profiles.get_profile("ci")
    for changed, new_key in [
        (dict(n_episodes=ci.n_episodes + 1), True),
        (dict(episode_seconds=2 * ci.episode_seconds), True),
        (dict(seed=ci.seed + 1), True),
        (dict(identification_seconds=2 * ci.identification_seconds), True),
        (dict(bench_episodes=ci.bench_episodes + 1), False),  # notebook 01's timing only
    ]:
        monkeypatch.setitem(profiles.PROFILES, "ci", dataclasses.replace(ci, **changed))
        assert (sweep.cell_key("table1", cell, "ci", "cpu") != today) == new_key, changed
