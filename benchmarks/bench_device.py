"""Training speed on a GPU beside one CPU thread, side by side in one run on one machine:

each model trains one epoch of a profile's budget (its steps, batch and validation) on each
device, one after another into a scratch folder, on the ci dataset (the step's cost depends
on the batch, not on how many episodes the batches are drawn from). A warm-up epoch on each
accelerator comes first and is not timed (CUDA's start-up and kernel choice). The CPU trains
on one thread, as every training run of this repository does. Writes figures/bench/device.csv:
seconds per epoch on each device and the CPU's over the accelerator's.

    python benchmarks/bench_device.py --budget paper --devices cpu cuda

Nothing in the repository needs an accelerator: this only says what one buys.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import torch
from results_file import write_results

from softflow import data, training
from softflow.models.specs import model_spec
from softflow.profiles import get_profile

MODELS = ("mlp", "lstm", "transformer", "rf", "forward", "rf-fwd")  # RF-FWD needs its surrogate


def seconds_per_epoch(name: str, dataset, budget, device: str, scratch: Path, trained: dict) -> float:
    """One epoch of ``budget`` for ``name`` on ``device``, trained from scratch; its wall seconds."""
    one = dataclasses.replace(budget, epochs=1, patience=1)
    dependencies = {dep: trained[(dep, device)] for dep in model_spec(name).requires}
    model, checkpoint = training.train(
        name, dataset, one, scratch / f"{name}-{device}.pt", dependencies=dependencies, device=device, progress=False
    )
    trained[(name, device)] = model
    return checkpoint["wall_seconds"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--budget", default="paper", help="profile whose training budget is timed")
    parser.add_argument("--devices", nargs="+", default=["cpu", "cuda"], help="the first is the reference")
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    args = parser.parse_args()
    for name in args.models:
        missing = [dep for dep in model_spec(name).requires if dep not in args.models[: args.models.index(name)]]
        if missing:
            raise ValueError(f"{name} needs {missing} timed before it in --models")
    for device in args.devices:
        torch.empty(1, device=device)  # an absent accelerator fails here, before any timing
    profile = get_profile(args.budget)
    dataset = data.load_dataset(get_profile("ci"), progress=False)
    reference = args.devices[0]
    results = dict(
        budget=profile.name,
        torch=torch.__version__,
        accelerator=torch.cuda.get_device_name() if torch.cuda.is_available() else "none",
        models={},
    )
    with tempfile.TemporaryDirectory() as scratch:
        scratch, trained = Path(scratch), {}
        for device in args.devices[1:]:  # warm-up, not timed
            warm = dataclasses.replace(profile.train_config("mlp"), epochs=1, steps_per_epoch=50, val_samples=1000)
            training.train("mlp", dataset, warm, scratch / f"warm-{device}.pt", device=device, progress=False)
        for name in args.models:
            budget = profile.train_config(name)
            timed = {
                device: seconds_per_epoch(name, dataset, budget, device, scratch, trained) for device in args.devices
            }
            row = dict(steps_per_epoch=budget.steps_per_epoch, batch_size=budget.batch_size)
            row.update({f"{device}_seconds_per_epoch": seconds for device, seconds in timed.items()})
            row.update({f"{reference}_over_{d}": timed[reference] / timed[d] for d in args.devices[1:]})
            results["models"][name] = row
            print(f"{name:12s} " + "  ".join(f"{d} {s:7.2f} s/epoch" for d, s in timed.items()), flush=True)
    write_results("device", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
