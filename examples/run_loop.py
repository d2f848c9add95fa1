"""Run a softflow loop graph on a robot's computer, with numpy and onnxruntime alone.

Make the graph from a model trained on your recordings:

    python -m softflow export mlp --recordings runs/ --loop --onnx loop.onnx

then give ``run`` your plant: an object with ``read()``, the newest frame of the observed columns
(the graph's ``tip_columns``, in m; NaN where the tracker gave none), and ``send(u)``, which
applies the inputs (the graph's ``input_columns``, in the recordings' units). Each period is one
onnxruntime call: estimate, delay compensation, the model's step and the safety rules are in the
graph, its memory comes back as outputs and goes in again (docs/real_robot.md).
"""

from __future__ import annotations

import json
import time

import numpy as np
import onnxruntime as ort


class LoopGraph:
    """A loop graph with its memory: ``graph(frame, reference)`` -> (u, holding)."""

    def __init__(self, path):
        options = ort.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1  # one core, no thread wake-ups
        self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        self.meta = {key: _value(text) for key, text in self.session.get_modelmeta().custom_metadata_map.items()}
        self.names = self.meta["memory"]
        self.memory = {
            name: np.array(start["values"], start["dtype"]).reshape(start["shape"])
            for name, start in self.meta["start_memory"].items()
        }
        self.delay, self.period = self.meta["delay_steps"], self.meta["sample_period_s"]

    def __call__(self, frame, reference):
        """u (m,) to send now for the newest ``frame`` (k,) and ``reference`` (3, d), the states
        wanted now, delay and delay + 1 periods ahead; and whether u is the safe input."""
        feed = dict(
            frame=np.asarray(frame, np.float64).reshape(1, -1),
            reference=np.asarray(reference, np.float32).reshape(1, 3, -1),
            **self.memory,
        )
        u, holding, *memory = self.session.run(None, feed)
        self.memory = dict(zip(self.names, memory))
        return u[0], bool(holding[0])


def _value(text: str):
    try:
        return json.loads(text)
    except ValueError:  # a plain string (the model's name)
        return text


def run(graph: LoopGraph, plant, reference, *, paced: bool = True):
    """Track ``reference`` (T+1, d): the states wanted at each period, in the model's order
    (positions of the observed columns, then their velocities). Each period reads a frame,
    sends u for the reference now, delay and delay + 1 periods ahead (its last state once it
    ends), and (``paced``) waits for the next period's deadline. Returns u (T, m), holding (T,)
    and the periods whose call overran."""
    reference = np.asarray(reference, np.float64)
    T = len(reference) - 1
    sent, holding, late = [], [], 0
    deadline = time.perf_counter()
    for t in range(T):
        rows = np.minimum([t, t + graph.delay, t + graph.delay + 1], T)
        u, hold = graph(plant.read(), reference[rows])
        plant.send(u)
        sent.append(u)
        holding.append(hold)
        deadline += graph.period
        if paced:
            left = deadline - time.perf_counter()
            if left < 0:
                late += 1
                deadline = time.perf_counter()  # start again from now: no burst of catch-up calls
            else:
                time.sleep(left)
    return np.array(sent), np.array(holding), late


if __name__ == "__main__":
    import sys

    loop = LoopGraph(sys.argv[1])
    print(json.dumps({key: loop.meta[key] for key in ("model", "sample_period_s", "delay_steps", "input_columns")}))
