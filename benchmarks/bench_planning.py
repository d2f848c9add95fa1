"""Planning latency of the RF family, side by side in one run (make bench):

- per control step at batch 1 (one transition, N Euler steps): plain eager torch vs the
  lean numpy sampler (LeanFlow), median and p99 over 2000 calls each;
- a whole 500-step trajectory planned in one batched call (Controller.plan).

Uses the profile's trained rf-fwd (default: ci; trains it first if missing).
Writes benchmarks/results/planning.json and prints a summary.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import torch

from results_file import write_results
from softflow import control, data, metrics, train
from softflow.models.common import one_thread
from softflow.models.flow import LeanFlow
from softflow.profiles import get_profile


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="ci")
    parser.add_argument("--model", default="rf-fwd")
    parser.add_argument("--repeats", type=int, default=2000)
    args = parser.parse_args()
    profile = get_profile(args.profile)
    dataset = data.load_dataset(profile, progress=False)
    model, _ = train.ensure_trained(args.model, profile, dataset)  # the shipped model, or trained with its budget
    lean = LeanFlow(model)
    window = dataset.states[dataset.test[0], 100:102][None]  # one transition (1, 2, 6)
    z = np.zeros((1, 2))
    window_t, z_t = torch.as_tensor(window, dtype=torch.float32), torch.as_tensor(z, dtype=torch.float32)
    results = dict(model=args.model, profile=profile.name, per_step={})
    with torch.inference_mode(), one_thread():
        for steps in (1, 2, 4, 10, 20):
            eager = metrics.latency(model.predict, window_t, None, z_t, steps, repeats=args.repeats)
            fast = metrics.latency(lean.predict, window, z, None, steps, repeats=args.repeats)
            results["per_step"][steps] = dict(eager_ms={k: 1e3 * v for k, v in eager.items()},
                                              lean_ms={k: 1e3 * v for k, v in fast.items()})
            print(f"N={steps:2d}: eager torch median {1e3 * eager['median']:.3f} ms (p99 {1e3 * eager['p99']:.3f}), "
                  f"lean numpy median {1e3 * fast['median']:.3f} ms (p99 {1e3 * fast['p99']:.3f}), "
                  f"{eager['median'] / fast['median']:.1f}x")
    controller = control.Controller(model, args.model)
    reference = dataset.states[dataset.test[0]]  # 501 states: a 500-step plan
    controller.plan(reference)
    times = []
    for _ in range(20):
        start = time.perf_counter()
        controller.plan(reference)
        times.append(time.perf_counter() - start)
    results["trajectory_500_steps_ms"] = 1e3 * float(np.median(times))
    print(f"whole 500-step trajectory in one batched call (N={model.steps}): {results['trajectory_500_steps_ms']:.1f} ms")
    write_results("planning", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
