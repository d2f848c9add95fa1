"""The loop of a model of recorded runs as a robot runs it (make bench-recorded-loop): the loop's
graph (``softflow export --loop``) called by examples/run_loop.py's ``LoopGraph`` (numpy and
onnxruntime alone), at 100 Hz and at 1 kHz.

Each period: one call with the newest frame and the reference rows, then a sleep until the next
deadline, as ``run_loop.run`` paces it. The frames are a held-out recorded run of the loop
study's rig, replayed one per period (the graph's work does not depend on where the tip is),
the models the loop study's seed-0 MLP, RF and RF-FWD (``--profile``: paper, or ci, trained
first if missing). Reports per model and rate: call latency p50 / p99 / p99.9 / max and deadline
misses (a period whose call exceeded the period). Writes figures/bench/recorded_loop.csv.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from results_file import REPO, write_results

from softflow import control
from softflow.control.planning import Controller
from softflow.data import recordings
from softflow.hardware.recorder import motor_columns
from softflow.rod.robots import HW_ROBOT
from softflow.studies import loop
from softflow.studies.study import recorded_cell_model
from softflow.studies.sweep import SWEEPS_DIR

RATES = (100, 1000)  # Hz


def example():
    spec = importlib.util.spec_from_file_location("run_loop", REPO / "examples" / "run_loop.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def paced(graph, frames: np.ndarray, rows: np.ndarray, period: float) -> np.ndarray:
    """Call latencies (s) of the graph over the frames (N, k), one call per ``period``."""
    latencies = np.empty(len(frames))
    deadline = time.perf_counter()
    for n, (frame, wanted) in enumerate(zip(frames, rows)):
        before = time.perf_counter()
        graph(frame, wanted)
        latencies[n] = time.perf_counter() - before
        deadline += period
        left = deadline - time.perf_counter()
        if left > 0:
            time.sleep(left)
        else:
            deadline = time.perf_counter()
    return latencies


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--seconds", type=float, default=20.0, help="per model and rate")
    args = parser.parse_args()
    workdir = SWEEPS_DIR / "loop"
    data = loop.dataset(args.profile, workdir)
    grid = loop.LOOP[args.profile]
    held = loop.record(workdir, args.profile, loop.HELD_OUT_SEED, grid.held_out)[0]
    run = recordings.read(held, inputs=motor_columns(HW_ROBOT), delay=data.delay_steps * data.dt)
    runner, results = example(), {}
    for name in grid.models:
        model, _ = recorded_cell_model(dict(model=name, seed=0), grid, args.profile, data, workdir, "cpu")
        controller = Controller(model, name, robot=None, gravity=None, delay_steps=data.delay_steps, dt=data.dt)
        with tempfile.TemporaryDirectory() as folder:
            graph = runner.LoopGraph(control.export_loop(control.loop_of(controller, data), Path(folder) / "loop.onnx"))
        for rate in RATES:
            n = int(args.seconds * rate)
            index = np.arange(n) % (len(run.states) - data.delay_steps - 2)
            frames = run.states[index, :3]
            rows = run.states[np.stack([index, index + data.delay_steps, index + data.delay_steps + 1], 1)]
            paced(graph, frames[: rate // 10], rows[: rate // 10], 1 / rate)  # warm-up
            ms = 1e3 * paced(graph, frames, rows, 1 / rate)
            results[f"{name}.{rate}hz"] = row = dict(
                p50=float(np.median(ms)),
                p99=float(np.quantile(ms, 0.99)),
                p999=float(np.quantile(ms, 0.999)),
                max=float(ms.max()),
                periods=n,
                deadline_misses=int((ms > 1e3 / rate).sum()),
            )
            print(
                f"{name:7s} {rate:5d} Hz: call p50 {row['p50']:.3f} ms, p99 {row['p99']:.3f}, p99.9 {row['p999']:.3f}, "
                f"max {row['max']:.3f}; deadline misses {row['deadline_misses']} of {n}"
            )
    write_results("recorded_loop", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
