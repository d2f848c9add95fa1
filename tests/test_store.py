"""Cache keys follow the numbers, not the source text; writes are all-or-nothing."""

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from softflow import data, store
from softflow.data import dataset
from softflow.profiles import get_profile
from softflow.rod import dynamics
from softflow.rod.robots import SIM_ROBOT

PAPER = get_profile("paper")


def test_content_key_is_canonical_and_sensitive():
    assert store.content_key({"a": 1, "b": [2, 3]}) == store.content_key({"b": [2, 3], "a": 1})
    assert store.content_key({"a": 1}) != store.content_key({"a": 1.0000001})
    assert len(store.content_key({}, length=8)) == 8


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "table.csv"
    store.write_text(path, "old")
    with pytest.raises(RuntimeError):
        with store.atomic_write(path, "w") as f:
            f.write("half")
            raise RuntimeError("interrupted")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


def test_cached_arrays_compute_once_and_recompute_what_is_corrupt_or_invalid(tmp_path):
    calls, spec = [], dict(n=3)

    def compute():
        calls.append(1)
        return dict(a=np.arange(3.0))

    first = store.cached_arrays(tmp_path, "c", spec, compute)
    again = store.cached_arrays(tmp_path, "c", spec, compute)
    assert len(calls) == 1 and np.array_equal(first["a"], again["a"])
    path = store.cache_file(tmp_path, "c", spec)
    path.write_bytes(path.read_bytes()[:20])  # a truncated file is never used
    assert np.array_equal(store.cached_arrays(tmp_path, "c", spec, compute)["a"], np.arange(3.0)) and len(calls) == 2
    store.cached_arrays(tmp_path, "c", spec, compute, valid=lambda arrays: "b" in arrays)  # stale layout: rebuilt
    assert len(calls) == 3


def test_a_cache_file_keeps_the_spec_that_keys_it(tmp_path):
    spec = dict(simulator=dict(gravity="vertical", dt=0.01), kind="evaluation", cells=(1, 2))
    store.cached_arrays(tmp_path, "references-evaluation", spec, lambda: dict(a=np.zeros(1)))
    path = store.cache_file(tmp_path, "references-evaluation", spec)
    kept = json.loads(store.spec_file(path).read_text())
    assert kept["cells"] == [1, 2] and path.name == f"references-evaluation-{store.content_key(kept)}.npz"


def test_a_shipped_copy_serves_a_missing_cache_and_a_bad_one_is_ignored(tmp_path, monkeypatch):
    shipped, cache, spec = tmp_path / "shipped", tmp_path / "data", dict(n=4)
    monkeypatch.setattr(store, "SHIPPED_CACHE", shipped)
    store.write_npz(store.cache_file(shipped, "refs", spec), a=np.arange(4.0))
    calls = []

    def compute():
        calls.append(1)
        return dict(a=np.zeros(2))

    assert np.array_equal(store.cached_arrays(cache, "refs", spec, compute)["a"], np.arange(4.0)) and not calls
    assert not cache.exists()  # the shipped copy is only read
    store.cache_file(shipped, "refs", spec).write_bytes(b"not a zip")
    assert np.array_equal(store.cached_arrays(cache, "refs", spec, compute)["a"], np.zeros(2)) and calls == [1]


def test_the_shipped_evaluation_references_are_what_their_key_computes():
    """The committed cache of Table I's references holds what computing its key gives today:
    its circle is rebuilt and compared (the rest follow the same key and code)."""
    from softflow.data import references
    from softflow.rod.dynamics import Simulator

    sim = Simulator(SIM_ROBOT)
    spec = references.references_spec(sim, "evaluation", "_evaluation_set")
    path = store.cache_file(store.SHIPPED_CACHE, "references-evaluation", spec)
    shipped = store.read_npz(path)
    assert shipped is not None, f"{path} is not committed: copy it from data/ after a run"
    assert str(shipped["names"][0]) == "circle"
    circle = references.shape_reference(sim, "circle")
    np.testing.assert_allclose(shipped["states_0"], circle.states, rtol=0, atol=1e-8)  # this CPU's last bits
    assert np.array_equal(shipped["mask_0"], circle.mask)


def test_dataset_key_follows_parameters_and_versions_not_the_name(monkeypatch):
    key = data.dataset_path(PAPER).stem
    assert data.dataset_path(PAPER, dataclasses.replace(SIM_ROBOT, name="renamed")).stem == key
    assert data.dataset_path(PAPER, dataclasses.replace(SIM_ROBOT, density=12001.0)).stem != key
    assert data.dataset_path(PAPER, gravity="horizontal").stem != key
    monkeypatch.setattr(dynamics, "SIMULATOR_VERSION", dynamics.SIMULATOR_VERSION + 1)
    assert data.dataset_path(PAPER).stem != key
    monkeypatch.undo()
    monkeypatch.setattr(dataset, "DATA_VERSION", dataset.DATA_VERSION + 1)
    assert data.dataset_path(PAPER).stem != key


def test_editing_comments_and_docstrings_keeps_the_dataset_key(tmp_path):
    """A copy of the package with a comment and a docstring edited gives the same key."""
    package = Path(dynamics.__file__).parent.parent
    copy = tmp_path / "softflow"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("rod/dynamics.py", "data/dataset.py", "rod/kinematics.py", "rod/statics.py"):
        source = (copy / name).read_text()
        (copy / name).write_text(source.replace('"""', '"""Edited. ', 1) + "\n# an edited comment\n")
    code = (
        "from softflow import data; from softflow.profiles import get_profile; "
        "print(data.__file__); print(data.dataset_path(get_profile('paper')).stem)"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True)
    origin, key = out.stdout.split()
    assert Path(origin).parent.parent == copy  # the edited copy was imported
    assert key == data.dataset_path(PAPER).stem
