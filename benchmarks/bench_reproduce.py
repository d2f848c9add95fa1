"""The README's main command on a fresh clone, as a new user runs it: this commit cloned into
build/bench/reproduce/ (no .venv, no data/), then `make venv` and `make reproduce` timed one after
the other, each notebook from the moment make starts it. Run it with the cores free (about half an
hour on two cores).

Writes figures/bench/reproduce_fresh_clone.csv (the venv's, each notebook's, the result block's
and the total minutes, and whether it passed) and copies the clone's figures/bench/reproduce.csv
(papermill's own time per notebook, what docs/results.md shows) back; the log is
build/bench/reproduce.log, and `git -C build/bench/reproduce status` shows which committed files
the run rewrote.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from pathlib import Path

from results_file import REPO, RESULTS, write_results

CLONE = REPO / "build" / "bench" / "reproduce"
LOG = REPO / "build" / "bench" / "reproduce.log"


def timed_stages(command: list[str], cwd: Path, log) -> tuple[dict, int]:
    """{stage: seconds} and the exit code of ``command``: a stage starts at each "== notebooks/NN.ipynb"
    line make prints and ends at the next (the last one, "result block", after 07)."""
    stages, stage, start = {}, "before the first notebook", time.perf_counter()
    process = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for line in process.stdout:
        log.write(line)
        log.flush()
        if line.startswith("== notebooks/") or line.startswith(".venv/bin/python -m softflow.report.readme"):
            now = time.perf_counter()
            stages[stage], start = now - start, now
            stage = line.split()[1].removeprefix("notebooks/") if line.startswith("==") else "result block"
    stages[stage] = time.perf_counter() - start
    return stages, process.wait()


def main():
    shutil.rmtree(CLONE, ignore_errors=True)
    CLONE.parent.mkdir(parents=True, exist_ok=True)
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(CLONE)], check=True)
    with open(LOG, "w") as log:
        venv, venv_code = timed_stages(["make", "venv"], CLONE, log)
        stages, code = timed_stages(["make", "reproduce"], CLONE, log) if venv_code == 0 else ({}, venv_code)
    venv_seconds = sum(venv.values())
    stages.pop("before the first notebook", None)
    total = venv_seconds + sum(stages.values())
    results = dict(
        venv_minutes=venv_seconds / 60,
        **{f"{stage}_minutes": seconds / 60 for stage, seconds in stages.items()},
        total_minutes=total / 60,
        exit_status=code,
    )
    for name, value in results.items():
        print(f"{name}: {value:.2f}" if isinstance(value, float) else f"{name}: {value}")
    cloned = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=CLONE, capture_output=True, text=True)
    write_results("reproduce_fresh_clone", results, measured=cloned.stdout.strip())  # commits may land meanwhile
    if code == 0:
        shutil.copy(CLONE / "figures" / "bench" / "reproduce.csv", RESULTS / "reproduce.csv")
    changed = subprocess.run(["git", "status", "--short"], cwd=CLONE, capture_output=True, text=True).stdout
    print("files the run rewrote or added:\n" + changed)
    return code


if __name__ == "__main__":
    sys.exit(main())
