"""The controller's step, defined once: one torch module maps a transition (x_t, x_{t+1}) to the
input to send. ``Controller.plan`` applies the model inside it to a whole reference at once,
``Controller.step`` runs it exported as one ONNX graph (``export``), and a robot's computer runs
that same graph.

What a period computes, in order: the model's own normalisation and network (a flow's Euler
steps from z = 0, or one pass of a regression model), the static prior of a prior model from its
inverse-statics grid (``GridPrior``), the clip of u to each input's range, and the check of the
states: a state that is not finite, a tip beyond the workspace box, or (a prior model) a tip
where the grid cannot give the prior makes the transition ``outside``, and its u is the safe
input, never a clipped full-scale command."""

from __future__ import annotations

import contextlib
import io
import logging
import warnings

import numpy as np
import onnx
import onnxruntime as ort
import torch
from torch import nn

from softflow.models.common import InverseModel
from softflow.models.flow import RectifiedFlow

# torch's exporter writes opset 18 (onnxruntime 1.14, 2023, and later run it).
OPSET = 18


class GridPrior(nn.Module):
    """RF-Physical's prior u_phys(p) at tip points p (B, 3) by trilinear interpolation of an
    ``rod.statics.InverseGrid`` (its nodes solved by the static table), in torch operations:
    the grid coordinates are the gravity-free arc's actuation of the tip's chord and the chord's
    length, where the inverse is smooth. Also returns (B,) bool: the points the grid cannot
    answer (off the grid, or in a cell with a corner at the table's clipped edge)."""

    def __init__(self, grid):
        super().__init__()
        as32 = lambda a: torch.as_tensor(np.asarray(a, np.float32))  # noqa: E731
        self.register_buffer("low", as32(grid.low))  # (3,)
        self.register_buffer("spacing", as32(grid.spacing))  # (3,)
        self.register_buffer("top", as32(grid.shape - 1))  # (3,) the last node per axis
        self.register_buffer("strides", as32(grid.strides))  # (3,) flat index of a node; float32 is exact to 2^24
        self.register_buffer("cell_strides", as32(grid.cell_strides))  # (3,) of a cell
        self.register_buffer(
            "corners", torch.as_tensor(grid.corners, dtype=torch.int64)
        )  # (8,) offsets from a cell's node
        self.register_buffer("bits", as32(list(np.ndindex(2, 2, 2))))  # (8, 3): which end of each axis a corner is at
        self.register_buffer("u", as32(grid.u))  # (N, m) the prior at every node
        self.register_buffer("kink", torch.as_tensor(grid.kink, dtype=torch.bool))  # (cells,)
        self.arc_scale = float(grid.arc_scale)

    def coordinates(self, p):
        """(arc actuation (2), chord length) (B, 3) of tips p (B, 3): ``statics.arc_actuation`` with
        the heading's cosine and sine taken as y / lateral and z / lateral."""
        x, yz = p[:, :1], p[:, 1:3]  # (B, 1), (B, 2)
        squared = (yz * yz).sum(1, keepdim=True)
        lateral, chord = torch.sqrt(squared), torch.sqrt(x * x + squared)  # (B, 1) each
        # the half bend atan2(lateral, x) as 2 atan(lateral / (chord + x)): lateral >= 0, no cancellation for x > 0;
        # on the axis (lateral = 0) the scale is 0 / tiny
        scale = 2 * self.arc_scale * torch.atan(lateral / (chord + x)) / lateral.clamp_min(1e-30)
        return torch.cat([scale * yz, chord], 1)

    def forward(self, p):
        s = (self.coordinates(p) - self.low) / self.spacing  # (B, 3) in node units
        off = ~((s >= 0) & (s <= self.top)).all(1, keepdim=True)  # (B, 1): off the grid, or not a number
        s = torch.where(off, 0.0, s)  # a cell to read for every row
        cell = torch.minimum(torch.floor(s), self.top - 1)  # the top face joins the last cell
        f = (s - cell).unsqueeze(1)  # (B, 1, 3)
        weight = (self.bits * f + (1 - self.bits) * (1 - f)).prod(2)  # (B, 8) each corner's trilinear weight
        values = self.u[(cell @ self.strides).to(torch.int64).unsqueeze(1) + self.corners]  # (B, 8, m)
        kink = self.kink[(cell @ self.cell_strides).to(torch.int64)]  # (B,)
        return (weight.unsqueeze(1) @ values).squeeze(1), off.squeeze(1) | kink


class Step(nn.Module):
    """The step of ``model`` (an inverse model over one transition) as a controller sends it:
    ``forward(x_t, x_next)`` (B, d), (B, d) float32 -> u (B, m), outside (B,). ``low``, ``high``
    (m,): each input's range; ``safe`` (m,): what is sent for an outside transition; ``box_low``,
    ``box_high`` (d,): the workspace box of the states (+-inf where nothing is refused);
    ``grid``: the ``InverseGrid`` of a prior model's training rod."""

    def __init__(self, model: InverseModel, *, low, high, safe, box_low, box_high, grid=None):
        super().__init__()
        if model.context != 1:
            raise ValueError(f"a step reads one transition; {type(model).__name__} reads {model.context}")
        if model.prior and grid is None:
            raise ValueError(f"{type(model).__name__} learns a residual around a static prior: give its grid")
        self.model = model.eval()
        self.prior = GridPrior(grid) if model.prior else None
        self.generative = isinstance(model, RectifiedFlow)
        low, high = _inward(low, high)  # a clipped u never leaves the range given in float64
        for name, value in dict(low=low, high=high, safe=np.clip(np.asarray(safe, np.float32), low, high)).items():
            self.register_buffer(name, torch.as_tensor(value))
        box = np.concatenate([box_low, box_high]).reshape(2, 1, -1).repeat(2, 1).reshape(2, -1)  # x_t's, x_next's
        self.register_buffer("box_low", torch.as_tensor(box[0], dtype=torch.float64))  # (2d,) float64, as
        self.register_buffer("box_high", torch.as_tensor(box[1], dtype=torch.float64))  # check_workspace judges

    def outside(self, x_t, x_next):
        """(B,) bool: the transitions with a state not finite or beyond the workspace box."""
        states = torch.cat([x_t, x_next], 1).double()  # (B, 2d)
        inside = (states >= self.box_low) & (states <= self.box_high)  # NaN compares False
        return inside.to(torch.int32).sum(1) < states.shape[1]

    def unclipped(self, x_t, x_next, *, noise=None, prior=None, steps: int | None = None):
        """The model's u (B, m) before the clip and the safe input, and (B,) bool: the transitions
        that are outside. A flow starts from ``noise`` (B, m) (None: z = 0) and takes ``steps``
        Euler steps (None: its own). ``prior`` (B, m): a prior model's u_phys solved elsewhere
        (``Controller.plan`` gives the static table's), instead of the grid's."""
        outside = self.outside(x_t, x_next)
        if self.prior is not None and prior is None:
            prior, off_grid = self.prior(x_next[:, : self.model.dims.position])
            outside = outside | off_grid
        condition = self.model.transition(x_t, x_next, prior)
        if not self.generative:
            return self.model.act(condition, prior), outside
        noise = torch.zeros(1, self.low.shape[0]) if noise is None else noise  # z = 0 broadcast: a constant
        return self.model.act(condition, prior, noise, steps), outside

    def forward(self, x_t, x_next):
        u, outside = self.unclipped(x_t, x_next)
        u = torch.minimum(torch.maximum(u, self.low), self.high)
        return torch.where(outside.unsqueeze(1), self.safe, u), outside


def _inward(low, high) -> tuple[np.ndarray, np.ndarray]:
    """The float32 bounds nearest to ``low`` and ``high`` (float64, (m,) each) that lie inside them."""
    low, high = np.asarray(low, np.float64), np.asarray(high, np.float64)
    low32, high32 = low.astype(np.float32), high.astype(np.float32)
    low32 = np.where(low32 < low, np.nextafter(low32, np.float32(np.inf)), low32)
    high32 = np.where(high32 > high, np.nextafter(high32, np.float32(-np.inf)), high32)
    return low32, high32


def graph(step: Step) -> onnx.ModelProto:
    """``step`` exported by torch's exporter as one ONNX graph: inputs ``x_t``, ``x_next`` (B, d)
    float32, outputs ``u`` (B, m) float32 and ``outside`` (B,) bool."""
    d = step.model.dims.state
    example = (torch.zeros(2, d), torch.full((2, d), 0.1))  # two distinct inputs: the exporter keeps both
    return export_graph(step, example, ["x_t", "x_next"], ["u", "outside"])


def export_graph(module: nn.Module, example: tuple, input_names: list, output_names: list) -> onnx.ModelProto:
    """``module`` exported by torch's exporter (opset ``OPSET``) with the batch, the first axis of
    every input, left free; the exporter's notes on what it could not register or fold are quiet."""
    batch = torch.export.Dim("batch", min=1)
    quiet = [logging.getLogger(name) for name in ("torch.onnx", "onnxscript")]
    levels = [logger.level for logger in quiet]
    for logger in quiet:
        logger.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            program = torch.onnx.export(
                module,
                example,
                dynamo=True,
                opset_version=OPSET,
                input_names=input_names,
                output_names=output_names,
                dynamic_shapes=tuple({0: batch} for _ in example),
                verbose=False,
            )
    finally:
        for logger, level in zip(quiet, levels):
            logger.setLevel(level)
    return program.model_proto


def real_time_session(model: onnx.ModelProto) -> ort.InferenceSession:
    """``model`` in onnxruntime as a control loop runs it: on the CPU, one thread, sequential."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    return ort.InferenceSession(model.SerializeToString(), options, providers=["CPUExecutionProvider"])


class BoundGraph:
    """A step module's graph in onnxruntime for a real-time loop: one thread, sequential, one
    transition's inputs and outputs bound once to arrays that each call reuses."""

    def __init__(self, step: Step):
        self.session = real_time_session(graph(step))
        d, m = step.model.dims.state, step.model.dims.inputs
        self.x_t, self.x_next = np.zeros((1, d), np.float32), np.zeros((1, d), np.float32)
        self.u, self.outside = np.zeros((1, m), np.float32), np.zeros(1, bool)
        self.binding = self.session.io_binding()
        for name, array in dict(x_t=self.x_t, x_next=self.x_next).items():
            self.binding.bind_ortvalue_input(name, ort.OrtValue.ortvalue_from_numpy(array))  # shares the array
        for name, array in dict(u=self.u, outside=self.outside).items():
            self.binding.bind_output(name, "cpu", 0, array.dtype, array.shape, array.ctypes.data)
        self.bounds = [(float(a), float(b)) for a, b in zip(step.low, step.high)]

    def run(self):
        self.session.run_with_iobinding(self.binding)

    def saturated(self) -> bool:
        """Whether the last u sits on an input's bound, as the clip leaves it."""
        return any(v <= low or v >= high for v, (low, high) in zip(self.u[0].tolist(), self.bounds))
