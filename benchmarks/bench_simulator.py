"""Simulator speed, side by side in one run (make bench):

1. the paper's dataset size (default 3000 episodes x 5 s of polynomial excitation) at the
   default accuracy: wall time and episodes/s;
2. the same rod and input in PyElastica (benchmarks/pyelastica_rod.py, run in its own
   venv .venv-elastica): wall time per simulated second, our speed-up (one episode, and
   per episode in a batch of 256), and the tip-trajectory difference of a 2 s response.

The two-segment rod has its own script, bench_two_segment.py.

Writes figures/bench/simulator.csv and prints a summary.
"""

from __future__ import annotations

import argparse
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from results_file import write_results

from softflow.data.excitation import polynomial_excitation
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT

HERE = Path(__file__).resolve().parent
ELASTICA_PYTHON = HERE.parent / ".venv-elastica" / "bin" / "python"


def smooth_3d_input(seconds: float = 2.0) -> np.ndarray:
    """The 2 s comparison input: u1 = 2 sin(2 pi 0.8 t), u2 = 1.5 (1 - cos(2 pi 0.5 t))."""
    t = np.arange(int(round(seconds / DT))) * DT
    return np.stack([2 * np.sin(2 * np.pi * 0.8 * t), 1.5 * (1 - np.cos(2 * np.pi * 0.5 * t))], -1)


def run_pyelastica(robot, inputs, **options) -> list[dict]:
    """PyElastica's trajectories of ``robot`` for each input (T, m) of ``inputs``, in its own
    interpreter: ``pyelastica_rod.simulate(robot, u, **options)`` each (tip, disks, wall_seconds)."""
    with tempfile.TemporaryDirectory() as tmp:
        job = Path(tmp) / "job.pkl"
        job.write_bytes(pickle.dumps((robot, [np.asarray(u, dtype=float) for u in inputs], options)))
        script = (
            f"import pickle, sys; sys.path[:0] = [{str(HERE)!r}, {str(HERE.parent)!r}]; import pyelastica_rod;"
            f"from pathlib import Path; job = Path({str(job)!r});"
            f"robot, inputs, options = pickle.loads(job.read_bytes());"
            f"job.write_bytes(pickle.dumps([pyelastica_rod.simulate(robot, u, **options) for u in inputs]))"
        )
        subprocess.run([str(ELASTICA_PYTHON), "-c", script], check=True)
        return pickle.loads(job.read_bytes())


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=3000)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    results = {}

    sim = Simulator(SIM_ROBOT, gravity="vertical")
    u = polynomial_excitation(args.episodes, int(round(args.seconds / DT)), np.random.default_rng(0))
    start = time.perf_counter()
    sim.rollout(u, progress=True)
    wall = time.perf_counter() - start
    results["dataset"] = dict(
        episodes=args.episodes, seconds_each=args.seconds, wall_seconds=wall, episodes_per_second=args.episodes / wall
    )
    print(f"ours: {args.episodes} episodes x {args.seconds} s in {wall:.1f} s ({args.episodes / wall:.1f} episodes/s)")

    u2 = smooth_3d_input()
    free = Simulator(SIM_ROBOT, gravity="none")
    start = time.perf_counter()
    ours = free.rollout(u2[None])[0, :, :3]
    single = time.perf_counter() - start
    start = time.perf_counter()
    free.rollout(np.repeat(u2[None], 256, 0))
    batched = (time.perf_counter() - start) / 256
    simulated = len(u2) * DT
    results["ours_s_per_simulated_s"] = dict(single=single / simulated, batched_256=batched / simulated)
    if not ELASTICA_PYTHON.exists():
        print(f"PyElastica comparison skipped: {ELASTICA_PYTHON} missing (see benchmarks/README.md)")
    else:
        elastica = run_pyelastica(SIM_ROBOT, [u2])[0]
        difference = np.linalg.norm(elastica["tip"] - ours, axis=1)
        results["pyelastica"] = dict(
            s_per_simulated_s=elastica["wall_seconds"] / simulated,
            speedup_single=elastica["wall_seconds"] / single,
            speedup_batched=elastica["wall_seconds"] / batched,
            max_tip_difference_mm=1e3 * difference.max(),
            max_tip_difference_percent_L=100 * difference.max() / SIM_ROBOT.length,
            rms_tip_difference_mm=1e3 * np.sqrt(np.mean(difference**2)),
        )
        e = results["pyelastica"]
        print(
            f"2 s response: PyElastica {e['s_per_simulated_s']:.2f} s per simulated s; ours {single / simulated:.3f} "
            f"(one episode) and {batched / simulated:.4f} (per episode, batch of 256): speed-up "
            f"{e['speedup_single']:.0f}x / {e['speedup_batched']:.0f}x"
        )
        print(
            f"tip difference: max {e['max_tip_difference_mm']:.2f} mm "
            f"({e['max_tip_difference_percent_L']:.2f} % of L), "
            f"RMS {e['rms_tip_difference_mm']:.2f} mm"
        )
    write_results("simulator", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
