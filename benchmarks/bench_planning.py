"""Planning latency of the shipped paper models, side by side in one run (make bench):

- the real-time step at batch 1, for the MLP, every RF variant and the one-step flows: the call a
  Python loop makes, ``Controller.step(x_t, x_next)`` with a state's float64 numbers (the step's
  ONNX graph in onnxruntime on one thread, its inputs and outputs bound once, the checks and the
  conversions around it); the bound onnxruntime call alone, as a robot's program in C++ makes it;
  and the same module in eager torch (``Controller.step_module``, one thread, no autograd);
- a whole 500-step reference planned in one batched call (``Controller.plan``) of RF-FWD.

Uses the profile's trained models (default: paper, the shipped weights; another profile trains
them first if missing) on a held-out episode of the ci dataset (the same rod). Writes
figures/bench/planning.csv and prints a summary.
"""

from __future__ import annotations

import argparse
import sys

import torch
from results_file import trained_controller, write_results

from softflow import data
from softflow.control import metrics
from softflow.models.common import one_thread
from softflow.profiles import get_profile

STEPPED = ("mlp", "rf", "rf-physical", "rf-fwd", "rf-1", "rf-fwd-1", "rf-physical-1")


def ms(latency: dict) -> dict:
    return {k: 1e3 * v for k, v in latency.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--repeats", type=int, default=5000)
    args = parser.parse_args()
    held_out = data.load_dataset(get_profile("ci"), progress=False)  # the rod's own runs, made in seconds
    reference = held_out.states[held_out.test[0], :501]  # (501, 6): a 500-step plan
    x_t, x_next = reference[100], reference[101]  # one transition, (6,) float64 each
    results = dict(profile=args.profile, step={})
    for name in STEPPED:
        controller = trained_controller(name, args.profile)
        step = metrics.latency(controller.step, x_t, x_next, repeats=args.repeats)  # builds the graph first
        graph = metrics.latency(controller.bound_graph.run, repeats=args.repeats)
        module, pair = controller.step_module, [torch.as_tensor(x[None], dtype=torch.float32) for x in (x_t, x_next)]
        with torch.inference_mode(), one_thread():
            eager = metrics.latency(module, *pair, repeats=args.repeats)
        row = results["step"][name] = dict(step_ms=ms(step), graph_ms=ms(graph), eager_ms=ms(eager))
        print(
            f"{name:14s} Controller.step median {row['step_ms']['median']:.4f} ms (p99 {row['step_ms']['p99']:.4f}); "
            f"the graph alone {row['graph_ms']['median']:.4f} ms; eager torch {row['eager_ms']['median']:.4f} ms"
        )
    controller = trained_controller("rf-fwd", args.profile)
    whole = metrics.latency(controller.plan, reference, repeats=20, warmup=2)
    results["trajectory_500_steps_ms"] = 1e3 * whole["median"]
    print(f"a 500-step plan of rf-fwd in one batched call: {results['trajectory_500_steps_ms']:.2f} ms")
    write_results("planning", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
