"""Planning latency, side by side in one run (make bench):

- the real-time step, ``Controller.step(x_t, x_next)`` at batch 1, for the MLP, every RF
  variant and the one-step flows (RF-1, RF-FWD-1), beside the model's eager torch ``predict`` of
  the same transition and the step exported as one ONNX graph (``control.export_onnx``) run
  by onnxruntime on one thread (each called as a robot's loop calls it: the step with a state's
  float64 numbers, the session with (1, d) float32 arrays; RF-Physical's graph carries its grid);
- for each flow, a 16-draw spread at one transition (``Controller.sample_step``, the draws as
  one batch) beside its step;
- RF-Physical's prior at batch 1: the inverse-statics grid its step reads (``InverseGrid``)
  beside the table's Gauss-Newton inverse that ``plan`` reads;
- per control step of RF-FWD for N = 1..20 Euler steps: eager torch vs the compiled lean
  sampler (LeanFlow, ``models.kernels``), median and p99 over 2000 calls each;
- a whole 500-step trajectory planned in one batched call (Controller.plan).

Uses the profile's trained models (default: ci; trains them first if missing).
Writes figures/bench/planning.csv and prints a summary.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch
from results_file import write_results

from softflow import control, data, training
from softflow.control import metrics
from softflow.models.common import one_thread
from softflow.models.flow import LeanFlow
from softflow.profiles import get_profile


def onnx_step(controller, window):
    """A call of the controller's exported step on the transition ``window`` (1, 2, d), in an
    onnxruntime session on one thread."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    with tempfile.TemporaryDirectory() as folder:  # the session holds the graph once made
        path = control.export_onnx(controller, Path(folder) / f"{controller.name}.onnx")
        session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    feeds = {"x_t": window[:, 0].astype(np.float32), "x_next": window[:, 1].astype(np.float32)}  # (1, d) each
    return lambda: session.run(None, feeds)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="ci")
    parser.add_argument("--model", default="rf-fwd")
    parser.add_argument("--repeats", type=int, default=2000)
    args = parser.parse_args()
    profile = get_profile(args.profile)
    dataset = data.load_dataset(profile, progress=False)
    window = dataset.states[dataset.test[0], 100:102][None]  # one transition (1, 2, 6)
    z = np.zeros((1, 2))
    window_t, z_t = torch.as_tensor(window, dtype=torch.float32), torch.as_tensor(z, dtype=torch.float32)
    results = dict(model=args.model, profile=profile.name, step={}, per_step={})
    for name in ("mlp", "rf", "rf-physical", "rf-fwd", "rf-1", "rf-fwd-1", "rf-physical-1"):
        controller = control.Controller(training.ensure_trained(name, profile, dataset)[0], name)
        extras = {
            k: torch.as_tensor(v[0], dtype=torch.float32)
            for k, v in controller.model.extras(window, controller.statics).items()
        }
        noise = {"noise": z_t} if controller.generative else {}
        with torch.inference_mode(), one_thread():
            predict = lambda c=controller, e=extras, n=noise: c.model.predict(window_t, **e, **n)  # noqa: E731
            eager = metrics.latency(predict, repeats=args.repeats)
        step = metrics.latency(controller.step, window[0, 0], window[0, 1], repeats=args.repeats)
        results["step"][name] = dict(
            eager_ms={k: 1e3 * v for k, v in eager.items()}, step_ms={k: 1e3 * v for k, v in step.items()}
        )
        graph = onnx_step(controller, window)
        results["step"][name]["onnx_ms"] = {k: 1e3 * v for k, v in metrics.latency(graph, repeats=args.repeats).items()}
        if controller.generative:
            spread = metrics.latency(controller.sample_step, window[0, 0], window[0, 1], 16, repeats=args.repeats)
            results["step"][name]["spread16_ms"] = {k: 1e3 * v for k, v in spread.items()}
            results["step"][name]["spread16_over_step"] = spread["median"] / step["median"]
        if controller.statics is not None:
            p = window[:, 1, :3]  # (1, 3)
            for prior, inverse in (("grid", controller.statics_grid.inverse), ("table", controller.statics.inverse)):
                took = metrics.latency(inverse, p, repeats=args.repeats)
                results["prior"] = results.get("prior", {}) | {f"{prior}_ms": {k: 1e3 * v for k, v in took.items()}}
        row = results["step"][name]
        onnx_ms = row.get("onnx_ms")
        print(
            f"{name:12s} step: median {1e3 * step['median']:.3f} ms (p99 {1e3 * step['p99']:.3f}); "
            f"eager torch median {1e3 * eager['median']:.3f} ms (p99 {1e3 * eager['p99']:.3f}); "
            + f"onnxruntime median {onnx_ms['median']:.3f} ms (p99 {onnx_ms['p99']:.3f})"
            + (f"; 16 draws {spread:.2f}x the step" if (spread := row.get("spread16_over_step")) else "")
        )
    grid, table = results["prior"]["grid_ms"], results["prior"]["table_ms"]
    print(f"RF-Physical prior: grid median {grid['median']:.4f} ms, table (Gauss-Newton) {table['median']:.3f} ms")
    model, _ = training.ensure_trained(args.model, profile, dataset)  # the shipped model, or trained with its budget
    lean = LeanFlow(model)
    with torch.inference_mode(), one_thread():
        for steps in (1, 2, 4, 10, 20):
            eager = metrics.latency(model.predict, window_t, None, z_t, steps, repeats=args.repeats)
            fast = metrics.latency(lean.predict, window, z, None, steps, repeats=args.repeats)
            results["per_step"][steps] = dict(
                eager_ms={k: 1e3 * v for k, v in eager.items()}, lean_ms={k: 1e3 * v for k, v in fast.items()}
            )
            print(
                f"N={steps:2d}: eager torch median {1e3 * eager['median']:.3f} ms (p99 {1e3 * eager['p99']:.3f}), "
                f"compiled median {1e3 * fast['median']:.3f} ms (p99 {1e3 * fast['p99']:.3f}), "
                f"{eager['median'] / fast['median']:.1f}x"
            )
    controller = control.Controller(model, args.model)
    reference = dataset.states[dataset.test[0]]  # 501 states: a 500-step plan
    controller.plan(reference)
    times = []
    for _ in range(20):
        start = time.perf_counter()
        controller.plan(reference)
        times.append(time.perf_counter() - start)
    results["trajectory_500_steps_ms"] = 1e3 * float(np.median(times))
    print(
        f"whole 500-step trajectory in one batched call (N={model.steps}): {results['trajectory_500_steps_ms']:.1f} ms"
    )
    write_results("planning", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
