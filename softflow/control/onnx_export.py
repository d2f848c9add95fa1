"""A controller's real-time step, or a whole period of the loop of a model of recorded runs, as
one ONNX graph for a robot's controller outside Python (onnxruntime's C, C++, C# or Python API):
``Controller.step_module`` (the graph ``Controller.step`` itself runs) or ``loop.Period``
exported by torch's exporter, with metadata that say what it was made from."""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import onnx
from onnx import helper

from softflow.control.loop import MEMORY, Loop
from softflow.control.planning import Controller
from softflow.control.step import graph
from softflow.data.recordings import column_unit
from softflow.store import atomic_write


def export_onnx(controller: Controller, path) -> Path:
    """Write ``controller.step`` as one ONNX graph at ``path`` (replaced); returns the path.

    Inputs ``x_t`` and ``x_next``: (B, d) float32 states in the model's units. Outputs ``u``
    (B, m) float32, clipped to the controller's input range per input, and ``outside`` (B,)
    bool: True where ``step`` refuses the pair (a tip position beyond the workspace margin, a
    value that is not finite, or a tip where a prior model's grid does not reach); there ``u``
    is the safe input (``safe_input`` in the metadata), never a clipped command. A flow starts
    from z = 0, as ``step`` does. The metadata (``metadata_props``; numbers and lists as JSON)
    say what the graph was made from: ``_metadata``."""
    path = _checked(controller, path)
    return _write(graph(controller.step_module), controller, "step", _metadata(controller), path)


def export_loop(loop: Loop, path) -> Path:
    """Write ``loop``'s period (``control.loop_of``) as one ONNX graph at ``path`` (replaced);
    returns the path. A robot's program calls it once per period with the newest frame of the
    observed columns (``frame``, (1, k) float64, NaN where none came), the reference states
    wanted now, delay and delay + 1 periods ahead (``reference``, (1, 3, d) float32) and the
    memory the last call returned (inputs named by ``loop.MEMORY``, outputs ``next_`` + each; the
    first call gets ``start_memory`` from the metadata), and sends ``u`` (1, m) float32;
    ``holding`` says it is the safe input. The
    metadata are the step's (``export_onnx``) and the loop's: the period, the observed and input
    columns, the inputs' units where their names declare them (``l1_mm``), each input's rate
    limit, the watchdog, the session's anchor and the start memory."""
    if not isinstance(loop, Loop):
        raise ValueError(f"expected a Loop (softflow.control.loop_of); got {type(loop).__name__}")
    controller, period = loop.controller, loop.period
    path = _checked(controller, path)
    start = {
        name: dict(
            dtype=str(value.dtype).removeprefix("torch."), shape=list(value.shape), values=value.flatten().tolist()
        )
        for name, value in period.memory().items()
    }
    values = _metadata(controller) | {
        key: json.dumps(value)
        for key, value in dict(
            input_columns=list(loop.input_columns),
            input_units=[column_unit(name) for name in loop.input_columns],  # null: the name declares none
            input_rate=period.rate.tolist(),
            watchdog_periods=period.watchdog,
            anchor_m=period.anchor.tolist(),
            memory=list(MEMORY),
            start_memory=start,
        ).items()
    }
    return _write(loop.graph(), controller, "loop", values, path)


def _checked(controller: Controller, path) -> Path:
    if not isinstance(controller, Controller):
        raise ValueError(f"expected a Controller (softflow.load_controller); got {type(controller).__name__}")
    if not controller.has_step:
        raise ValueError(
            f"{controller.name} reads a window of {controller.model.context} past transitions: it has no "
            "one-transition step to export; plan it in Python (Controller.plan)"
        )
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a directory; expected a file to write (e.g. {controller.name}.onnx)")
    return path


def _write(model: onnx.ModelProto, controller: Controller, what: str, metadata: dict, path: Path) -> Path:
    model.producer_name, model.producer_version = "softflow", _version()
    made = "Controller.step" if what == "step" else "a loop's period"
    model.doc_string = f"softflow {controller.name}: {made} as one graph"
    model.graph.name = f"softflow_{controller.name.replace('-', '_')}_{what}"
    helper.set_model_props(model, metadata)
    onnx.checker.check_model(model, full_check=True)
    with atomic_write(path) as f:
        f.write(model.SerializeToString())
    return path


def _metadata(controller: Controller) -> dict[str, str]:
    """What a robot's program needs to use the graph: the model and its rod, the sizes, the Euler
    steps (0: a regression model), the workspace (tip mean and half-widths, m; null with no margin),
    the input range and the safe input, the sample period (s; null when unknown), the delay in periods by which a
    model of recorded runs' inputs must be sent early and the columns it observes, the version."""
    dims, (mean, halfwidth), (low, high) = controller.model.dims, controller.workspace, controller.input_range
    values = dict(
        model=controller.name,
        robot=None if controller.robot is None else controller.robot.name,
        gravity=controller.gravity,
        state_size=dims.state,
        input_size=dims.inputs,
        euler_steps=controller.model.steps if controller.generative else 0,
        workspace_mean=mean.tolist(),
        workspace_halfwidth=None if halfwidth is None else halfwidth.tolist(),
        workspace_margin=controller.workspace_margin,
        input_low=low.tolist(),
        input_high=high.tolist(),
        safe_input=controller.safe_input.tolist(),
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
