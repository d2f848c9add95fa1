"""`make test` on a fresh clone under kernel paths forced by the environment (make portability):
the CPU's own (native), a generic x86-64 one and an AVX2 one, one after the other, none of them
set by the Makefile, so the suite is shown to pass on paths it does not choose. Each run's
outcome and wall time, with the CPU model and its flags, go to figures/bench/portability.csv;
how far each path's trained ci results (the full-precision CSVs the ci notebooks write) lie from
the native ones goes to figures/bench/portability_spread.csv: the spread that sets the
notebooks' tolerance (notebooks/conftest.py). Logs in build/bench/; run it with the cores free.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
from bench_fresh_clone import timed
from results_file import REPO, RESULTS

from softflow.machine import description
from softflow.report.provenance import commit

NUMPY_SSE42 = "SSE SSE2 SSE3 SSSE3 SSE41 POPCNT SSE42"
# numpy 2.4 dispatches by x86-64 levels: a list of single features up to AVX2 leaves it at its
# X86_V2 baseline (nothing from X86_V3 is enabled unless every feature of the level is); the
# level's name enables its AVX2 kernels.
NUMPY_AVX2 = "X86_V2 X86_V3"
PATHS = {
    "native": {},
    "generic": dict(
        ATEN_CPU_CAPABILITY="default",
        MKL_CBWR="COMPATIBLE",
        OPENBLAS_CORETYPE="Prescott",
        NPY_ENABLE_CPU_FEATURES=NUMPY_SSE42,
        NUMBA_CPU_NAME="generic",
    ),
    "avx2": dict(
        ATEN_CPU_CAPABILITY="avx2",
        MKL_CBWR="AVX2",
        OPENBLAS_CORETYPE="Haswell",
        NPY_ENABLE_CPU_FEATURES=NUMPY_AVX2,
        NUMBA_CPU_NAME="haswell",
    ),
}
SPREAD_LOG = "SOFTFLOW_NBVAL_SPREAD"  # notebooks/conftest.py logs each tolerant cell's deviation here


def cpu_flags() -> str:
    """The CPU's vector extensions (the flags that choose kernels), from /proc/cpuinfo."""
    info = Path("/proc/cpuinfo")
    if not info.exists():
        return ""
    lines = info.read_text().splitlines()
    flags = next((line.split(":", 1)[1].split() for line in lines if line.startswith("flags")), [])
    return " ".join(f for f in flags if f.startswith(("sse", "ssse", "avx", "fma", "f16c", "amx")))


def kernels(python: Path, env: dict) -> str:
    """What numpy and torch say they run under ``env``."""
    probe = (
        "import torch; from numpy._core import _multiarray_umath as m; "
        "enabled = [k for k in m.__cpu_dispatch__ if m.__cpu_features__.get(k)]; "
        "print('numpy', enabled[-1] if enabled else 'baseline ' + ' '.join(m.__cpu_baseline__), "
        "'torch', torch.backends.cpu.get_cpu_capability())"
    )
    result = subprocess.run([str(python), "-c", probe], capture_output=True, text=True, env=env)
    return result.stdout.strip() or result.stderr.strip()[-200:]


def numeric_spread(native: Path, other: Path) -> dict:
    """{file: largest relative difference of any number} between two build/ci folders' CSVs."""
    out = {}
    for path in sorted(native.glob("*.csv")):
        mine = other / path.name
        if not mine.exists():
            continue
        try:
            a, b = pd.read_csv(path), pd.read_csv(mine)
        except pd.errors.EmptyDataError:  # a table without columns (a notebook's empty result): no numbers
            continue
        numbers = [c for c in a.columns if pd.api.types.is_float_dtype(a[c]) and c in b and len(a) == len(b)]
        numbers = [c for c in numbers if not c.endswith(("seconds", "minutes", "_ms", "_min"))]  # wall times
        if not numbers:
            continue
        x, y = a[numbers].to_numpy(float), b[numbers].to_numpy(float)
        scale = np.maximum(np.abs(x), 1e-9)
        out[path.name] = float(np.nanmax(np.abs(x - y) / scale, initial=0.0))
    return out


def main() -> int:
    rows, spreads, outputs = [], [], {}
    logs = REPO / "build" / "bench"
    logs.mkdir(parents=True, exist_ok=True)
    tested = commit()  # every path tests this commit, whatever lands meanwhile
    with tempfile.TemporaryDirectory() as scratch:
        for name, forced in PATHS.items():
            clone = Path(scratch) / name
            subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
            subprocess.run(["git", "-C", str(clone), "checkout", "--quiet", tested], check=True)
            venv_seconds, venv_code = timed(["make", "venv"], clone, logs / f"portability_{name}_venv.log")
            spread_log = logs / f"portability_{name}_cells.jsonl"  # kept: which cell used how much
            spread_log.unlink(missing_ok=True)
            env = dict(forced, **{SPREAD_LOG: str(spread_log)})
            seconds, code = timed(["make", "test"], clone, logs / f"portability_{name}_test.log", env)
            cells = [json.loads(line) for line in spread_log.read_text().splitlines()] if spread_log.exists() else []
            used = [cell["used"] for cell in cells if cell["used"] is not None]
            rows.append(
                dict(
                    path=name,
                    environment=" ".join(f"{k}={v}" for k, v in forced.items()) or "(none)",
                    kernels=kernels(clone / ".venv" / "bin" / "python", dict(os.environ, **forced)),
                    passed=venv_code == 0 and code == 0,
                    venv_minutes=round(venv_seconds / 60, 2),
                    test_minutes=round(seconds / 60, 2),
                    tolerant_cells=len(cells),
                    largest_share_of_tolerance=max(used, default=0.0),  # a printed number's |ran - committed| / allowed
                    machine=description(),
                    cpu_flags=cpu_flags(),
                    date=datetime.now(UTC).strftime("%Y-%m-%d"),
                    commit=tested,
                )
            )
            outputs[name] = Path(scratch) / f"{name}-ci"
            shutil.copytree(clone / "build" / "ci", outputs[name], ignore=shutil.ignore_patterns("*.png"))
            print(f"{name}: {'passed' if rows[-1]['passed'] else 'FAILED'} in {seconds / 60:.1f} min", flush=True)
            shutil.rmtree(clone / ".venv")
        for name in list(PATHS)[1:]:
            for file, value in numeric_spread(outputs["native"], outputs[name]).items():
                spreads.append(dict(path=name, file=file, largest_relative_difference=value))
    RESULTS.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(RESULTS / "portability.csv", index=False)
    pd.DataFrame(spreads).to_csv(RESULTS / "portability_spread.csv", index=False)
    print(pd.DataFrame(rows).drop(columns=["cpu_flags"]).to_string(index=False))
    return 0 if all(row["passed"] for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
