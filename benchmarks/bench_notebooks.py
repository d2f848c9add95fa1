"""What each notebook's ci run costs (make bench-setup): every notebook in make reproduce's order
(07 last, it reads the others' results), through papermill, one BLAS thread, from one empty
data folder, so a notebook's time includes what it computes first and excludes what an earlier
one left cached (02's references, 03's models for 04 and 08). CPU is user + system time of the
notebook's process tree, the cost on a busy machine; wall time is the wait on an idle one.
Writes figures/bench/notebooks.csv (the README's notebook table).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_file import REPO, write_results

PAPERMILL = Path(sys.executable).parent / "papermill"


def notebooks_in_order() -> list[Path]:
    found = sorted((REPO / "notebooks").glob("[0-9]*.ipynb"))
    last = [nb for nb in found if nb.name.startswith("07_")]
    return [nb for nb in found if nb not in last] + last


def children_cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", nargs="*", help="notebook name prefixes (e.g. 01 12); default all")
    args = parser.parse_args()
    chosen = [nb for nb in notebooks_in_order() if not args.only or nb.name[:2] in args.only]
    results = dict(profile="ci", threads=1, notebooks={})
    with tempfile.TemporaryDirectory() as scratch:
        env = dict(os.environ, SOFTFLOW_DATA=str(Path(scratch) / "data"), OMP_NUM_THREADS="1")
        for notebook in chosen:
            cpu, start = children_cpu_seconds(), time.perf_counter()
            command = [str(PAPERMILL), "--cwd", "notebooks", "-p", "profile", "ci", str(notebook)]
            run = subprocess.run([*command, str(Path(scratch) / notebook.name)], cwd=REPO, env=env, capture_output=True)
            if run.returncode:
                sys.exit(f"{notebook.name} failed:\n{run.stderr.decode()[-3000:]}")
            seconds = dict(
                cpu_minutes=(children_cpu_seconds() - cpu) / 60, wall_minutes=(time.perf_counter() - start) / 60
            )
            results["notebooks"][notebook.stem] = seconds
            print(f"{notebook.stem:28s} {seconds['cpu_minutes']:5.1f} CPU min, {seconds['wall_minutes']:5.1f} min wall")
    write_results("notebooks" if not args.only else "notebooks-partial", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
