"""The step exported as one ONNX graph (``control.export_onnx``, ``softflow export MODEL --onnx``,
the graph ``Controller.step`` runs) against its definition, ``Controller.step_module`` in torch:
the same u on 10,000 in-workspace transitions of every shipped model that steps (RF-Physical with
its prior's grid) and of models of recorded runs, and against ``plan``; the refusals of the
workspace margin as ``check_workspace`` judges them, the safe input in their place, the clipping
per input; what has no one-transition step is refused by name."""

import contextlib
import io
import json
import re
import warnings

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch
from test_recordings import point_mass_run, tiny_training

from softflow import HW_ROBOT, SIM_ROBOT, TWO_SEGMENT_ROD, Simulator, cli, control, data, recordings
from softflow.models.specs import CONTROLLERS, resolved_kwargs
from softflow.report import model_cards
from softflow.studies import two_segment

PAIRS = 10_000
# N. Both compute in float32 from the same weights; they differ in the order of the matmul sums
# and in the sigmoid: at most 4.6e-6 N measured on the shipped models' references.
TOLERANCE = 1e-5
# Every shipped model that has a one-transition step (not a window of past states), on each rod it
# ships for: read from checkpoints/, so a newly shipped model is checked without a word here.
SHIPPED = [
    (m.name, m.robot, m.gravity)
    for m in model_cards.shipped_models()
    if m.paper_model and m.name in CONTROLLERS and "context" not in resolved_kwargs(m.name)
]
DELAY = 3  # periods of 10 ms: the delay the recorded models are trained with
TEXT = {"model", "robot", "gravity", "softflow_version"}  # metadata stored as text, not JSON


def session(path) -> ort.InferenceSession:
    """The graph on one CPU thread, as a robot's controller runs it."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])


def run_graph(path, x_t, x_next):
    """(u (B, m), outside (B,)) of the graph at ``path``."""
    return session(path).run(None, {"x_t": x_t, "x_next": x_next})


def metadata(path) -> dict:
    """The graph's metadata, its JSON values decoded (text values are stored as they are)."""
    stored = session(path).get_modelmeta().custom_metadata_map
    return {key: value if key in TEXT else json.loads(value) for key, value in stored.items()}


def defined(controller, x_t, x_next):
    """(u (B, m), outside (B,)) of the step's definition, ``Controller.step_module``, in torch."""
    with torch.no_grad():
        u, outside = controller.step_module(*(torch.as_tensor(x, dtype=torch.float32) for x in (x_t, x_next)))
    return u.numpy(), outside.numpy()


def refuses(controller, x_t, x_next) -> bool:
    """Whether ``check_workspace`` (float64) refuses either state, or one is not finite."""
    if not (np.isfinite(x_t).all() and np.isfinite(x_next).all()):
        return True
    try:
        controller.check_workspace(np.stack([x_t, x_next]).astype(np.float64))
    except ValueError:
        return True
    return False


def rod_references(robot, gravity) -> list[np.ndarray]:
    """The states (T+1, d) of each of the rod's own references: Table I's on the paper's rod, Table
    III's shapes on the hardware twin, the two-segment study's shapes (all cached in the repository)."""
    sim = Simulator(robot, gravity)
    if robot == HW_ROBOT:
        made = data.hardware_references(sim)
    elif robot == TWO_SEGMENT_ROD:
        made = two_segment.references(sim, "paper", names=list(two_segment.TWO_SEGMENT["paper"].shapes))
    else:
        made = data.evaluation_references(sim)
    return [r.states for r in made]


def transitions(trajectories, controller, n: int = PAIRS, seed: int = 0):
    """n pairs (x_t, x_next), (n, d) float32 each, inside the workspace: the trajectories'
    consecutive states, tiled to n, each copy after the first shifted by a small random offset
    (0.1 mm, 1 mm/s; the same for both states of a pair, so that its increment is kept)."""
    x_t = np.concatenate([X[:-1] for X in trajectories])  # (P, d)
    x_next = np.concatenate([X[1:] for X in trajectories])
    index, p = np.arange(n) % len(x_t), x_t.shape[1] // 2
    shift = np.random.default_rng(seed).normal(size=(n, 2 * p)) * np.repeat([1e-4, 1e-3], p)
    shift[: len(x_t)] = 0
    x_t, x_next = (np.asarray(x[index] + shift, np.float32) for x in (x_t, x_next))
    for x, name in ((x_t, "x_t"), (x_next, "x_next")):
        controller.check_workspace(x, name)
    return x_t, x_next


@pytest.mark.parametrize("name, robot, gravity", SHIPPED, ids=[f"{n}-{r.name}-{g}" for n, r, g in SHIPPED])
def test_the_graph_steps_as_the_controller_on_its_rods_references(name, robot, gravity, tmp_path):
    controller = control.load_controller(name, robot=robot, gravity=gravity)
    x_t, x_next = transitions(rod_references(robot, gravity), controller)
    u, outside = run_graph(control.export_onnx(controller, tmp_path / f"{name}.onnx"), x_t, x_next)
    assert u.shape == (PAIRS, controller.model.dims.inputs) and u.dtype == np.float32
    np.testing.assert_allclose(u, defined(controller, x_t, x_next)[0], rtol=0, atol=TOLERANCE)
    assert outside.dtype == bool and not outside.any()
    if controller.statics is None:  # plan's prior is the table's, the step's the grid's (1e-3 N)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", control.SaturationWarning)
            planned = controller.plan(np.stack([x_t[: PAIRS // 10], x_next[: PAIRS // 10]], 1))[:, 0]
        np.testing.assert_allclose(u[: PAIRS // 10], planned, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("name", ["rf-1", "rf-fwd-1", "rf-physical-1"])
@pytest.mark.parametrize("steps", [1, 2])
def test_a_one_step_flows_graph_steps_as_the_controller(name, steps, trained, tmp_path):
    model = trained(name)[0]
    model.steps = steps  # at one step and at two: each step's span enters the first layer
    controller = control.Controller(model, name)
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), controller)
    u, outside = run_graph(control.export_onnx(controller, tmp_path / f"{name}.onnx"), x_t, x_next)
    np.testing.assert_allclose(u, defined(controller, x_t, x_next)[0], rtol=0, atol=TOLERANCE)
    assert metadata(tmp_path / f"{name}.onnx")["euler_steps"] == steps and not outside.any()


def test_an_mlp_with_the_static_prior_exports_as_it_steps(trained, tmp_path):
    controller = control.Controller(trained("mlp-physical")[0], "mlp-physical")
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), controller, n=2000)
    u, outside = run_graph(control.export_onnx(controller, tmp_path / "mlp-physical.onnx"), x_t, x_next)
    np.testing.assert_allclose(u, defined(controller, x_t, x_next)[0], rtol=0, atol=TOLERANCE)
    assert not outside.any()


def test_a_prior_the_grid_cannot_give_is_flagged_and_sends_the_safe_input(tmp_path):
    """RF-Physical's graph carries its prior's grid; where the grid cannot follow the table (here a
    tip whose inverse is clipped at the table's edge), ``outside`` says so, u is the safe input,
    and ``step`` refuses the state."""
    controller = control.load_controller("rf-physical")
    table = controller.statics
    tip, _ = table.tip(np.array([[table.u_range, 1.0], [2.0, 1.0]]))  # at the edge, and well inside
    x = np.concatenate([tip, np.zeros((2, 3))], 1)  # at rest at each tip
    u, outside = run_graph(control.export_onnx(controller, tmp_path / "rf-physical.onnx"), *(x.astype(np.float32),) * 2)
    np.testing.assert_array_equal(outside, [True, False])
    np.testing.assert_array_equal(u[0], controller.safe_input.astype(np.float32))
    np.testing.assert_allclose(u[1], controller.step(x[1], x[1]), rtol=0, atol=TOLERANCE)
    with pytest.raises(ValueError, match="where the static prior's grid does not reach"):
        controller.step(x[0], x[0])


def test_the_graph_is_the_steps_arithmetic_with_its_metadata(tmp_path):
    controller = control.load_controller("rf-fwd")
    path = control.export_onnx(controller, tmp_path / "new" / "rf-fwd.onnx")  # its folder is made
    assert onnx.load(path).opset_import[0].version == 18  # onnxruntime 1.14 and later
    ran = session(path)
    assert [(v.name, v.shape) for v in ran.get_inputs()] == [("x_t", ["batch", 6]), ("x_next", ["batch", 6])]
    assert [(v.name, v.shape) for v in ran.get_outputs()] == [("u", ["batch", 2]), ("outside", ["batch"])]
    meta, (mean, halfwidth) = metadata(path), controller.workspace
    assert (
        meta["model"] == "rf-fwd"
        and meta["robot"] == "sim"
        and meta["gravity"] == "vertical"
        and meta["euler_steps"] == controller.model.steps
    )
    assert (meta["state_size"], meta["input_size"], meta["workspace_margin"]) == (6, 2, control.WORKSPACE_MARGIN)
    np.testing.assert_array_equal(meta["workspace_mean"], mean)
    np.testing.assert_array_equal(meta["workspace_halfwidth"], halfwidth)
    assert (meta["input_low"], meta["input_high"], meta["sample_period_s"]) == ([-4.0, -4.0], [4.0, 4.0], 0.01)
    assert meta["safe_input"] == [0.0, 0.0]
    assert (meta["delay_steps"], meta["tip_columns"]) == (0, [])
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), controller, n=1)  # batch 1
    np.testing.assert_allclose(
        ran.run(["u"], {"x_t": x_t, "x_next": x_next})[0], controller.step(x_t, x_next), atol=TOLERANCE
    )


def test_the_graph_clips_each_input_to_its_range_as_the_step(tmp_path):
    shipped = control.load_controller("rf")
    controller = control.Controller(shipped.model, "rf", u_range=([-1.0, -0.25], [0.5, 2.0]))
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), controller)
    u, _ = run_graph(control.export_onnx(controller, tmp_path / "rf.onnx"), x_t, x_next)
    np.testing.assert_allclose(u, defined(controller, x_t, x_next)[0], rtol=0, atol=TOLERANCE)
    raw = controller.step(x_t, x_next, clip=False)
    for bound, saturated in zip(
        controller.input_range, (raw < controller.input_range[0], raw > controller.input_range[1])
    ):
        assert saturated.mean(0).min() > 0.01  # every bound of every input is reached
        np.testing.assert_allclose(u[saturated], np.broadcast_to(bound, u.shape)[saturated], rtol=0, atol=TOLERANCE)


def test_outside_flags_the_pairs_the_workspace_refuses_and_sends_the_safe_input(tmp_path):
    """Pairs built to straddle the margin: one tip coordinate of x_t or x_next of each pair set
    just inside, on or just beyond it (1e-6 of the half-width is a few float32 steps); some hold
    a value that is not finite (a lost marker), which is refused too. The graph (float32) flags
    what ``check_workspace`` (float64) refuses, and sends the safe input there."""
    controller = control.load_controller("mlp")
    n = 2000
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), controller, n=n)
    mean, halfwidth = controller.workspace
    rng = np.random.default_rng(1)
    axis, side = rng.integers(0, len(mean), n), rng.choice([-1.0, 1.0], n)
    factor = rng.choice([0.999, 1 - 1e-6, 1.0, 1 + 1e-6, 1.001], n)
    value = mean[axis] + side * factor * halfwidth[axis]
    in_next = rng.random(n) < 0.5
    x_t[~in_next, axis[~in_next]] = value[~in_next]
    x_next[in_next, axis[in_next]] = value[in_next]
    x_t[::97, 4], x_next[50::101, 1] = np.nan, np.inf
    refused = np.array([refuses(controller, a, b) for a, b in zip(x_t, x_next)])
    u, outside = run_graph(control.export_onnx(controller, tmp_path / "mlp.onnx"), x_t, x_next)
    assert 0.3 < refused.mean() < 0.7
    np.testing.assert_array_equal(outside, refused)
    assert (u[outside] == 0).all()  # the rod's safe input: no differential tension


def test_with_no_margin_only_states_that_are_not_finite_are_outside(tmp_path):
    controller = control.load_controller("mlp")
    controller.workspace_margin = None
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), controller, n=4)
    x_t[:, 1] += 1.0  # a metre off: far outside any margin
    x_next[3, 0] = np.nan
    path = control.export_onnx(controller, tmp_path / "mlp.onnx")
    np.testing.assert_array_equal(run_graph(path, x_t, x_next)[1], [False, False, False, True])
    meta = metadata(path)
    assert (meta["workspace_margin"], meta["workspace_halfwidth"]) == (None, None)


@pytest.mark.parametrize(
    "name, message",
    [
        ("lstm", "lstm reads a window of 10 past transitions: it has no one-transition step to export"),
        ("transformer", "it has no one-transition step to export; plan it in Python"),
    ],
)
def test_what_has_no_graph_yet_is_refused(name, message, tmp_path):
    controller = control.load_controller(name)
    with pytest.raises(ValueError, match=message):
        control.export_onnx(controller, tmp_path / "model.onnx")
    assert not list(tmp_path.iterdir())


def test_bad_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match="expected a Controller"):
        control.export_onnx(control.load_controller("mlp").model, tmp_path / "mlp.onnx")
    with pytest.raises(ValueError, match="is a directory; expected a file to write"):
        control.export_onnx(control.load_controller("mlp"), tmp_path)


@pytest.mark.parametrize("rod", [[], ["--robot", "hw"]], ids=["default", "hw"])
def test_the_cli_writes_the_paper_rods_graph_by_default_and_the_hardware_rods_on_request(rod, tmp_path, capsys):
    out, robot = tmp_path / "rf-fwd.onnx", "hw" if rod else "sim"
    cli.main(["export", "rf-fwd", *rod, "--onnx", str(out)])
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == str(out) and lines[0].startswith(f"rf-fwd ({robot} rod, vertical): Controller.step as one ONNX")
    meta = metadata(out)
    assert (meta["model"], meta["robot"], meta["gravity"]) == ("rf-fwd", robot, "vertical")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Twelve recordings of a 3-input, 2-D-tip point mass; an MLP and an RF trained on them by the
    CLI with a delay of DELAY periods given (ci profile shrunk to TINY; nothing in data/). Returns
    (folder, Dataset, where the checkpoints are)."""
    runs, rng = tmp_path_factory.mktemp("runs"), np.random.default_rng(3)
    for i in range(12):
        point_mass_run(runs / f"run{i:02d}.csv", rng, 3, 2, 3.0)
    trained_in = tmp_path_factory.mktemp("checkpoints")
    with pytest.MonkeyPatch.context() as patch:
        tiny_training(patch, trained_in)
        with contextlib.redirect_stdout(io.StringIO()):
            cli.main(["train", "mlp", "rf", "--recordings", str(runs), "--profile", "ci", "--delay", f"{DELAY / 100}"])
        dataset = recordings.load_dataset(runs, delay=DELAY / 100)
    return runs, dataset, trained_in


@pytest.mark.parametrize("model", ["mlp", "rf"])
def test_a_model_of_recorded_runs_exports_with_its_delay(recorded, model, tmp_path, capsys, monkeypatch):
    runs, dataset, trained_in = recorded
    tiny_training(monkeypatch, trained_in)
    out = tmp_path / f"{model}.onnx"
    cli.main(
        ["export", model, "--profile", "ci", "--recordings", str(runs), "--delay", f"{DELAY / 100}", "--onnx", str(out)]
    )
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == str(out) and f"moves {DELAY} periods after an input is sent" in lines[0]
    meta = metadata(out)
    controller = control.load_controller(model, "ci", recordings=dataset)
    low, high = controller.input_range
    assert (meta["delay_steps"], meta["tip_columns"], meta["sample_period_s"]) == (DELAY, ["x_m", "y_m"], dataset.dt)
    assert (meta["robot"], meta["state_size"], meta["input_size"]) == ("null", 4, 3)
    assert (meta["input_low"], meta["input_high"]) == (low.tolist(), high.tolist())
    x_t, x_next = transitions(dataset.states, controller)
    u, outside = run_graph(out, x_t, x_next)
    np.testing.assert_allclose(u, defined(controller, x_t, x_next)[0], rtol=0, atol=TOLERANCE)
    assert not outside.any()


def test_the_cli_writes_the_limits_and_the_safe_input_it_is_given(tmp_path, capsys):
    """A rig whose actuators must stay inside narrower limits than the data took: each input is
    clipped to its own range, and a refused transition sends the safe input given."""
    out = tmp_path / "rf.onnx"
    cli.main(["export", "rf", "--onnx", str(out), "--input-range=-1:0.5,-2:3", "--safe-input", "0.25,-1"])
    meta = metadata(out)
    assert (meta["input_low"], meta["input_high"], meta["safe_input"]) == ([-1.0, -2.0], [0.5, 3.0], [0.25, -1.0])
    x_t, x_next = transitions(rod_references(SIM_ROBOT, "vertical"), control.load_controller("rf"), n=2000)
    x_next[::10, 0] = 9.0  # a tip 9 m out
    u, outside = run_graph(out, x_t, x_next)
    assert outside.sum() == 200 and (u[outside] == np.float32([0.25, -1.0])).all()
    assert ((u[~outside] >= np.float32([-1, -2])) & (u[~outside] <= np.float32([0.5, 3]))).all()
    assert (u[~outside] == np.float32([-1, -2])).any() and (u[~outside] == np.float32([0.5, 3])).any()  # reached


@pytest.mark.parametrize(
    "options, message",
    [
        (["--onnx", "{out}", "--safe-input", "9"], "safe_input must be one value per input inside"),
        (["--onnx", "{out}", "--input-range=1:0"], r"u_range must be \(low, high\) with low <= high"),
        (["--onnx", "{out}", "--input-range", "1"], "--input-range takes LOW:HIGH"),
        (["--onnx", "{out}", "--safe-input", "a"], "--safe-input takes numbers separated by commas"),
        (["--out", "{out}", "--safe-input", "0"], "--safe-input: limits of the step's graph; they need --onnx"),
    ],
)
def test_limits_that_do_not_fit_are_refused_by_flag(options, message, tmp_path, capsys):
    argv = ["export", "rf", *(o.format(out=tmp_path / "rf.onnx") for o in options)]
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    error = capsys.readouterr().err
    assert stop.value.code == 2 and re.search(message, error) and "usage:" not in error
    assert not list(tmp_path.iterdir())
