"""How a sweep scales with workers (make bench): the same study grid, from an empty cache
each time, on a LocalCluster of 1 and then 2 (or --workers) single-threaded processes,
side by side in one run. The default grid, ``data_size`` in the ci profile, is four cells
that each train a model from scratch, so the cells are the work and nothing is cached
between runs. Writes figures/bench/sweep.csv.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from results_file import write_results

from softflow.studies import sweep


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--study", default="data_size")
    parser.add_argument("--profile", default="ci")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    results = {}
    for workers in args.workers:
        with tempfile.TemporaryDirectory() as root, sweep.connect(workers=workers) as client:
            start = time.perf_counter()
            run = sweep.run_sweep(args.study, args.profile, client=client, device="cpu", root=root, progress=False)
            seconds = time.perf_counter() - start
        if run.failures:
            raise SystemExit(f"cells failed: {run.failures}")
        results[workers] = dict(seconds=seconds, cells=int(run.rows.key.nunique()))
        print(
            f"{args.study} ({args.profile}), {workers} worker(s): {results[workers]['cells']} cells in {seconds:.1f} s"
        )
    base = results[args.workers[0]]["seconds"]
    for workers, result in results.items():
        result["speed_up"] = base / result["seconds"]
        print(f"{workers} worker(s): speed-up {result['speed_up']:.2f}x against {args.workers[0]}")
    print(write_results("sweep", dict(study=args.study, profile=args.profile, workers=results)))


if __name__ == "__main__":
    main()
