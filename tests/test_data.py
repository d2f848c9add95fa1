"""Excitation, dataset cache and reference data."""

import inspect

import numpy as np
import pytest

from softflow import data
from softflow.data import dataset as dataset_module
from softflow.profiles import Profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT, SIM_ROBOT, U_MAX

TINY = Profile("tiny", n_episodes=6, episode_seconds=0.3)


def assert_same_states(actual, expected):
    """Equal up to the last bits that batched BLAS orders differently for another batch size;
    velocities are central differences (relative accuracy about 1e-7)."""
    np.testing.assert_allclose(actual[..., :3], expected[..., :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(actual[..., 3:], expected[..., 3:], rtol=0, atol=1e-6)


@pytest.fixture(scope="module")
def sim():
    return Simulator(SIM_ROBOT)


def test_polynomial_excitation_stays_in_bounds_and_spans_the_range():
    u = data.polynomial_excitation(500, 500, np.random.default_rng(0))
    assert u.shape == (500, 500, 2)
    assert np.abs(u).max() <= U_MAX
    peaks = np.abs(u).max(1)
    assert peaks.min() >= 0.5 - 1e-12 and peaks.max() > 3.9


def test_dataset_states_are_the_rollout_of_the_stored_u(tmp_path, sim):
    D = data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    assert_same_states(D.states[:3], sim.rollout(D.u[:3]))
    assert sorted(np.concatenate([D.train, D.val, D.test])) == list(range(TINY.n_episodes))


def test_transitions_are_views(tmp_path):
    D = data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    x, x_next, u = D.transitions(slice(0, 4))
    assert all(np.shares_memory(a, b) for a, b in ((x, D.states), (x_next, D.states), (u, D.u)))
    np.testing.assert_array_equal(x[:, 1:], x_next[:, :-1])


def test_cache_is_reused_and_a_corrupt_file_is_rebuilt(tmp_path, monkeypatch):
    first = data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    [path] = tmp_path.glob("dataset-*.npz")

    def no_simulation(*args, **kwargs):
        raise AssertionError("cached data was regenerated")

    with monkeypatch.context() as patch:
        patch.setattr(Simulator, "rollout", no_simulation)
        np.testing.assert_array_equal(data.load_dataset(TINY, data_dir=tmp_path).states, first.states)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])  # truncated, as by a crash
    np.testing.assert_array_equal(data.load_dataset(TINY, data_dir=tmp_path, progress=False).states, first.states)


def test_an_interrupted_generation_resumes_from_its_finished_blocks(tmp_path, monkeypatch):
    monkeypatch.setattr(dataset_module, "BLOCK_EPISODES", 2)
    calls = []
    real_rollout = Simulator.rollout

    def crash_on_second_block(self, u, **kwargs):
        calls.append(len(u))
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_rollout(self, u, **kwargs)

    monkeypatch.setattr(Simulator, "rollout", crash_on_second_block)
    with pytest.raises(KeyboardInterrupt):
        data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    assert not list(tmp_path.glob("dataset-*.npz"))  # nothing half-written is visible
    monkeypatch.setattr(Simulator, "rollout", real_rollout)
    calls.clear()
    monkeypatch.setattr(Simulator, "rollout", lambda self, u, **kw: calls.append(len(u)) or real_rollout(self, u))
    D = data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    assert calls == [2, 2]  # the first block was not simulated again
    assert_same_states(D.states, Simulator(SIM_ROBOT).rollout(D.u))


@pytest.fixture(scope="module")
def circle(sim):
    return data.shape_reference(sim, "circle")


def test_reference_velocity_is_the_time_derivative_of_its_positions(sim, circle):
    X = circle.states
    central = (X[2:, :3] - X[:-2, :3]) / (2 * DT)
    np.testing.assert_allclose(central, X[1:-1, 3:], atol=2e-4)  # O(dt^2) of a 0.15 m/s circle


@pytest.mark.parametrize("name", ["heart", "char_M"])
def test_reference_x_velocity_follows_the_static_workspace(sim, name):
    """v = dp/d(y, z) (v_y, v_z): check the chain rule against a difference of the lift."""
    X = data.shape_reference(sim, name).states[::25]
    step = 1e-4 / np.abs(X[:, 4:]).max()
    plus, _, _ = sim.static_lift(X[:, 1:3] + step * X[:, 4:])
    minus, _, _ = sim.static_lift(X[:, 1:3] - step * X[:, 4:])
    np.testing.assert_allclose((plus[:, 0] - minus[:, 0]) / (2 * step), X[:, 3], atol=1e-6)
    np.testing.assert_allclose(plus[:, 1:], X[:, 1:3] + step * X[:, 4:], atol=1e-9)


def test_mask_covers_exactly_the_path_after_the_approach(sim, circle):
    n_approach = int(round(data.APPROACH_SECONDS / DT))
    assert not circle.mask[:n_approach].any() and circle.mask[n_approach:].all()
    np.testing.assert_allclose(circle.states[0, :3], sim.tip_positions(sim.rest_q()[None])[0], atol=1e-9)
    np.testing.assert_allclose(circle.states[n_approach, 1:3], [data.SIZE, 0.0], atol=1e-6)
    np.testing.assert_allclose(circle.states[0, 3:], 0.0, atol=1e-12)  # starts at rest


def test_a_path_outside_the_workspace_raises(sim):
    with pytest.raises(ValueError, match="workspace"):  # fast: every sample of the path is lifted first
        data.shape_reference(sim, "circle", size=0.35, speed=1.5)


def test_actuated_references_keep_their_true_input(sim):
    [reference] = data.random_references(sim, n=1, seconds=0.5)
    assert_same_states(reference.states, sim.rollout(reference.u_true[None])[0])
    assert reference.mask.all()


def test_burst_circle_period_falls_from_5_to_1_2_s(sim):
    """The paper's law (defaults: 5.0 -> 1.2 s over 12 s), checked on a 2 s burst: the same
    lift of every sample at a sixth of the cost."""
    defaults = inspect.signature(data.burst_circle_reference).parameters
    assert (defaults["periods"].default, defaults["duration"].default) == ((5.0, 1.2), 12.0)
    reference = data.burst_circle_reference(sim, duration=2.0)
    path = reference.states[reference.mask]
    angular_rate = np.linalg.norm(path[:, 4:], axis=1) / 0.15
    np.testing.assert_allclose(2 * np.pi / angular_rate[[0, -1]], [5.0, 1.2], rtol=1e-3)


def test_coverage_is_high_in_distribution_and_zero_far_away(tmp_path):
    D = data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    train, held_out = D.states[:4], D.states[4:]
    assert data.coverage(train, held_out, held_out) >= 0.97  # 0.99 up to the quantile of 62 points
    assert data.coverage(train, held_out + 10.0, held_out) == 0.0


def test_unknown_shape_is_rejected(sim):
    with pytest.raises(ValueError, match="shape must be one of"):
        data.shape_reference(sim, "hexagon")


def test_a_subset_trains_on_fewer_episodes_and_is_judged_on_the_same_ones(dataset):
    small = data.subset(dataset, 10)
    assert list(small.train) == list(dataset.train[:8])
    assert np.array_equal(small.val, dataset.val) and np.array_equal(small.test, dataset.test)
    assert small.key != dataset.key and small.states is dataset.states
    with pytest.raises(ValueError, match="n_episodes"):
        data.subset(dataset, 1000)


def test_hardware_burst_speeds_up_to_a_0_2_s_period_about_the_rest_tip():
    """Table III's burst (defaults: 5.0 -> 0.2 s at the paper's slope), checked on a 2 s burst."""
    defaults = inspect.signature(data.hardware_burst_reference).parameters
    assert defaults["periods"].default == (5.0, 0.2) and defaults["duration"].default == pytest.approx(12.0 * 4.8 / 3.8)
    hw = Simulator(HW_ROBOT)
    reference = data.hardware_burst_reference(hw, duration=2.0)
    path = reference.states[reference.mask]
    rest_tip = hw.tip_positions(hw.rest_q()[None])[0, 1:]
    radius = np.linalg.norm(path[:, 1:3] - rest_tip, axis=1)
    np.testing.assert_allclose(radius, data.HARDWARE_BURST_RADIUS, rtol=1e-9)
    angular_rate = np.linalg.norm(path[:, 4:], axis=1) / data.HARDWARE_BURST_RADIUS
    np.testing.assert_allclose(2 * np.pi / angular_rate[[0, -1]], [5.0, 0.2], rtol=5e-3)  # to the sample
