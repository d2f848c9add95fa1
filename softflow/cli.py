"""`python -m softflow ...`: the notebooks' long steps without Jupyter.

  python -m softflow data  --profile paper              generate (or verify) the dataset
  python -m softflow train --profile paper mlp rf-fwd   train models into their checkpoints
  python -m softflow train --robot hw --gravity horizontal rf-fwd   a hardware-twin model
  python -m softflow train --profile paper --ship rf-fwd   retrain a shipped model into checkpoints/
  python -m softflow sweep table1 --profile paper [--scheduler-file F]   a study's cells as Dask tasks (docs/sweeps.md)

Trained models go to data/checkpoints/ (git-ignored); only --ship writes checkpoints/.
"""

from __future__ import annotations

import argparse
import sys
import time

from softflow import data, training
from softflow.models.registry import MODELS
from softflow.profiles import PROFILES, get_profile
from softflow.rod.robots import ROBOTS


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["sweep"]:
        return _sweep(argv[1:])
    parser = argparse.ArgumentParser(
        prog="python -m softflow", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("command", choices=["data", "train"])
    parser.add_argument("models", nargs="*", metavar="model", help=f"models to train: {', '.join(sorted(MODELS))}")
    parser.add_argument("--profile", default="paper", choices=sorted(PROFILES))
    parser.add_argument("--robot", default="sim", choices=sorted(ROBOTS))
    parser.add_argument("--gravity", default="vertical", choices=["vertical", "horizontal"])
    parser.add_argument(
        "--ship",
        action="store_true",
        help="write the paper-profile checkpoints committed in checkpoints/ (maintainers only)",
    )
    args = parser.parse_intermixed_args(argv)
    unknown = sorted(set(args.models) - set(MODELS))
    if unknown:
        parser.error(f"unknown model(s) {unknown}; choose from {sorted(MODELS)}")
    profile = get_profile(args.profile)
    start = time.perf_counter()
    robot = ROBOTS[args.robot]
    dataset = data.load_dataset(profile, robot, args.gravity)
    print(f"dataset {dataset.key}: {dataset.u.shape[0]} episodes ({time.perf_counter() - start:.0f} s)")
    if args.command == "train":
        for name in args.models:
            _, checkpoint = training.ensure_trained(
                name, profile, dataset, robot, args.gravity, ship=args.ship, progress=True
            )
            print(
                f"{name}: {checkpoint['epochs_run']} epochs, best validation loss {checkpoint['best_val']:.4f}, "
                f"{checkpoint['wall_seconds'] / 60:.1f} min of training"
            )


def _sweep(argv):
    """The sweep subcommand; the CSV path is the last line of stdout, exit status 1 if a cell failed."""
    from softflow.studies import sweep

    parser = argparse.ArgumentParser(
        prog="python -m softflow sweep", description=sweep.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("study", choices=sorted(sweep.STUDIES))
    parser.add_argument("--profile", required=True, choices=sorted(PROFILES))
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--scheduler-file", help="run on the cluster whose scheduler wrote this file")
    cluster.add_argument("--scheduler", metavar="ADDRESS", help="run on the cluster at this address (tcp://host:8786)")
    parser.add_argument("--workers", type=int, help="worker processes of the local cluster (default: one per core)")
    parser.add_argument("--device", default="auto", choices=sweep.DEVICES, help="auto: CUDA, else MPS, else CPU")
    parser.add_argument(
        "--recompute",
        action="store_true",
        help="recompute the cells whose rows ship in figures/sweeps/ (cached rows in data/sweeps/ still count)",
    )
    args = parser.parse_args(argv)
    start = time.perf_counter()
    try:
        with sweep.connect(args.scheduler_file, args.scheduler, args.workers) as client:
            result = sweep.run_sweep(
                args.study, args.profile, client=client, device=args.device, shipped=not args.recompute
            )
    except ValueError as error:
        parser.error(str(error))
    for failure in result.failures:
        print(f"cell {failure.cell} failed: {failure.error}", file=sys.stderr)
    computed = result.computed - len(result.failures)
    print(
        f"{args.study}: {len(result.rows)} rows ({result.cached} cached, {computed} computed, "
        f"{len(result.failures)} failed) in {time.perf_counter() - start:.0f} s"
    )
    print(result.csv)
    if result.failures:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
