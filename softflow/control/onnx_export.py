"""A controller's real-time step as one ONNX graph, for a robot's controller outside Python
(onnxruntime's C, C++, C# or Python API): normalisation, the network (every Euler step of a flow
unrolled), denormalisation and clipping, and the workspace check, built node by node from the
lean sampler's float32 weights. No tracer: the graph holds the step's arithmetic and nothing
else: named nodes that read like ``LeanFlow.predict`` (89 for the shipped 4-step RF-FWD; Netron
draws them)."""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from softflow.control.planning import Controller
from softflow.store import atomic_write

# onnxruntime 1.13 (2022) and later run opset 17: a robot's computer often carries an older
# runtime than this one, and the step needs no newer operator.
OPSET = 17


class _Graph:
    """The nodes and constants of a graph being built; each op returns the name of its output."""

    def __init__(self):
        self.nodes, self.constants = [], []

    def constant(self, name: str, value) -> str:
        self.constants.append(numpy_helper.from_array(np.asarray(value), name))
        return name

    def op(self, op_type: str, *inputs: str, out: str, **attributes) -> str:
        self.nodes.append(helper.make_node(op_type, list(inputs), [out], name=out, **attributes))
        return out

    def linear(self, x: str, layer: tuple[str, str], out: str) -> str:
        """x @ W^T + b, as the lean samplers compute it."""
        weight, bias = layer
        return self.op("Add", self.op("MatMul", x, weight, out=f"{out}.matmul"), bias, out=out)

    def silu(self, h: str) -> str:
        """h sigmoid(h)."""
        return self.op("Mul", h, self.op("Sigmoid", h, out=f"{h}.sigmoid"), out=f"{h}.silu")


def export_onnx(controller: Controller, path) -> Path:
    """Write ``controller.step`` as one ONNX graph at ``path`` (replaced); returns the path.

    Inputs ``x_t`` and ``x_next``: (B, d) float32 states in the model's units. Outputs ``u``
    (B, m) float32, clipped to the controller's input range per input, and ``outside`` (B,)
    bool: True where ``step`` refuses the pair (a tip position beyond the workspace margin, or a
    value that is not finite); a controller must not send that row's u. A flow starts from
    z = 0, as ``step`` does. The metadata (``metadata_props``; numbers and lists as JSON) say what
    the graph was made from: ``_metadata``. RF-Physical has no graph yet (ValueError): its prior
    inverts a table of the rod's statics iteratively."""
    if not isinstance(controller, Controller):
        raise ValueError(f"expected a Controller (softflow.load_controller); got {type(controller).__name__}")
    if controller.lean is None:
        raise ValueError(
            f"{controller.name} reads a window of {controller.model.context} past transitions: it has no "
            "one-transition step to export; plan it in Python (Controller.plan)"
        )
    if controller.model.needs_statics:
        raise ValueError(
            f"{controller.name} adds its output to a static prior found by iteratively inverting a table of "
            "the rod's statics: the graph has no form of that inverse yet; Controller.step remains the path for it"
        )
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a directory; expected a file to write (e.g. {controller.name}.onnx)")
    opset = [helper.make_opsetid("", OPSET)]
    model = helper.make_model(
        _step_graph(controller),
        opset_imports=opset,
        ir_version=helper.find_min_ir_version_for(opset),
        producer_name="softflow",
        producer_version=_version(),
        doc_string=f"softflow {controller.name}: Controller.step as one graph",
    )
    helper.set_model_props(model, _metadata(controller))
    onnx.checker.check_model(model, full_check=True)
    with atomic_write(path) as f:
        f.write(model.SerializeToString())
    return path


def _step_graph(controller: Controller) -> onnx.GraphProto:
    lean, dims = controller.lean, controller.model.dims
    g = _Graph()
    features = _features(g, lean)
    xi = _flow(g, lean, features) if controller.generative else _mlp(g, lean, features)
    std, mean = (g.constant(f"action_norm.{k}", lean.buffers[f"action_norm.{k}"]) for k in ("std", "mean"))
    u = g.op("Add", g.op("Mul", xi, std, out="u_normalised.scaled"), mean, out="u_unclipped")
    low, high = (
        g.constant(name, b.astype(np.float32)) for name, b in zip(("input_low", "input_high"), controller.input_range)
    )
    g.op("Min", g.op("Max", u, low, out="u_above_low"), high, out="u")  # np.clip(u, low, high)
    _outside(g, controller)
    batch = lambda name, elem, *shape: helper.make_tensor_value_info(name, elem, ["batch", *shape])
    return helper.make_graph(
        g.nodes,
        f"softflow_{controller.name.replace('-', '_')}_step",
        [batch("x_t", TensorProto.FLOAT, dims.state), batch("x_next", TensorProto.FLOAT, dims.state)],
        [batch("u", TensorProto.FLOAT, dims.inputs), batch("outside", TensorProto.BOOL)],
        g.constants,
    )


def _features(g: _Graph, lean) -> str:
    """[x_t, x_next - x_t], each part normalised as ``LeanModel.features``: (B, 2d)."""
    g.op("Sub", "x_next", "x_t", out="delta")
    parts = [
        g.op(
            "Div",
            g.op("Sub", x, g.constant(f"{norm}.mean", lean.buffers[f"{norm}.mean"]), out=f"{x}.centred"),
            g.constant(f"{norm}.std", lean.buffers[f"{norm}.std"]),
            out=f"{x}.normalised",
        )
        for x, norm in (("x_t", "state_norm"), ("delta", "delta_norm"))
    ]
    return g.op("Concat", *parts, out="features", axis=1)


def _layers(g: _Graph, lean, start: int) -> list[tuple[str, str]]:
    """The (W^T, b) constants of the lean model's layers from ``start`` on."""
    return [
        (g.constant(f"layer{i}.weight", w), g.constant(f"layer{i}.bias", b))
        for i, (w, b) in enumerate(lean.weights[start:], start)
    ]


def _mlp(g: _Graph, lean, features: str) -> str:
    """``LeanMLP.predict`` before denormalisation: (B, m)."""
    h = features
    for i, layer in enumerate(_layers(g, lean, 0)):
        h = g.linear(g.silu(h) if i else h, layer, f"layer{i}")
    return h


def _flow(g: _Graph, lean, features: str) -> str:
    """``LeanFlow.predict`` from z = 0 before denormalisation, its Euler steps unrolled: (B, m).
    The condition's share of the first layer is computed once; at the first step xi = 0 and
    tau = 0, so the first layer is that share (and a one-step flow's span) alone."""
    n, (_, first_b) = lean.steps, lean.weights[0]
    w_condition = g.constant("layer0.weight_condition", lean.w_condition)
    condition_part = g.op("MatMul", features, w_condition, out="condition.matmul")
    first_bias = g.op("Add", condition_part, g.constant("layer0.bias", first_b), out="first_bias")
    w_xi, steps = g.constant("layer0.weight_xi", lean.w_xi), g.constant("euler_steps", np.float32(n))
    layers, xi = _layers(g, lean, 1), None
    for k in range(n):
        h = first_bias
        time_weight = (k / n) * lean.w_tau + lean.w_span / n  # tau = k/n, a one-step flow's span 1/n
        if xi is not None:
            time_part = g.constant(f"step{k}.time_weight", time_weight)
            h = g.op("Add", g.op("MatMul", xi, w_xi, out=f"step{k}.xi.matmul"), time_part, out=f"step{k}.xi_tau")
            h = g.op("Add", h, first_bias, out=f"step{k}.layer0")
        elif time_weight.any():
            h = g.op("Add", first_bias, g.constant(f"step{k}.time_weight", time_weight), out=f"step{k}.layer0")
        for i, layer in enumerate(layers, 1):
            h = g.linear(g.silu(h), layer, f"step{k}.layer{i}")
        increment = g.op("Div", h, steps, out=f"step{k}.increment")  # velocity / n
        xi = increment if xi is None else g.op("Add", xi, increment, out=f"xi{k + 1}")
    return xi


def _outside(g: _Graph, controller: Controller) -> str:
    """(B,) bool: a value of x_t or x_next is not finite or, with a margin, a tip position lies
    beyond it. Compared in float64, as ``step`` compares, so a state at the margin is judged alike."""
    states = g.op("Concat", "x_t", "x_next", out="states", axis=1)  # (B, 2d)
    states = g.op("Cast", states, out="states.f64", to=TensorProto.DOUBLE)
    magnitude = g.op("Abs", states, out="states.abs")
    ok = g.op("Less", magnitude, g.constant("infinity", np.float64(np.inf)), out="finite")  # NaN compares False
    mean, halfwidth = controller.workspace
    if halfwidth is not None:
        p, d = len(mean), controller.model.dims.state
        tips = g.op("Gather", states, g.constant("tip_index", np.r_[0:p, d : d + p]), out="tips", axis=1)  # (B, 2p)
        offset = g.op("Sub", tips, g.constant("workspace.mean", np.tile(mean, 2)), out="tips.offset")
        distance = g.op("Abs", offset, out="tips.distance")
        within = g.op("LessOrEqual", distance, g.constant("workspace.halfwidth", np.tile(halfwidth, 2)), out="within")
        ok = g.op("Concat", ok, within, out="ok", axis=1)
    refused = g.op("Cast", g.op("Not", ok, out="refused"), out="refused.int", to=TensorProto.INT32)
    any_refused = g.op("ReduceMax", refused, out="refused.any", axes=[1], keepdims=0)
    return g.op("Cast", any_refused, out="outside", to=TensorProto.BOOL)


def _metadata(controller: Controller) -> dict[str, str]:
    """What a robot's program needs to use the graph: the model and its rod, the sizes, the Euler
    steps (0: a regression model), the workspace (tip mean and half-widths, m; null with no margin),
    the input range, the sample period (s; null when unknown), the delay in periods by which a
    model of recorded runs' inputs must be sent early and the columns it observes, the version."""
    dims, (mean, halfwidth), (low, high) = controller.model.dims, controller.workspace, controller.input_range
    values = dict(
        model=controller.name,
        robot=None if controller.robot is None else controller.robot.name,
        gravity=controller.gravity,
        state_size=dims.state,
        input_size=dims.inputs,
        euler_steps=controller.lean.steps if controller.generative else 0,
        workspace_mean=mean.tolist(),
        workspace_halfwidth=None if halfwidth is None else halfwidth.tolist(),
        workspace_margin=controller.workspace_margin,
        input_low=low.tolist(),
        input_high=high.tolist(),
        sample_period_s=controller.dt,
        delay_steps=controller.delay_steps,
        tip_columns=list(controller.tip_columns),
        softflow_version=_version(),
    )
    return {key: value if isinstance(value, str) else json.dumps(value) for key, value in values.items()}


def _version() -> str:
    try:
        return version("softflow")
    except PackageNotFoundError:  # run from a clone that was never installed
        return "unknown"
