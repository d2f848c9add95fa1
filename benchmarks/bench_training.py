"""Training cost of every model, side by side in one run (make bench):

each model trains a few epochs of its profile budget (the same steps per epoch, batch,
validation and single thread as the real run) into a scratch folder, one after another
so no two share the cores; seconds per epoch times the budget's epochs gives the wall time
of a full run (an upper bound: early stopping can end it sooner). RF-FWD's forward
surrogate is timed as its own row. Writes figures/bench/training.csv.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

from results_file import write_results

from softflow import data, training
from softflow.models.specs import model_spec
from softflow.profiles import get_profile

MODELS = ("mlp", "lstm", "transformer", "rf", "rf-physical", "forward", "rf-fwd")  # RF-FWD needs its surrogate


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="ci")
    parser.add_argument("--epochs", type=int, default=3, help="epochs timed per model")
    args = parser.parse_args()
    profile = get_profile(args.profile)
    dataset = data.load_dataset(profile, progress=False)
    results = dict(profile=profile.name, epochs_timed=args.epochs, models={})
    trained = {}
    with tempfile.TemporaryDirectory() as scratch:
        for name in MODELS:
            budget = profile.train_config(name)
            timed = dataclasses.replace(budget, epochs=args.epochs, patience=args.epochs)
            dependencies = {dep: trained[dep] for dep in model_spec(name).requires}
            trained[name], checkpoint = training.train(
                name, dataset, timed, Path(scratch) / f"{name}.pt", dependencies=dependencies, progress=False
            )
            per_epoch = checkpoint["wall_seconds"] / checkpoint["epochs_run"]
            results["models"][name] = dict(
                seconds_per_epoch=per_epoch,
                budget_epochs=budget.epochs,
                full_budget_minutes=per_epoch * budget.epochs / 60,
            )
            print(
                f"{name:12s} {per_epoch:6.2f} s/epoch x {budget.epochs:3d} epochs = "
                f"{per_epoch * budget.epochs / 60:5.1f} min for the full budget"
            )
    write_results("training", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
