"""`python -m softflow ...`: the notebooks' long steps without Jupyter.

  python -m softflow data  --profile paper              generate (or verify) the dataset
  python -m softflow train --profile paper mlp rf-fwd   train models into their checkpoints
"""
from __future__ import annotations

import argparse
import time

from . import control, data, train
from .profiles import PROFILES, get_profile


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m softflow", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=["data", "train"])
    parser.add_argument("models", nargs="*", metavar="model", help=f"models to train: {', '.join(sorted(train.MODELS))}")
    parser.add_argument("--profile", default="paper", choices=sorted(PROFILES))
    args = parser.parse_intermixed_args(argv)
    unknown = sorted(set(args.models) - set(train.MODELS))
    if unknown:
        parser.error(f"unknown model(s) {unknown}; choose from {sorted(train.MODELS)}")
    profile = get_profile(args.profile)
    start = time.perf_counter()
    dataset = data.load_dataset(profile)
    print(f"dataset {dataset.key}: {dataset.u.shape[0]} episodes ({time.perf_counter() - start:.0f} s)")
    if args.command == "train":
        for name in args.models:
            _, checkpoint = train.train(name, dataset, profile.train, control.checkpoint_path(name, profile.name))
            print(f"{name}: {checkpoint['epochs_run']} epochs, best validation loss {checkpoint['best_val']:.4f}, "
                  f"{checkpoint['wall_seconds'] / 60:.1f} min of training")


if __name__ == "__main__":
    main()
