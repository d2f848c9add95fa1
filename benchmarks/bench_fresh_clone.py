"""The README's test command on a fresh clone, as CI runs it (make bench-setup): this commit
cloned into a scratch folder (no .venv, no data/), then `make venv` and `make test` timed one
after the other. The venv's time includes pip's download cache where the machine has one
(CI's machines start without). Writes figures/bench/fresh_clone.csv, where the test time goes
(figures/bench/fresh_clone_tests.csv: each lane's seconds per test file or notebook, setup and
teardown included, and its wall time), and the two logs to build/bench/; run it with the
cores free.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_file import REPO, write_results

LANES = ("lane_a", "lane_b", "last")  # the order make test prints its pytest sessions in
DURATION = re.compile(r"^([\d.]+)s (?:setup|call|teardown)\s+(.+?)::", re.MULTILINE)
SESSION_WALL = re.compile(r"^=+ .* in ([\d.]+)s", re.MULTILINE)  # "=== 466 passed in 859.15s (0:14:19) ==="


def timed(command: list[str], cwd: Path, log: Path, forced: dict | None = None) -> tuple[float, int]:
    """Wall seconds and exit code of ``command`` run as CI runs it, with ``forced`` variables set."""
    start = time.perf_counter()
    with open(log, "w") as out:
        env = dict(os.environ, CI="true", PYTEST_ADDOPTS="--durations=0", **(forced or {}))
        code = subprocess.run(command, cwd=cwd, stdout=out, stderr=subprocess.STDOUT, env=env)
    return time.perf_counter() - start, code.returncode


def seconds_per_file(log: str) -> dict:
    """{lane: {file: seconds, "wall": the session's seconds}} from make test's log: pytest's
    durations summed per test file or notebook, in each of its sessions."""
    sessions = log.split("test session starts")[1:]
    if len(sessions) != len(LANES):
        raise ValueError(f"expected {len(LANES)} pytest sessions in the log; found {len(sessions)}")
    out = {}
    for lane, text in zip(LANES, sessions):
        files: dict[str, float] = {}
        for seconds, file in DURATION.findall(text):
            files[file] = files.get(file, 0.0) + float(seconds)
        out[lane] = dict(sorted(files.items(), key=lambda item: -item[1]), wall=float(SESSION_WALL.findall(text)[-1]))
    return out


def main():
    with tempfile.TemporaryDirectory() as scratch:
        clone = Path(scratch) / "softflow"
        subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
        venv, venv_code = timed(["make", "venv"], clone, Path(scratch) / "venv.log")
        test, test_code = timed(["make", "test"], clone, Path(scratch) / "test.log")
        log = (Path(scratch) / "test.log").read_text()
        tail = log[-3000:]
        logs = REPO / "build" / "bench"
        logs.mkdir(parents=True, exist_ok=True)
        for name in ("venv.log", "test.log"):
            shutil.copy(Path(scratch) / name, logs / f"fresh_clone_{name}")
    results = dict(
        venv_minutes=venv / 60,
        test_minutes=test / 60,
        total_minutes=(venv + test) / 60,
        passed=venv_code == 0 and test_code == 0,
    )
    print(tail)
    print(f"make venv {venv / 60:.1f} min + make test {test / 60:.1f} min = {(venv + test) / 60:.1f} min")
    write_results("fresh_clone", results)
    if test_code == 0:
        write_results("fresh_clone_tests", seconds_per_file(log))
    return 0 if results["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
