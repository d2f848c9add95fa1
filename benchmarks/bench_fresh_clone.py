"""The README's test command on a fresh clone, as CI runs it (make bench-setup): this commit
cloned into a scratch folder (no .venv, no data/), then `make venv` and `make test` timed one
after the other. The venv's time includes pip's download cache where the machine has one
(CI's machines start without). Writes figures/bench/fresh_clone.csv, and the two logs to
build/bench/ (the test log lists each lane's 40 slowest tests); run it with the cores free.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_file import REPO, write_results


def timed(command: list[str], cwd: Path, log: Path) -> tuple[float, int]:
    start = time.perf_counter()
    with open(log, "w") as out:
        env = dict(os.environ, CI="true", PYTEST_ADDOPTS="--durations=40")
        code = subprocess.run(command, cwd=cwd, stdout=out, stderr=subprocess.STDOUT, env=env)
    return time.perf_counter() - start, code.returncode


def main():
    with tempfile.TemporaryDirectory() as scratch:
        clone = Path(scratch) / "softflow"
        subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
        venv, venv_code = timed(["make", "venv"], clone, Path(scratch) / "venv.log")
        test, test_code = timed(["make", "test"], clone, Path(scratch) / "test.log")
        tail = (Path(scratch) / "test.log").read_text()[-3000:]
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
    return 0 if results["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
