"""The README's quickstart runs as written, so it cannot rot: a new user's first ten lines."""

import re
import subprocess
import sys

from softflow.store import REPO


def quickstart() -> str:
    """The first python block under the README's "## Quickstart" heading."""
    text = (REPO / "README.md").read_text()
    section = text.split("## Quickstart", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks, "the README's Quickstart section has no python block"
    return blocks[0]


def test_quickstart_is_short():
    assert len(quickstart().strip().splitlines()) <= 10


def test_quickstart_runs_and_tracks_the_circle(tmp_path):
    """Run in a fresh interpreter outside the repository, as a user's script would."""
    done = subprocess.run(
        [sys.executable, "-c", quickstart()], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    row = done.stdout.strip().splitlines()[-1].split()  # index, model, reference, rmse_mm
    assert row[1:3] == ["rf-fwd", "circle"], done.stdout
    assert 0 < float(row[3]) < 5.0, f"the shipped RF-FWD should track a 5 cm circle within millimetres: {done.stdout}"
