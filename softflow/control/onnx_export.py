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
    z = 0, as ``step`` does. A model with a static prior (RF-Physical, MLP-Physical) carries the
    step's inverse-statics grid (``InverseGrid``) in the graph; where the step solves the prior
    by the table instead (off the grid, or at the table's clipped edge: 7.5e-5 of the paper
    dataset's states), the graph cannot, and ``outside`` is True. The metadata
    (``metadata_props``; numbers and lists as JSON) say what the graph was made from: ``_metadata``."""
    if not isinstance(controller, Controller):
        raise ValueError(f"expected a Controller (softflow.load_controller); got {type(controller).__name__}")
    if controller.lean is None:
        raise ValueError(
            f"{controller.name} reads a window of {controller.model.context} past transitions: it has no "
            "one-transition step to export; plan it in Python (Controller.plan)"
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
    prior = needs_table = None
    if controller.statics_grid is not None:
        prior, needs_table = _prior(g, controller.statics_grid, dims.position)
        normalised = _normalised(g, lean, prior, "prior_norm")
        features = g.op("Concat", features, normalised, out="features_and_prior", axis=1)
    xi = _flow(g, lean, features) if controller.generative else _mlp(g, lean, features)
    target = "residual_norm" if lean.prior else "action_norm"
    std, mean = (g.constant(f"{target}.{k}", lean.buffers[f"{target}.{k}"]) for k in ("std", "mean"))
    u = g.op("Add", g.op("Mul", xi, std, out="u_normalised.scaled"), mean, out="u_model")
    if prior is not None:
        u = g.op("Add", u, prior, out="u_with_prior")
    low, high = (
        g.constant(name, b.astype(np.float32)) for name, b in zip(("input_low", "input_high"), controller.input_range)
    )
    g.op("Min", g.op("Max", u, low, out="u_above_low"), high, out="u")  # np.clip(u, low, high)
    _outside(g, controller, needs_table)
    batch = lambda name, elem, *shape: helper.make_tensor_value_info(name, elem, ["batch", *shape])
    return helper.make_graph(
        g.nodes,
        f"softflow_{controller.name.replace('-', '_')}_step",
        [batch("x_t", TensorProto.FLOAT, dims.state), batch("x_next", TensorProto.FLOAT, dims.state)],
        [batch("u", TensorProto.FLOAT, dims.inputs), batch("outside", TensorProto.BOOL)],
        g.constants,
    )


def _features(g: _Graph, lean) -> str:
    """[x_t, x_next - x_t], each part normalised by the model's trained normalisers: (B, 2d)."""
    g.op("Sub", "x_next", "x_t", out="delta")
    parts = [_normalised(g, lean, x, norm) for x, norm in (("x_t", "state_norm"), ("delta", "delta_norm"))]
    return g.op("Concat", *parts, out="features", axis=1)


def _normalised(g: _Graph, lean, x: str, norm: str) -> str:
    """(x - mean) / std with the model's trained normaliser ``norm``."""
    centred = g.op("Sub", x, g.constant(f"{norm}.mean", lean.buffers[f"{norm}.mean"]), out=f"{x}.centred")
    return g.op("Div", centred, g.constant(f"{norm}.std", lean.buffers[f"{norm}.std"]), out=f"{x}.normalised")


def _prior(g: _Graph, grid, position: int) -> tuple[str, str]:
    """``InverseGrid.inverse`` of x_next's tip position, in float64 as the step computes it: the
    prior (B, m) float32, and (B,) bool where the step would solve it by the table instead."""
    p = g.op(
        "Cast",
        g.op("Slice", "x_next", *_ints(g, "tip", [0], [position], [1]), out="tip"),
        out="tip.f64",
        to=TensorProto.DOUBLE,
    )
    x = g.op("Slice", p, *_ints(g, "axial", [0], [1], [1]), out="tip.x")  # (B, 1)
    yz = g.op("Slice", p, *_ints(g, "lateral", [1], [3], [1]), out="tip.yz")  # (B, 2)
    axis1 = g.constant("axis1", np.array([1], np.int64))  # ReduceSum's axes: an input since opset 13
    squares = g.op("ReduceSum", g.op("Mul", yz, yz, out="yz.squared"), axis1, out="lateral.squared", keepdims=1)
    lateral = g.op("Sqrt", squares, out="lateral")
    behind = g.op(
        "Cast",
        g.op("Less", x, g.constant("zero.f64", np.float64(0)), out="behind"),
        out="behind.f64",
        to=TensorProto.DOUBLE,
    )
    half_bend = g.op(  # atan2(lateral, x) for lateral >= 0: atan(lateral / x), plus pi behind the base
        "Add",
        g.op(  # in float32: onnxruntime has no float64 Atan (its 6e-8 moves the prior by 1e-7 N)
            "Cast",
            g.op(
                "Atan",
                g.op("Cast", g.op("Div", lateral, x, out="lateral_over_x"), out="ratio.f32", to=TensorProto.FLOAT),
                out="atan.f32",
            ),
            out="atan",
            to=TensorProto.DOUBLE,
        ),
        g.op("Mul", behind, g.constant("pi", np.float64(np.pi)), out="behind.pi"),
        out="half_bend",
    )
    floor = g.op("Max", lateral, g.constant("tiny", np.float64(1e-300)), out="lateral.floored")
    scale = g.op(
        "Div",
        g.op("Mul", half_bend, g.constant("arc_scale", np.float64(grid.arc_scale)), out="bend.scaled"),
        floor,
        out="arc.scale",
    )
    length = g.op("Sqrt", g.op("Add", g.op("Mul", x, x, out="x.squared"), squares, out="chord.squared"), out="chord")
    coordinates = g.op("Concat", g.op("Mul", scale, yz, out="arc"), length, out="grid.coordinates", axis=1)
    s = g.op(
        "Div",
        g.op("Sub", coordinates, g.constant("grid.low", grid.low), out="grid.offset"),
        g.constant("grid.spacing", grid.spacing),
        out="grid.units",
    )
    top = g.constant("grid.top_cell", (grid.shape - 2).astype(np.float64))
    cell = g.op(
        "Min",
        g.op("Max", g.op("Floor", s, out="s.floor"), g.constant("zero3", np.zeros(3)), out="cell.above"),
        top,
        out="cell",
    )
    f = g.op("Sub", s, cell, out="cell.fraction")  # (B, 3)
    index = g.op("Cast", cell, out="cell.int", to=TensorProto.INT64)

    def flat(strides, name):
        return g.op(
            "ReduceSum",
            g.op("Mul", index, g.constant(f"{name}.strides", strides), out=f"{name}.scaled"),
            axis1,
            out=name,
            keepdims=1,
        )  # (B, 1)

    corners = g.op("Add", flat(grid.strides, "cell.node"), g.constant("cell.corners", grid.corners), out="corners")
    values = g.op("Gather", g.constant("grid.u", grid.u), corners, out="corner.u", axis=0)  # (B, 8, 2)
    for axis in range(3):  # 8 -> 4 -> 2 -> 1 corners, as InverseGrid.inverse
        half = 8 >> (axis + 1)
        low = g.op("Slice", values, *_ints(g, f"lerp{axis}.low", [0], [half], [1]), out=f"lerp{axis}.low")
        high = g.op("Slice", values, *_ints(g, f"lerp{axis}.high", [half], [2 * half], [1]), out=f"lerp{axis}.high")
        weight = g.op(
            "Unsqueeze",
            g.op("Slice", f, *_ints(g, f"lerp{axis}.f", [axis], [axis + 1], [1]), out=f"lerp{axis}.f"),
            g.constant(f"lerp{axis}.axes", np.array([2])),
            out=f"lerp{axis}.weight",
        )  # (B, 1, 1)
        step = g.op("Mul", weight, g.op("Sub", high, low, out=f"lerp{axis}.span"), out=f"lerp{axis}.step")
        values = g.op("Add", low, step, out=f"lerp{axis}")
    prior = g.op("Squeeze", values, g.constant("corner.axis", np.array([1])), out="prior.f64")
    on_grid = g.op(
        "And",
        g.op("GreaterOrEqual", s, g.constant("zero3.grid", np.zeros(3)), out="grid.above_low"),
        g.op("LessOrEqual", s, g.constant("grid.top", (grid.shape - 1).astype(np.float64)), out="grid.below_high"),
        out="grid.inside_axes",
    )
    inside = g.op(
        "ReduceMin",
        g.op("Cast", on_grid, out="grid.inside.int", to=TensorProto.INT32),
        out="grid.inside",
        axes=[1],
        keepdims=0,
    )
    kink = g.op(
        "Gather",
        g.constant("grid.kink", grid.kink),
        g.op("Squeeze", flat(grid.cell_strides, "cell.index"), g.constant("cell.axis", np.array([1])), out="cell.flat"),
        out="cell.kink",
        axis=0,
    )  # (B,)
    needs_table = g.op(
        "Or",
        g.op("Not", g.op("Cast", inside, out="grid.inside.bool", to=TensorProto.BOOL), out="off_grid"),
        kink,
        out="needs_table",
    )
    return g.op("Cast", prior, out="prior", to=TensorProto.FLOAT), needs_table


def _ints(g: _Graph, name: str, starts, ends, axes) -> list[str]:
    """Slice's starts, ends and axes as int64 constants."""
    return [
        g.constant(f"{name}.{k}", np.array(v, np.int64))
        for k, v in (("starts", starts), ("ends", ends), ("axes", axes))
    ]


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


def _outside(g: _Graph, controller: Controller, needs_table: str | None = None) -> str:
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
    if needs_table is None:
        return g.op("Cast", any_refused, out="outside", to=TensorProto.BOOL)
    refused = g.op("Cast", any_refused, out="refused.bool", to=TensorProto.BOOL)
    return g.op("Or", refused, needs_table, out="outside")


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
