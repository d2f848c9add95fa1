"""Dataset variants: what a model is shown of the tip (hidden channels, finite differences,
noise), how the rod is driven, and that the folded variant's premise holds in the statics."""

import numpy as np
import pytest

from softflow import control
from softflow.data import variants
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT


@pytest.fixture(scope="module")
def states():
    t = np.arange(101) * DT
    p = np.stack([0.4 - 0.01 * t, 0.1 * np.sin(2 * t), 0.05 * t**2], -1)
    v = np.stack([-0.01 + 0 * t, 0.2 * np.cos(2 * t), 0.1 * t], -1)
    return np.concatenate([p, v], -1)[None]  # (1, 101, 6)


def test_observation_hides_channels_and_differences_positions(states):
    seen = variants.VARIANTS["position-only"].observe(states)
    assert np.all(seen[..., 3:] == 0) and np.array_equal(seen[..., :3], states[..., :3])
    folded = variants.VARIANTS["folded"].observe(states)
    assert np.all(folded[..., [0, 3]] == 0) and np.array_equal(folded[..., [1, 2, 4, 5]], states[..., [1, 2, 4, 5]])
    differenced = variants.VARIANTS["finite-difference"].observe(states)
    np.testing.assert_allclose(differenced[0, 1:, 3:], np.diff(states[0, :, :3], axis=0) / DT)
    assert np.all(differenced[0, 0, 3:] == 0)  # from rest
    # backward differences lag the exact velocity by half a sample
    np.testing.assert_allclose(differenced[0, 1:, 4], states[0, 1:, 4], atol=0.2 * 2 * DT)


def test_position_noise_has_its_stated_size_and_only_with_a_generator(states):
    variant = variants.VARIANTS["noise-2mm"]
    np.testing.assert_array_equal(variant.observe(states)[..., :3], states[..., :3])
    many = np.repeat(states, 200, axis=0)
    noisy = variant.observe(many, np.random.default_rng(0))
    assert np.std(noisy[..., :3] - many[..., :3]) == pytest.approx(2e-3, rel=0.02)


def test_piecewise_excitation_holds_levels_within_range():
    u = variants.piecewise_excitation(50, 500, np.random.default_rng(0), u_max=3.0)
    assert u.shape == (50, 500, 2) and np.abs(u).max() <= 3.0
    changes = np.count_nonzero(np.diff(u, axis=1), axis=1)  # per episode and input
    held = 500 / (changes + 1) * DT
    assert held.min() >= 0.05 and 0.15 < held.mean() < 0.4  # uniform(0.05, 0.5) s holds


def test_variant_datasets_share_the_simulation_and_differ_in_key(tmp_path):
    paper = variants.variant_dataset(variants.VARIANTS["paper"], 6, seconds=0.3, data_dir=tmp_path)
    hidden = variants.variant_dataset(variants.VARIANTS["position-only"], 6, seconds=0.3, data_dir=tmp_path)
    assert len(list(tmp_path.glob("variant-*.npz"))) == 1 and paper.key != hidden.key
    np.testing.assert_array_equal(paper.u, hidden.u)
    np.testing.assert_array_equal(hidden.states[..., :3], paper.states[..., :3])
    folded = variants.variant_dataset(variants.VARIANTS["folded"], 6, seconds=0.3, data_dir=tmp_path)
    assert np.linalg.norm(folded.u, axis=-1).max() <= 12.0 + 1e-12 and np.abs(folded.u).max() > 4.0
    weak = variants.VARIANTS["weak-damping"]
    assert weak.robot.damping == pytest.approx(SIM_ROBOT.damping / 10)


def test_the_folded_workspace_reaches_one_lateral_tip_position_with_two_bends():
    """The folded variant's premise: with x hidden, the tip's lateral reach at 4 N comes back
    at a larger tension (the rod bends past its furthest reach)."""
    sim = Simulator(SIM_ROBOT)
    u1 = np.linspace(0.0, 12.0, 121)
    reach = sim.static_tip(np.stack([u1, np.zeros_like(u1)], -1))[:, 1]
    at_4 = reach[40]
    beyond = u1[np.argmax(reach) :][np.argmin(np.abs(reach[np.argmax(reach) :] - at_4))]
    assert 6.0 < u1[np.argmax(reach)] < 8.0 and 8.5 < beyond < 9.5
    assert reach[u1 == beyond][0] == pytest.approx(at_4, abs=2e-3)


def test_a_controller_plans_on_what_its_model_was_shown(trained):
    model, _ = trained("mlp")
    X = Simulator(SIM_ROBOT).rollout(np.full((1, 30, 2), 1.0))[0]
    hidden = variants.VARIANTS["position-only"]
    controller = control.Controller(model, "mlp", observe=hidden.observe)
    faster = X.copy()
    faster[:, 3:] *= 3.0  # velocities the model does not see
    np.testing.assert_array_equal(controller.plan(X), controller.plan(faster))
    np.testing.assert_array_equal(controller.plan(X), control.Controller(model, "mlp").plan(hidden.observe(X)))
    limited = control.Controller(model, "mlp", u_limit=0.5)
    with pytest.warns(control.SaturationWarning, match="0.5 N"):
        assert np.abs(limited.plan(X)).max() <= 0.5
    with pytest.raises(ValueError, match="u_limit"):
        control.Controller(model, "mlp", u_limit=0.0)


def test_a_study_may_plan_beyond_the_workspace_a_user_is_held_to(trained):
    model, _ = trained("mlp")
    far = Simulator(SIM_ROBOT).rollout(np.full((1, 20, 2), 1.0))[0]
    far[:, 0] += 1.0  # a metre off in x: a user's unit mistake, or a study's extrapolation
    with pytest.raises(ValueError, match="training standard deviations"):
        control.Controller(model, "mlp").plan(far)
    assert np.isfinite(control.Controller(model, "mlp", workspace_margin=None).plan(far)).all()
