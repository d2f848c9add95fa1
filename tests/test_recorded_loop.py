"""The loop of a model of recorded runs (control.loop): its filter is the offline smoother's
forward pass, its predictor is exact on a linear rig, its limits are the recordings', it is safe
by construction (unknown, stale or outside: the safe input; never faster than the recordings
moved), and its exported graph, run by examples/run_loop.py with numpy and onnxruntime alone,
is the torch period to 1e-5 over a whole run and drives a delayed rod."""

import contextlib
import importlib.util
import io
import json
from pathlib import Path

import numpy as np
import onnx
import pandas as pd
import pytest
import torch
from test_recordings import delayed_rod_run, tiny_training

from softflow import SIM_ROBOT, Simulator, cli, control, recordings
from softflow.control import loop
from softflow.control.planning import Controller
from softflow.data.dataset import Dataset
from softflow.data.smoothing import _filter
from softflow.models.specs import build_model

DELAY = 6  # periods of 10 ms
EXAMPLE = Path(__file__).parents[1] / "examples" / "run_loop.py"


def example():
    spec = importlib.util.spec_from_file_location("run_loop", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_loops_filter_is_the_smoothers_forward_pass():
    rng = np.random.default_rng(0)
    dt, noise, jerk = 0.01, np.array([1e-4, 3e-4]), np.array([3.0, 30.0])
    t = np.arange(300) * dt
    values = np.stack([0.1 * np.sin(3 * t), 0.05 * np.cos(5 * t)], 1) + noise * rng.standard_normal((300, 2))
    values[rng.random((300, 2)) < 0.1] = np.nan  # lost frames
    values[0] = [0.0, 0.05]
    estimator = loop.Estimator(dt, noise, jerk)
    x, P = torch.full((1, 2, 3), torch.nan, dtype=torch.float64), torch.zeros(1, 2, 3, 3, dtype=torch.float64)
    online = []
    for frame in values:
        frame = torch.as_tensor(frame)[None]
        x, P = estimator(frame, x, P, torch.isfinite(frame))
        online.append(x[0].numpy())
    for i in range(2):
        _, (_, _, filtered, covariance) = _filter(t, values[:, i], noise[i : i + 1], jerk[i : i + 1], keep=True)
        np.testing.assert_allclose(np.array(online)[:, i], filtered[:, 0], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(P[0, i].numpy(), covariance[-1, 0], rtol=1e-9, atol=1e-15)


def test_a_model_for_the_loop_trains_on_the_states_the_loop_estimates(rig):
    """Recordings read with causal=True (levels given, as the loop's are one per column) hold the
    loop's own estimates: the filter over the same frames, period by period, to 1e-9 m."""
    runs = rig[0]
    run = recordings.read(runs / "run0.csv", delay=0.06, noise=1e-4, jerk=10.0, causal=True)
    frames = pd.read_csv(runs / "run0.csv").dropna(subset=["x_m"])[["x_m", "y_m", "z_m"]].to_numpy()
    estimator = loop.Estimator(0.01, np.full(3, 1e-4), np.full(3, 10.0))
    x, P = torch.full((1, 3, 3), torch.nan, dtype=torch.float64), torch.zeros(1, 3, 3, 3, dtype=torch.float64)
    online = []
    for frame in torch.as_tensor(frames)[:, None]:
        x, P = estimator(frame, x, P, torch.isfinite(frame))
        online.append(torch.cat([x[0, :, 0], x[0, :, 1]]).numpy())
    np.testing.assert_allclose(np.array(online)[: len(run.states)], run.states, rtol=0, atol=1e-9)
    smoothed = recordings.read(runs / "run0.csv", delay=0.06, noise=1e-4, jerk=10.0).states
    assert np.abs(smoothed - run.states).max() > 1e-3  # the smoother's states are others: it sees ahead


def linear_rig(steps: int = 400, seed: int = 1):
    """Episodes of a stable linear rig x_{t+1} = x_t A + u_t B + c, exactly: (Dataset, A, B, c)."""
    rng = np.random.default_rng(seed)
    d, m = 4, 2
    A = np.eye(d) + 0.05 * rng.standard_normal((d, d)) - 0.1 * np.eye(d)
    B, c = rng.standard_normal((m, d)), 0.01 * rng.standard_normal(d)
    u = rng.uniform(-1, 1, (5, steps, m))
    X = np.zeros((5, steps + 1, d))
    for t in range(steps):
        X[:, t + 1] = X[:, t] @ A + u[:, t] @ B + c
    data = Dataset(u, X, np.arange(4), np.array([4]), np.array([4]), robot=None, gravity=None, dt=0.01)
    return data, A, B, c


def test_the_predictor_carries_a_linear_rig_exactly_through_the_inputs_in_flight():
    data, A, B, c = linear_rig()
    predictor = loop.Predictor.fit(data, 5, ridge=0.0)
    u, X = data.u[4], data.states[4]  # a held-out episode
    for t in (0, 37, 200):
        ahead = predictor(torch.as_tensor(X[t])[None], torch.as_tensor(u[t : t + 5])[None])[0].numpy()
        np.testing.assert_allclose(ahead, X[t + 5], rtol=1e-8, atol=1e-10)
    none = loop.Predictor.fit(data, 0)
    np.testing.assert_allclose(none(torch.as_tensor(X[:3]), torch.zeros(3, 0, 2, dtype=torch.float64)).numpy(), X[:3])


def test_the_limits_are_what_the_training_recordings_did():
    u = np.array([[[0.0, 1.0], [2.0, 1.5], [3.0, 1.0]], [[-1.0, 0.0], [-1.0, 0.5], [9.0, 0.5]]])  # (2, 3, 2)
    data = Dataset(u, np.zeros((2, 4, 2)), np.array([0]), np.array([1]), np.array([1]), robot=None, gravity=None)
    limits = loop.InputLimits.of(data)  # the training episode only: 9 is a validation input
    np.testing.assert_array_equal(limits.low, [0.0, 1.0])
    np.testing.assert_array_equal(limits.high, [3.0, 1.5])
    np.testing.assert_array_equal(limits.rate, [2.0, 0.5])
    np.testing.assert_array_equal(limits.safe, [2.0, 1.0])
    given = loop.InputLimits.of(data, u_range=(-1, 1), safe_input=[0.5, -0.5])
    np.testing.assert_array_equal(given.high, [1.0, 1.0])
    np.testing.assert_array_equal(given.safe, [0.5, -0.5])
    with pytest.raises(ValueError, match="safe_input must be 2 values, each inside its input's range"):
        loop.InputLimits.of(data, safe_input=[5.0, 1.0])


def test_a_plan_is_checked_against_the_limits_of_the_recordings():
    limits = loop.InputLimits(np.array([0.0, -1.0]), np.array([3.0, 1.0]), np.array([0.5, 2.0]), np.zeros(2))
    inside = np.array([[0.0, -1.0], [0.5, 1.0], [1.0, -1.0]])  # on the range's ends, at the rate's limit
    assert limits.violations(inside) == []
    beyond = np.array([[0.0, 0.0], [3.5, 0.0], [2.5, 0.5]])  # 3.5 above 3; steps of 3.5 and 1 beyond 0.5
    assert limits.violations(beyond, ["l1_mm", "l2_mm"]) == [
        "l1_mm: 1 of 3 samples outside 0 to 3, 2 steps faster than 0.5 per period"
    ]


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """Three runs of the simulated rod whose inputs act 60 ms after they are sent, their Dataset,
    and an MLP trained on them by the CLI (ci profile shrunk to TINY), the states causal."""
    runs = tmp_path_factory.mktemp("delayed")
    for seed in range(3):
        delayed_rod_run(runs / f"run{seed}.csv", DELAY, seed=30 + seed, seconds=6.0)
    trained_in = tmp_path_factory.mktemp("checkpoints")
    with pytest.MonkeyPatch.context() as patch:
        tiny_training(patch, trained_in)
        with contextlib.redirect_stdout(io.StringIO()):
            cli.main(["train", "mlp", "--recordings", str(runs), "--profile", "ci", "--delay", "0.06", "--causal"])
    data = recordings.load_dataset(runs, delay=0.06, causal=True, data_dir=None)
    return runs, data, trained_in


@pytest.fixture
def trained(rig, monkeypatch):
    tiny_training(monkeypatch, rig[2])
    return rig


def rows_for(states, t: int) -> np.ndarray:
    """The reference rows a loop gets at period t: the states wanted now, DELAY and DELAY + 1
    periods ahead (the last once the path ends), (3, d)."""
    return states[np.minimum([t, t + DELAY, t + DELAY + 1], len(states) - 1)]


def untrained_loop(data, **options) -> loop.Loop:
    torch.manual_seed(0)
    controller = Controller(build_model("mlp", data.dims), "mlp", robot=None, gravity=None, dt=data.dt)
    return loop.loop_of(controller, data, **options)


def test_the_loop_sends_the_safe_input_until_it_knows_the_state_and_when_frames_go_stale(rig):
    _, data, _ = rig
    run = recordings.read(rig[0] / "run0.csv", delay=0.06)
    tip = run.states[:, :3]  # (T+1, 3)
    looped = untrained_loop(data)
    safe = looped.period.step.safe.double().numpy()
    np.testing.assert_array_equal(looped(np.full(3, np.nan), rows_for(run.states, 0)), safe)  # no frame yet
    assert looped.holding
    looped(tip[0], rows_for(run.states, 1))
    assert not looped.holding  # a fresh frame of the point
    watchdog = looped.period.watchdog
    for t in range(1, watchdog + 1):  # the tracker holds the point: every coordinate repeats
        looped(tip[0], rows_for(run.states, 1 + t))
        assert not looped.holding
    np.testing.assert_array_equal(looped(tip[0], rows_for(run.states, 2 + watchdog)), safe)
    assert looped.holding
    looped(tip[1], rows_for(run.states, 3 + watchdog))
    assert not looped.holding  # fresh again
    looped(tip[2], np.full((3, 6), 1e3))  # a reference a units slip sent beyond the workspace
    assert looped.holding


def test_a_constant_coordinate_is_not_a_held_frame(rig):
    _, data, _ = rig
    run = recordings.read(rig[0] / "run0.csv", delay=0.06)
    looped = untrained_loop(data, watchdog=0.0)
    for t in range(20):
        looped(np.array([0.4, *run.states[t, 1:3]]), rows_for(run.states, t))  # x never changes, y and z do
        assert not looped.holding or t == 0


def test_the_loop_moves_no_faster_than_the_recordings_and_stays_in_their_range(rig):
    _, data, _ = rig
    run = recordings.read(rig[0] / "run1.csv", delay=0.06)
    looped = untrained_loop(data, u_range=(-1.0, 1.0), rate=1e-3)
    rate = looped.period.rate.double().numpy()
    sent = [looped(x[:3], rows_for(run.states, t)) for t, x in enumerate(run.states)]
    steps = np.abs(np.diff(sent, axis=0))
    assert (steps <= rate + 1e-6).all() and (np.abs(sent) <= 1.0).all()
    assert (steps.max(0) > 0.999 * rate).all()  # each input is held to its limit, not under it by a still model


def test_the_loops_graph_run_by_the_example_is_the_torch_period(rig, tmp_path):
    _, data, _ = rig
    looped = untrained_loop(data)
    path = control.export_loop(looped, tmp_path / "loop.onnx")
    graph = example().LoopGraph(path)
    run = recordings.read(rig[0] / "run2.csv", delay=0.06)
    rng = np.random.default_rng(3)
    frames = run.states[:, :3] + 5e-5 * rng.standard_normal((len(run.states), 3))
    frames[rng.random(len(frames)) < 0.05] = np.nan  # lost
    held = np.flatnonzero(rng.random(len(frames)) < 0.05)
    frames[held[held > 0]] = frames[held[held > 0] - 1]  # held by the tracker
    reference = [rows_for(run.states, t) for t in range(len(frames))]
    torch_u, graph_u = [], []
    for frame, wanted in zip(frames, reference):
        torch_u.append(looped(frame, wanted))
        u, holding = graph(frame, wanted)
        graph_u.append(u)
        assert holding == looped.holding
    assert np.abs(np.array(torch_u) - np.array(graph_u)).max() <= 1e-5


class DelayedRod:
    """The simulated rod as a plant: inputs act DELAY periods after ``send``, ``read`` films the tip."""

    def __init__(self, seed: int = 0):
        self.sim = Simulator(SIM_ROBOT, gravity="vertical")
        self.q, self.qd = self.sim.rest_q()[None], np.zeros((1, self.sim.nq))
        self.queue, self.rng, self.tips = [np.zeros(2)] * DELAY, np.random.default_rng(seed), []

    def read(self):
        tip = self.sim.tip_positions(self.q)[0]
        self.tips.append(tip)
        return tip + 5e-5 * self.rng.standard_normal(3)

    def send(self, u):
        self.queue.append(np.asarray(u, float))
        q, qd = self.sim.integrate(self.queue.pop(0)[None, None], self.q, self.qd)
        self.q, self.qd = q[:, -1], qd[:, -1]


def test_the_exported_loop_drives_a_delayed_rod_from_the_cli_graph(trained, tmp_path, capsys):
    runs, data, _ = trained
    path = tmp_path / "loop.onnx"
    with contextlib.redirect_stdout(io.StringIO()) as out:
        cli.main(
            ["export", "mlp", "--profile", "ci", "--recordings", str(runs), "--delay", "0.06", "--causal", "--loop"]
            + ["--onnx", str(path)]
        )
    assert "delay 6 periods" in out.getvalue()
    with pytest.raises(SystemExit) as stop:
        cli.main(
            ["export", "mlp", "--profile", "ci", "--recordings", str(runs), "--delay", "0.06", "--causal", "--loop"]
            + ["--onnx", str(tmp_path / "anchored.onnx"), "--rest", str(TRUNK_REST)]
        )
    assert stop.value.code == 2 and "holds no rest run" in capsys.readouterr().err
    meta = {p.key: p.value for p in onnx.load(path).metadata_props}
    assert json.loads(meta["input_columns"]) == ["u1", "u2"] and json.loads(meta["delay_steps"]) == DELAY
    assert json.loads(meta["input_units"]) == [None, None]  # u1, u2 declare none; l1_mm would be "mm"
    assert [recordings.column_unit(c) for c in ("l1_mm", "u1_N", "u_1", "x")] == ["mm", "N", None, None]
    assert json.loads(meta["safe_input"]) == pytest.approx(np.median(data.u[data.train].reshape(-1, 2), 0), abs=1e-6)
    runner = example()
    graph = runner.LoopGraph(path)
    reference = recordings.read(runs / "run0.csv", delay=0.06).states[:200]  # a recorded path, from rest
    plant = DelayedRod()
    u, holding, late = runner.run(graph, plant, reference, paced=False)
    low, high, rate = (np.array(json.loads(meta[k])) for k in ("input_low", "input_high", "input_rate"))
    assert u.shape == (199, 2) and late == 0 and not holding[1:].any()
    assert ((u >= low - 1e-6) & (u <= high + 1e-6)).all() and (np.abs(np.diff(u, axis=0)) <= rate + 1e-6).all()
    assert np.isfinite(plant.tips).all()


TRUNK_REST = Path(__file__).parents[1] / "datasets" / "asl_trunk" / "rest.csv.gz"
TRUNK_TIP = ["x3_m", "y3_m", "z3_m"]


def test_a_new_session_is_anchored_by_its_rest_run_to_the_recordings(tmp_path):
    """The trunk's rest run, and the same run as a later session would film it: the rest pose
    moved 12 mm, 5 mm and 30 mm; the offset is the move back, to the file's 1 um rounding."""
    moved = tmp_path / "rest_today.csv"
    frame = pd.read_csv(TRUNK_REST)
    shift = np.array([0.012, -0.005, 0.030])
    for column, delta in zip(TRUNK_TIP, shift):
        frame[column] = (frame[column] + delta).round(6)
    frame.to_csv(moved, index=False)
    np.testing.assert_allclose(recordings.rest_offset(moved, TRUNK_REST, tip=TRUNK_TIP), -shift, atol=1e-6)
    with pytest.raises(ValueError, match="its inputs change; a rest run holds every input constant"):
        recordings.rest_offset(TRUNK_REST.with_name("random_1.csv.gz"), TRUNK_REST, tip=TRUNK_TIP)


def test_an_anchored_loop_sees_todays_frames_as_the_recordings(rig):
    _, data, _ = rig
    run = recordings.read(rig[0] / "run1.csv", delay=0.06)
    shift = np.array([0.01, -0.02, 0.005])
    plain, anchored = untrained_loop(data), untrained_loop(data, anchor=-shift)
    for t in range(60):
        wanted = rows_for(run.states, t)
        np.testing.assert_allclose(
            anchored(run.states[t, :3] + shift, wanted), plain(run.states[t, :3], wanted), atol=1e-6
        )
    with pytest.raises(ValueError, match="anchor must be 3 finite offsets in m"):
        untrained_loop(data, anchor=[0.0, 0.0])
