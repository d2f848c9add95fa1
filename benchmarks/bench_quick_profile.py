"""What each profile's budget buys a model of a user's own runs (in make bench): the ASL
trunk's real runs as a user would train on them (``softflow train MODEL --recordings DIR``, every
disk observed), with the ``ci`` and ``quick`` budgets: the wall time to train each per-step
model, and its per-step input error on a run it never saw, random_2 (each step paired with the
input sent the recordings' delay before it: RMS over inputs and steps, degrees). The paper
budget is the trunk studies' (hours; ``figures/sweeps/trunk_v2-paper.csv``). Writes
figures/bench/quick_profile.csv.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from results_file import write_results

from softflow.control.planning import Controller
from softflow.data import recordings
from softflow.profiles import get_profile
from softflow.studies.trunk import DISKS, MAX_GAP, TRUNK
from softflow.training import ensure_trained

TRAINING = ("random_1", "circles", "payload_100g", "payload_300g")  # the user's folder of runs
HELD_OUT = "random_2"
MODELS = ("mlp", "rf", "rf-fwd")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profiles", default="ci,quick")
    args = parser.parse_args()
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        runs = Path(folder) / "runs"
        runs.mkdir()
        for name in TRAINING:
            shutil.copy(TRUNK / f"{name}.csv.gz", runs)
        data = recordings.load_dataset(runs, tip=list(DISKS), max_gap=MAX_GAP, fractions=(0.5, 0.25))
        test = recordings.read(
            TRUNK / f"{HELD_OUT}.csv.gz", tip=list(DISKS), max_gap=MAX_GAP, delay=data.delay_steps * data.dt
        )
        u, states = test.pairs(data.delay_steps)  # (T-d, 6), (T-d+1, 18)
        for profile in args.profiles.split(","):
            for name in MODELS:
                started = time.perf_counter()
                model, _ = ensure_trained(
                    name, get_profile(profile), data, None, None, root=Path(folder) / profile, progress=True
                )
                seconds = time.perf_counter() - started
                controller = Controller(model, name, robot=None, gravity=None, workspace_margin=None)
                planned = controller.step(states[:-1], states[1:], clip=False)  # (T-d, 6)
                error = float(np.sqrt(np.mean((planned - u) ** 2)))
                results[f"{profile}.{name}"] = dict(train_seconds=seconds, held_out_input_error_deg=error)
                print(f"{profile:6s} {name:7s}: trained in {seconds:.1f} s; on {HELD_OUT} {error:.2f} deg RMS per step")
    write_results("quick_profile", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
