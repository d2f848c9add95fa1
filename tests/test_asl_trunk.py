"""The curated ASL trunk runs (datasets/asl_trunk/README.md): the committed files are those the
script rebuilds from the upstream files, and the loader finds in the real runs what the README
and docs/recordings.md say: the lost frames per disk, the long gaps, the noise at rest and the
input-to-motion delay."""

import gzip
import hashlib
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from softflow import recordings
from softflow.store import REPO

CURATED = REPO / "datasets" / "asl_trunk"
UPSTREAM = REPO.parent / "shared" / "datasets" / "asl_trunk"
RUNS = ("circles", "payload_100g", "payload_300g", "random_1", "random_2", "rest")
DISKS = [f"{axis}{disk}_m" for disk in (1, 2, 3) for axis in "xyz"]
TIP = DISKS[6:]
needs_upstream = pytest.mark.skipif(
    not UPSTREAM.is_dir(), reason=f"the upstream ASL trunk files are not at {UPSTREAM} (README.md: where from)"
)


def sums(text: str) -> dict:
    return {name: digest for digest, name in (line.split() for line in text.splitlines() if line.strip())}


def curate(upstream, out, script=CURATED / "curate.py"):
    return subprocess.run(
        [sys.executable, str(script), str(upstream), "--out", str(out)], capture_output=True, text=True, timeout=120
    )


# ---------------------------------------------------------------------------- the files
def test_the_committed_files_are_those_recorded_and_small():
    recorded = sums((CURATED / "SHA256SUMS").read_text())
    assert sorted(recorded) == [f"{run}.csv.gz" for run in RUNS]
    for name, digest in recorded.items():
        assert hashlib.sha256((CURATED / name).read_bytes()).hexdigest() == digest, name
    assert sum((CURATED / name).stat().st_size for name in recorded) < 10e6
    licence = (CURATED / "LICENSE").read_text()
    assert licence.startswith("MIT License") and "Copyright (c) 2024 Stanford Autonomous Systems Lab" in licence
    assert "8b4b9234b287a0403d1844821bfad79e36e1f66f" in (CURATED / "README.md").read_text()


def test_each_run_is_one_observation_more_than_its_inputs_on_a_100_hz_clock():
    for run in RUNS:
        table = pd.read_csv(CURATED / f"{run}.csv.gz")
        assert list(table.columns) == ["time_s", "u1", "u2", "u3", "u4", "u5", "u6", *DISKS]
        assert len(table) == (3001 if run == "rest" else 15001)
        np.testing.assert_allclose(table.time_s, np.arange(len(table)) / 100)
        inputs = table[[f"u{i}" for i in range(1, 7)]]
        assert inputs.iloc[-1].isna().all() and inputs.iloc[:-1].notna().all().all()
        heights = table[["y1_m", "y2_m", "y3_m"]].median()  # y is vertical: the disks hang below the base
        assert table[DISKS].notna().all().all() and 0 > heights.y1_m > heights.y2_m > heights.y3_m > -0.4
    assert (pd.read_csv(CURATED / "rest.csv.gz").filter(like="u").fillna(0) == 0).all().all()
    inputs = [f"u{i}" for i in range(1, 7)]
    for payload in ("payload_100g", "payload_300g"):  # random_1's inputs replayed with a mass at the tip
        pd.testing.assert_frame_equal(
            pd.read_csv(CURATED / f"{payload}.csv.gz")[inputs], pd.read_csv(CURATED / "random_1.csv.gz")[inputs]
        )


@needs_upstream
def test_the_script_rebuilds_the_committed_files_from_the_upstream_ones(tmp_path):
    done = curate(UPSTREAM, tmp_path)
    assert done.returncode == 0, done.stderr
    for name, digest in sums((CURATED / "SHA256SUMS").read_text()).items():
        assert hashlib.sha256((tmp_path / name).read_bytes()).hexdigest() == digest
    assert (CURATED / "LICENSE").read_bytes() == (UPSTREAM / "LICENSE").read_bytes()


@needs_upstream
def test_the_script_refuses_a_changed_upstream_file_and_outputs_that_differ(tmp_path):
    changed = tmp_path / "upstream"
    shutil.copytree(UPSTREAM, changed)
    target = changed / "observations_controlled_1.csv"
    target.chmod(0o644)
    target.write_bytes(target.read_bytes().replace(b"0.1", b"0.2", 1))
    done = curate(changed, tmp_path / "out")
    assert done.returncode == 1 and "observations_controlled_1.csv: SHA-256" in done.stderr
    assert not (tmp_path / "out").exists()  # checked before anything is written
    moved = tmp_path / "script"  # the script beside a SHA256SUMS that records another table
    moved.mkdir()
    shutil.copy(CURATED / "curate.py", moved)
    recorded = (CURATED / "SHA256SUMS").read_text()
    (moved / "SHA256SUMS").write_text(recorded.replace(recorded[:8], "00000000", 1))
    done = curate(UPSTREAM, tmp_path / "out", moved / "curate.py")
    assert done.returncode == 1 and "differs from the recorded" in done.stderr and "table itself differs" in done.stderr


def test_the_compression_carries_no_name_or_time():
    packed = (CURATED / "rest.csv.gz").read_bytes()
    assert packed[:10] == b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x02\xff"
    assert gzip.decompress(packed).startswith(b"time_s,u1,")


# ---------------------------------------------------------------------------- what the loader finds
LOST = {  # run: (held frames, one-frame jumps) per disk 1, 2, 3, measured (README.md)
    "random_1": ([106, 77, 14], [10, 24, 1]),
    "random_2": ([61, 105, 33], [6, 38, 1]),
    "circles": ([423, 73, 67], [1, 32, 0]),
    "rest": ([134, 4, 23], [0, 0, 0]),
    "payload_100g": ([60, 25, 30], [7, 28, 3]),
    "payload_300g": ([42, 27, 22], [8, 27, 1]),
}


@pytest.mark.parametrize("run", LOST)
def test_the_lost_frames_per_disk(run):
    table = pd.read_csv(CURATED / f"{run}.csv.gz")
    lost, frozen, jumps = recordings.lost_frames(table.time_s, table[DISKS].to_numpy(), DISKS)
    assert (frozen[::3].tolist(), jumps[::3].tolist()) == LOST[run]
    for disk in range(3):  # a disk's frame is lost whole
        assert (lost[:, 3 * disk : 3 * disk + 3] == lost[:, [3 * disk]]).all()


def test_the_noise_at_rest_is_a_few_micrometres():
    table = pd.read_csv(CURATED / "rest.csv.gz")
    positions = table[DISKS].to_numpy()
    lost = recordings.lost_frames(table.time_s, positions, DISKS)[0]
    spread = [positions[~lost[:, i], i].std() for i in range(9)]
    assert 2e-6 < min(spread) and max(spread) < 9e-6


def test_long_gaps_are_refused_with_all_disks_and_the_runs_cut_there_on_request():
    """random_2 loses disk 2 for 0.33 s at 101.97 s, circles disk 1 for 0.29 and 0.50 s in its first
    second: cut there, 10-s episodes come from the stretches 0-101.97 s and 102.30-150 s of random_2
    and 0.97-150 s of circles (0.29-0.47 s is shorter than an episode), each 22 pairs shorter; payload_100g
    has no long gap."""
    path = CURATED / "random_2.csv.gz"
    levels = dict(noise=1e-5, jerk=100.0)  # fixed: seconds instead of a minute; the gaps do not depend on them
    with pytest.raises(
        ValueError,
        match=r"rows 10197-10230, column 'x2_m': 0\.330 s between frames .*judged lost there: rows .* \(held\)",
    ):
        recordings.read(path, tip=DISKS, delay=0.0, **levels)
    files = [path, CURATED / "circles.csv.gz", CURATED / "payload_100g.csv.gz"]
    options = dict(tip=DISKS, delay=0.22, episode_seconds=10.0, fractions=(1 / 3, 1 / 3), data_dir=None, **levels)
    data = recordings.load_dataset(files, split_at_gaps=True, **options)
    pairs = [10197 - 22, 4770 - 22, 14903 - 22, 15000 - 22]  # random_2, random_2, circles, payload_100g
    assert data.delay_steps == 22 and len(data.u) == sum(-(-n // 1000) for n in pairs)


def test_the_trunk_responds_to_the_input_sent_about_a_fifth_of_a_second_earlier():
    """Fixed smoother levels keep it to seconds; the fitted ones give the same estimates."""
    path = CURATED / "random_1.csv.gz"
    disks = recordings.read(path, tip=DISKS, noise=1e-5, jerk=100.0)
    tip = recordings.read(path, tip=TIP, noise=1e-5, jerk=100.0)
    assert (disks.delay_steps, tip.delay_steps) == (23, 21) and disks.delay == pytest.approx(0.23)
    assert disks.frozen.tolist() == [106] * 3 + [77] * 3 + [14] * 3
