"""The two-segment rod (``TWO_SEGMENT_ROD``) against PyElastica, and its speed (make bench):

1. statics: the gravity-free static tip and middle disk of ours and of PyElastica (settled
   from rest) beside the closed-form piecewise arcs, for S-shaped inputs (u1 and u3 of
   opposite signs, all four inputs non-zero);
2. a 2 s response to a smooth 4-input input that bends the two segments in different
   planes: tip and middle-disk difference to PyElastica (benchmarks/pyelastica_rod.py, run
   in its own venv .venv-elastica);
3. speed on that response: PyElastica's wall time per simulated second against ours (one
   episode, and per episode in a batch of 256);
4. the batched rollout beside the one-segment rod on the same episodes (5 s of polynomial
   excitation, the one-segment rod driven by the tip pair) at two batch sizes, so that the
   per-episode cost shows whether a larger batch (the dataset's 3000) scales linearly.

Writes figures/bench/two_segment.csv and prints a summary.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np
from bench_simulator import ELASTICA_PYTHON, run_pyelastica
from results_file import write_results

from softflow.data.excitation import polynomial_excitation
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT, TWO_SEGMENT_ROD
from softflow.rod.validation import arc_disk_positions

ROBOT = TWO_SEGMENT_ROD
# S-shaped: the tip cables (u3, u4) bend the second segment against the first, whose
# curvature is (u1 + u3, u2 + u4) r / EI.
STATIC_INPUTS = np.array([[-3.0, 1.0, 2.0, 1.0], [3.0, -2.0, -2.0, 1.5], [-2.5, -1.5, 1.5, 2.0]])  # (3, 4) N
SETTLING_DAMPING = 6.0  # zeta_1 ~ 0.7: PyElastica settles in 2 s; the equilibrium does not depend on it


def smooth_4_input(seconds: float = 2.0) -> np.ndarray:
    """The 2 s comparison input, (T, 4): u1 = 2 sin(2 pi 0.8 t), u2 = 1.5 (1 - cos(2 pi 0.5 t))
    at the middle disk, u3 = -1.5 (1 - cos(2 pi 0.4 t)), u4 = 1.2 sin(2 pi 1.1 t) at the tip, so
    the second segment turns in another plane than the first and the pairs change sign apart."""
    t = np.arange(int(round(seconds / DT))) * DT
    return np.stack(
        [
            2 * np.sin(2 * np.pi * 0.8 * t),
            1.5 * (1 - np.cos(2 * np.pi * 0.5 * t)),
            -1.5 * (1 - np.cos(2 * np.pi * 0.4 * t)),
            1.2 * np.sin(2 * np.pi * 1.1 * t),
        ],
        -1,
    )


def two_segment_side_by_side(episodes: int, seconds: float, repeats: int = 2) -> dict:
    """Wall time (s) of a batched rollout of the two-segment rod and of the one-segment rod
    on the same episodes: u (B, T, 4) for the former, its tip pair u[..., 2:] for the latter."""
    rng = np.random.default_rng(1)
    n_steps = int(round(seconds / DT))
    u = np.concatenate([polynomial_excitation(episodes, n_steps, rng) for _ in range(2)], -1)  # (B, T, 4)
    rods = {"one_segment": (Simulator(SIM_ROBOT), u[..., 2:]), "two_segment": (Simulator(TWO_SEGMENT_ROD), u)}
    walls = {name: np.inf for name in rods}
    for _ in range(repeats):  # alternate, keep the faster run of each: load on a shared machine hits both alike
        for name, (sim, inputs) in rods.items():
            start = time.perf_counter()
            sim.rollout(inputs)
            walls[name] = min(walls[name], time.perf_counter() - start)
    simulated = episodes * seconds
    return dict(
        episodes=episodes,
        seconds_each=seconds,
        repeats=repeats,
        threads=rods["one_segment"][0].threads,
        one_segment_wall_seconds=walls["one_segment"],
        two_segment_wall_seconds=walls["two_segment"],
        one_segment_s_per_episode_second=walls["one_segment"] / simulated,
        two_segment_s_per_episode_second=walls["two_segment"] / simulated,
        ratio=walls["two_segment"] / walls["one_segment"],
    )


def difference(a: np.ndarray, b: np.ndarray, length: float) -> dict:
    """Max and RMS of |a - b| over time, in mm and % of the rod's length: (T+1, 3) each."""
    d = np.linalg.norm(a - b, axis=-1)
    rms = np.sqrt(np.mean(d**2))
    return dict(
        max_mm=1e3 * d.max(), max_percent_L=100 * d.max() / length, rms_mm=1e3 * rms, rms_percent_L=100 * rms / length
    )


def statics(results: dict) -> None:
    """Equilibria of ours and of PyElastica beside the piecewise arcs (the tip and the middle disk)."""
    ours = Simulator(ROBOT, gravity="none")
    ours_disks = ours.disk_positions(ours.static_q(STATIC_INPUTS))  # (N, 2, 3)
    arcs = arc_disk_positions(STATIC_INPUTS, ROBOT)  # (N, 2, 3)
    settled = dataclasses.replace(ROBOT, damping=SETTLING_DAMPING * ROBOT.damping)
    theirs = [r["disks"][-1] for r in run_pyelastica(settled, [u[None] for u in STATIC_INPUTS], duration=2.0)]
    for i, u in enumerate(STATIC_INPUTS):
        row = dict(u=" ".join(f"{v:g}" for v in u), tip_mm=" ".join(f"{v:.2f}" for v in 1e3 * arcs[i, -1]))
        for part, k in (("tip", -1), ("middle", 0)):
            row[f"{part}_ours_vs_arc_mm"] = 1e3 * np.linalg.norm(ours_disks[i, k] - arcs[i, k])
            row[f"{part}_pyelastica_vs_arc_mm"] = 1e3 * np.linalg.norm(theirs[i][k] - arcs[i, k])
            row[f"{part}_ours_vs_pyelastica_mm"] = 1e3 * np.linalg.norm(ours_disks[i, k] - theirs[i][k])
        results[f"static_{i}"] = row
        print(
            f"static u = ({row['u']}): tip at ({row['tip_mm']}) mm; ours vs PyElastica: tip "
            f"{row['tip_ours_vs_pyelastica_mm']:.3f} mm, middle disk {row['middle_ours_vs_pyelastica_mm']:.3f} mm; "
            f"PyElastica vs arcs {row['tip_pyelastica_vs_arc_mm']:.3f} mm, "
            f"ours vs arcs {row['tip_ours_vs_arc_mm']:.1e} mm"
        )


def response_and_speed(results: dict) -> None:
    """The 2 s response: trajectory differences and wall times of both codes."""
    u = smooth_4_input()
    simulated = len(u) * DT
    sim = Simulator(ROBOT, gravity="none")
    qs = sim.integrate(u[None], sim.rest_q()[None], np.zeros((1, sim.nq)))[0][0]  # (T+1, nq)
    ours = sim.disk_positions(qs)  # (T+1, 2, 3)
    start = time.perf_counter()
    sim.rollout(u[None])
    single = time.perf_counter() - start
    start = time.perf_counter()
    sim.rollout(np.repeat(u[None], 256, 0))
    batched = (time.perf_counter() - start) / 256
    theirs = run_pyelastica(ROBOT, [u])[0]
    results["response"] = dict(
        seconds=simulated,
        tip=difference(ours[:, -1], theirs["disks"][:, -1], ROBOT.length),
        middle=difference(ours[:, 0], theirs["disks"][:, 0], ROBOT.length),
        tip_excursion_mm=1e3 * np.linalg.norm(ours[:, -1] - ours[0, -1], axis=-1).max(),
    )
    results["speed"] = dict(
        threads=sim.threads,
        pyelastica_s_per_simulated_s=theirs["wall_seconds"] / simulated,
        ours_single_s_per_simulated_s=single / simulated,
        ours_batched_256_s_per_simulated_s=batched / simulated,
        speedup_single=theirs["wall_seconds"] / single,
        speedup_batched=theirs["wall_seconds"] / batched,
    )
    r, s = results["response"], results["speed"]
    print(
        f"2 s response (tip moves up to {r['tip_excursion_mm']:.0f} mm): tip max {r['tip']['max_mm']:.2f} mm "
        f"({r['tip']['max_percent_L']:.3f} % of L), RMS {r['tip']['rms_mm']:.2f} mm; middle disk max "
        f"{r['middle']['max_mm']:.2f} mm, RMS {r['middle']['rms_mm']:.2f} mm"
    )
    print(
        f"speed: PyElastica {s['pyelastica_s_per_simulated_s']:.2f} s per simulated s; ours "
        f"{s['ours_single_s_per_simulated_s']:.3f} (one episode), {s['ours_batched_256_s_per_simulated_s']:.4f} "
        f"(per episode, batch of 256): speed-up {s['speedup_single']:.0f}x / {s['speedup_batched']:.0f}x"
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, nargs="+", default=[256, 512], help="batch sizes of step 4")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--repeats", type=int, default=2, help="alternating runs of step 4, the faster kept")
    args = parser.parse_args()
    results = dict(cores=os.cpu_count())
    if not ELASTICA_PYTHON.exists():
        print(f"PyElastica comparison skipped: {ELASTICA_PYTHON} missing (see benchmarks/README.md)")
    else:
        statics(results)
        response_and_speed(results)
    for episodes in args.episodes:
        results[f"side_by_side_{episodes}"] = side = two_segment_side_by_side(episodes, args.seconds, args.repeats)
        print(
            f"{episodes} episodes x {args.seconds:g} s: two-segment rod {side['two_segment_wall_seconds']:.1f} s, "
            f"one-segment rod {side['one_segment_wall_seconds']:.1f} s ({side['ratio']:.2f}x); "
            f"{side['two_segment_s_per_episode_second']:.4f} / {side['one_segment_s_per_episode_second']:.4f} s "
            f"per episode per simulated s"
        )
    write_results("two_segment", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
