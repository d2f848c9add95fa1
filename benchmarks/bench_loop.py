"""A 1 kHz control loop in Python, as a robot's controller would run it (make bench-loop).

Each 1 ms period: read the plant's state x_t, ``Controller.step(x_t, x*_{t+1})`` towards the
next state of a held-out reference of the paper rod (workspace check included), send u to
the plant, then wait for the next period. The plant is the GVS simulator's run of that
held-out episode, simulated ahead and replayed (one simulated step costs about 1.4 ms, more
than the period; a learned surrogate fed back into the inverse model drifts out of the
workspace within a second), so every state is the rod's and the period's work is the
controller's. The episode restarts every 500 periods. The loop runs for ``--seconds`` per
model, with Python's garbage collector on (a user's default): with the cores idle, waiting for
each period by sleeping (a user's default); with the cores idle, spinning through the wait (a
controller on a core of its own: the core never idles, so its caches and clock stay warm, and
the step costs what the planning benchmark measures); and sleeping beside a process that keeps
one core busy.

Reports per run: step latency (the call alone) and the period's work (state, step, send)
at p50 / p99 / p99.9 and their maximum, deadline misses (a period whose work exceeded 1 ms),
and late starts (a period begun more than 1 ms after its deadline, e.g. preempted while
waiting). Uses the profile's trained models (default: paper, the shipped weights; another
profile trains them first if missing). Writes figures/bench/loop.csv.
"""

from __future__ import annotations

import argparse
import gc
import subprocess
import sys
import time

import numpy as np
from results_file import trained_controller, write_results

from softflow import data
from softflow.profiles import get_profile

PERIOD = 1e-3  # s
SPIN = 2e-4  # s before a deadline the loop stops sleeping and spins, for a punctual start


CONDITIONS = {"idle": (False, SPIN), "idle_spinning": (False, PERIOD), "one_core_busy": (True, SPIN)}  # busy, spin


def run_loop(controller, plant, seconds: float, spin: float = SPIN) -> dict:
    """The loop for ``seconds`` on the plant's states (T+1, d), sleeping until ``spin`` seconds
    before each deadline and spinning from there: latencies (s) of each period's step and
    work, and the count of late starts."""
    n = int(round(seconds / PERIOD))
    steps, works, late = np.empty(n), np.empty(n), 0
    T = len(plant) - 1
    sent = np.empty((n, controller.model.dims.inputs))
    gc.collect()
    start = time.perf_counter()
    for k in range(n):
        deadline = start + k * PERIOD
        while (now := time.perf_counter()) < deadline:
            if deadline - now > spin:
                time.sleep(deadline - now - spin)
        late += now - deadline > PERIOD
        t = k % T
        x_t = plant[t]
        before = time.perf_counter()
        u = controller.step(x_t, plant[t + 1])
        after = time.perf_counter()
        sent[k] = u
        steps[k], works[k] = after - before, time.perf_counter() - now
    return dict(steps=steps, works=works, late=late)


def summary(run: dict) -> dict:
    out = {}
    for what in ("steps", "works"):
        ms = 1e3 * run[what]
        out[f"{what[:-1]}_ms"] = {
            "p50": float(np.median(ms)),
            "p99": float(np.quantile(ms, 0.99)),
            "p99.9": float(np.quantile(ms, 0.999)),
            "max": float(ms.max()),
        }
    out["periods"] = len(run["steps"])
    out["deadline_misses"] = int((run["works"] > PERIOD).sum())
    out["late_starts"] = run["late"]
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--models", default="mlp,rf,rf-fwd,rf-physical,rf-1,rf-fwd-1,rf-physical-1")
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    held_out = data.load_dataset(get_profile("ci"), progress=False)  # the rod's own runs, made in seconds
    plant = held_out.states[held_out.test[0]]  # (501, 6): the simulated rod on a held-out episode
    results = {}
    for condition, (loaded, spin) in CONDITIONS.items():
        busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if loaded else None
        try:
            for name in args.models.split(","):
                controller = trained_controller(name, args.profile)
                run_loop(controller, plant, 1.0, spin)  # warm-up: caches, the grid, the allocator
                results[f"{condition}.{name}"] = row = summary(run_loop(controller, plant, args.seconds, spin))
                print(
                    f"{condition:14s} {name:12s} step p50 {row['step_ms']['p50']:.3f} ms, "
                    f"p99 {row['step_ms']['p99']:.3f}, p99.9 {row['step_ms']['p99.9']:.3f}, "
                    f"max {row['step_ms']['max']:.3f}; work p99.9 "
                    f"{row['work_ms']['p99.9']:.3f} ms; deadline misses {row['deadline_misses']} of {row['periods']}, "
                    f"late starts {row['late_starts']}"
                )
        finally:
            if busy is not None:
                busy.kill()
                busy.wait()
    write_results("loop", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
