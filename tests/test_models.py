"""Inverse models, the shared training loop and open-loop control."""

import dataclasses
import warnings

import numpy as np
import pytest
import torch
from small_runs import QUICK, SMALL

from softflow import control, data, models, training
from softflow.models import checkpoints
from softflow.models.baselines import InverseMLP
from softflow.models.common import Normalizer
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT, U_MAX


def test_normalizer_round_trip_and_constant_channel_guard():
    x = torch.tensor([[1.0, 5.0], [3.0, 5.0], [5.0, 5.0]])
    norm = Normalizer(2)
    norm.fit(x)
    assert torch.allclose(norm.unnormalize(norm.normalize(x)), x)
    assert torch.isfinite(norm.normalize(x)).all()  # the constant channel does not divide by zero


def test_windows_repeat_the_rest_state_before_the_start():
    states = np.arange(2 * 5 * 6, dtype=float).reshape(2, 5, 6)
    window = data.gather_windows(states, [1], [1], context=3)[0]
    np.testing.assert_array_equal(window, states[1, [0, 0, 1, 2]])


@pytest.mark.parametrize("name", ["mlp", "lstm", "transformer"])
def test_training_beats_the_mean_on_held_out_episodes(name, dataset, trained):
    model, checkpoint = trained(name)
    window, u, _ = training.Sampler(dataset, dataset.test, model.context, np.random.default_rng(0)).fixed(3000, 0)
    with torch.no_grad():
        held_out_mse = torch.mean((model.predict(window) - u) ** 2).item()
    variance = torch.var(u, dim=0).sum().item() / 2
    assert held_out_mse < 0.5 * variance  # explains more than half of the held-out variance
    assert checkpoint["wall_seconds"] > 0 and len(checkpoint["history"]) == checkpoint["epochs_run"]


def test_an_interrupted_run_resumes_to_the_same_weights(dataset, tmp_path, monkeypatch):
    reference, _ = training.train("mlp", dataset, QUICK, tmp_path / "straight.pt", progress=False)
    calls = {"n": 0}
    real_loss = InverseMLP.compute_loss

    def interrupt_in_epoch_two(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == QUICK.steps_per_epoch + 10:
            raise KeyboardInterrupt
        return real_loss(self, *args, **kwargs)

    monkeypatch.setattr(InverseMLP, "compute_loss", interrupt_in_epoch_two)
    with pytest.raises(KeyboardInterrupt):
        training.train("mlp", dataset, QUICK, tmp_path / "resumed.pt", progress=False)
    assert (tmp_path / "resumed.pt.latest").exists() and not (tmp_path / "resumed.pt").exists()
    monkeypatch.setattr(InverseMLP, "compute_loss", real_loss)
    resumed, _ = training.train("mlp", dataset, QUICK, tmp_path / "resumed.pt", progress=False)
    for a, b in zip(reference.state_dict().values(), resumed.state_dict().values()):
        torch.testing.assert_close(a, b)


def test_a_changed_default_retrains_instead_of_reusing_the_checkpoint(dataset, tmp_path, monkeypatch):
    """The checkpoint records every constructor argument, registry and class defaults
    included, so a new default cannot silently reuse weights trained with the old one."""
    path = tmp_path / "mlp.pt"
    _, first = training.train("mlp", dataset, QUICK, path, progress=False)
    assert first["model_kwargs"] == {"hidden": 256, "layers": 3}
    stamp = path.stat().st_mtime_ns
    training.train("mlp", dataset, QUICK, path, progress=False)
    assert path.stat().st_mtime_ns == stamp  # same arguments: reused
    monkeypatch.setitem(models.MODELS, "mlp", models.ModelSpec(InverseMLP, "MLP", {"hidden": 32}))
    model, second = training.train("mlp", dataset, QUICK, path, progress=False)
    assert second["model_kwargs"] == {"hidden": 32, "layers": 3} and model.net[0].out_features == 32


def test_a_size_variant_trains_beside_the_default_model(dataset, tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path)
    profile = dataclasses.replace(SMALL, train=QUICK)
    _, variant = training.ensure_trained("mlp", profile, dataset, model_kwargs={"hidden": 32})
    assert (tmp_path / "small" / "variants" / "mlp-hidden32.pt").exists() and variant["model_kwargs"]["hidden"] == 32
    assert checkpoints.checkpoint_path("mlp", "small", model_kwargs={"hidden": 256}) == tmp_path / "small" / "mlp.pt"


def test_unknown_model_arguments_are_a_value_error():
    with pytest.raises(ValueError, match="bad arguments for model 'rf'"):
        models.build_model("rf", width=3)


def test_a_corrupt_checkpoint_is_reported_by_path(tmp_path):
    path = tmp_path / "mlp.pt"
    path.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match=str(path)):
        checkpoints.load_checkpoint(path)


def test_missing_controller_names_the_command_that_trains_it(tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path)
    with pytest.raises(ValueError, match="python -m softflow train --profile ci --robot sim --gravity vertical mlp"):
        control.load_controller("mlp", profile="ci")
    with pytest.raises(ValueError, match="profile must be one of"):
        control.load_controller("mlp", profile="nonexistent")


def test_plan_shapes_and_batching(dataset, trained):
    model, _ = trained("lstm")
    controller = control.Controller(model, "lstm")
    reference = dataset.states[0]
    single = controller.plan(reference)
    batched = controller.plan(np.stack([reference, dataset.states[1]]))
    assert single.shape == (reference.shape[0] - 1, 2) and batched.shape == (2,) + single.shape
    np.testing.assert_allclose(batched[0], single, atol=1e-5)
    with pytest.raises(ValueError, match="finite"):
        controller.plan(np.full((5, 6), np.nan))


class _Oracle:
    """Returns the true actuation of an actuated reference."""

    name = "oracle"

    def __init__(self, references):
        self.u = {r.states.tobytes(): r.u_true for r in references}

    def plan(self, reference):
        return self.u[np.asarray(reference).tobytes()]


def test_evaluate_scores_a_perfect_plan_as_perfect():
    sim = Simulator(SIM_ROBOT)
    references = data.random_references(sim, n=2, seconds=2.0)
    results, runs = control.evaluate(_Oracle(references), references, sim)
    assert results.rmse_mm.max() < 1e-6
    assert results.mae_u1.max() == 0 and abs(results.phase_lag_s).max() < 1e-3
    np.testing.assert_allclose(results.input_energy, [np.sum(r.u_true**2) * DT for r in references])


def test_evaluate_many_runs_one_flow_at_several_step_counts_as_separate_runs_would(dataset, trained):
    sim = Simulator(SIM_ROBOT)
    references = data.random_references(sim, n=2, seconds=1.0)
    flow = trained("rf")[0]
    variants = [control.Controller(flow, f"rf N={n}") for n in (1, 4)]
    together, _ = control.evaluate_many(
        variants, references, sim, options_of={"rf N=1": dict(steps=1), "rf N=4": dict(steps=4)}
    )
    for controller, n in zip(variants, (1, 4)):
        alone, _ = control.evaluate(controller, references, sim, steps=n)
        np.testing.assert_allclose(together[together.model == controller.name].rmse_mm, alone.rmse_mm, rtol=1e-12)
    assert together.groupby("model").rmse_mm.mean().nunique() == 2  # the step count matters
    with pytest.raises(ValueError, match=r"options_of names controllers that are not evaluated: \['rf N=2'\]"):
        control.evaluate_many(variants, references, sim, options_of={"rf N=2": dict(steps=2)})


def test_plan_refuses_references_outside_the_training_workspace(dataset, trained):
    controller = control.Controller(trained("mlp")[0], "mlp")
    reference = dataset.states[0]
    with pytest.raises(
        ValueError,
        match=r"reference tip position x = 400 m at index \(0, 0\) is \d+ training "
        r"standard deviations .* is it in metres",
    ):
        controller.plan(reference * 1e3)  # millimetres
    with pytest.raises(ValueError, match="at least one trajectory"):
        controller.plan(np.zeros((0, 5, 6)))


def test_plan_options_must_fit_the_model(dataset, trained):
    regression, flow = control.Controller(trained("mlp")[0], "mlp"), control.Controller(trained("rf")[0], "rf")
    reference = dataset.states[0]
    with pytest.raises(ValueError, match="mlp is a regression model: it takes no noise or step options"):
        regression.plan(reference, noise="seeded")
    with pytest.raises(ValueError, match=r"options \['steps'\]"):
        regression.plan(reference, steps=4)
    with pytest.raises(ValueError, match="it has no noise to sample"):
        regression.sample(reference, 3)
    with pytest.raises(ValueError, match="steps must be a positive integer; got 0"):
        flow.plan(reference, steps=0)
    with pytest.raises(ValueError, match=r"unknown plan options \['step'\]"):
        flow.plan(reference, step=4)


def test_a_plan_beyond_the_actuator_range_is_clipped_with_a_counted_warning(dataset, trained):
    import copy

    model = copy.deepcopy(trained("mlp")[0])
    with torch.no_grad():
        model.action_norm.std.mul_(10)  # a model that asks for ten times the actuation
    controller = control.Controller(model, "mlp")
    reference = dataset.states[0, :20]
    with pytest.warns(control.SaturationWarning, match=r"mlp: \d+ of 38 planned u values exceed the actuator range"):
        u = controller.plan(reference)
    assert np.abs(u).max() == U_MAX
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plans, _ = control.plan_all(controller, [data.Reference("jump", "shape", reference, np.ones(20, bool))])
    np.testing.assert_array_equal(plans[0], u)  # evaluations clip silently: saturation is what they measure


@pytest.mark.parametrize(
    "name", ["mlp", "mlp-physical", "rf", "rf-physical", "rf-fwd", "rf-1", "rf-fwd-1", "rf-physical-1"]
)
def test_step_gives_the_planned_u_of_each_transition(name, dataset, trained):
    controller = control.Controller(trained(name)[0], name)
    states = dataset.states[dataset.test[0], :60]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", control.SaturationWarning)
        planned = controller.plan(states)
        stepped = controller.step(states[:-1], states[1:])  # a batch of transitions
        single = controller.step(states[10], states[11])  # one transition
    tolerance = 1e-3 if controller.model.needs_statics else 1e-5  # step's prior: the grid, 1e-3 N of plan's table
    np.testing.assert_allclose(stepped, planned, atol=tolerance)
    assert single.shape == (2,)
    np.testing.assert_allclose(single, planned[10], atol=tolerance)


@pytest.mark.parametrize("name", ["rf", "rf-physical", "rf-1", "rf-physical-1"])
def test_step_draws_are_the_flows_samples_from_the_same_noise(name, dataset, trained):
    controller = control.Controller(trained(name)[0], name)
    states = dataset.states[dataset.test[0], 30:33]  # two transitions
    draws = controller.sample_step(states[:-1], states[1:], 16, seed=3)  # (16, 2, m)
    noise = np.random.default_rng(3).standard_normal((32, 2))  # the draws' z, draw-major
    window = torch.as_tensor(np.tile(np.stack([states[:-1], states[1:]], 1), (16, 1, 1)), dtype=torch.float32)
    extras = controller.model.extras(window.numpy().astype(np.float64), controller.statics)  # {prior: (32, 1, m)}
    extras = {k: torch.as_tensor(v[:, 0], dtype=torch.float32) for k, v in extras.items()}
    with torch.inference_mode():
        expected = controller.model.predict(window, **extras, noise=torch.as_tensor(noise, dtype=torch.float32))
    tolerance = 1e-3 if controller.model.needs_statics else 1e-5  # the grid's prior against the table's
    np.testing.assert_allclose(draws.reshape(32, 2), expected.numpy(), atol=tolerance)
    assert draws.std(0).min() > 1e-3  # 16 draws, not one: the flow is uncertain about each input
    one = controller.sample_step(states[0], states[1], 16, seed=3)
    assert one.shape == (16, 2)
    draw = lambda: controller.sample_step(states[0], states[1], 4)  # noqa: E731
    assert not np.array_equal(draw(), draw())  # the controller's generator: fresh draws at each call


def test_step_checks_its_input_and_needs_a_per_step_model(dataset, trained):
    controller = control.Controller(trained("mlp")[0], "mlp")
    with pytest.raises(ValueError, match=r"x_next must have shape \(6\)"):
        controller.step(np.zeros(6), np.zeros(5))
    with pytest.raises(ValueError, match="x_t must be finite"):
        controller.step(np.full(6, np.nan), np.zeros(6))
    rest = dataset.states[0, 0]
    for bad in (np.nan, np.inf):  # in a velocity, which the workspace check does not bound
        with pytest.raises(ValueError, match="x_next must be finite"):
            controller.step(rest, np.concatenate([rest[:3], [bad, 0.0, 0.0]]))
        with pytest.raises(ValueError, match="x_next must be finite"):
            control.Controller(controller.model, "mlp", workspace_margin=None).step(rest, np.full(6, bad))
    with pytest.raises(ValueError, match="lstm reads a window of 10 past transitions"):
        control.Controller(trained("lstm")[0], "lstm").step(np.zeros(6), np.zeros(6))


def test_mlp_physical_regresses_the_residual_around_the_static_prior(dataset, trained):
    """The prior without the flow: held-out u from the prior plus the learned residual is far
    closer than the quasi-static prior alone, and a zeroed network returns the prior plus
    the residual's mean."""
    import copy

    model, _ = trained("mlp-physical")
    controller = control.Controller(model, "mlp-physical")
    episode = dataset.test[0]
    states, u_true = dataset.states[episode], dataset.u[episode]
    prior = controller.statics.inverse(states[1:, :3])
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", control.SaturationWarning)
        assert rms(controller.plan(states) - u_true) < 0.5 * rms(prior - u_true)
        silent = copy.deepcopy(model)
        with torch.no_grad():
            silent.net[-1].weight.zero_()
            silent.net[-1].bias.zero_()
        u = control.Controller(silent, "silent").plan(states)
    np.testing.assert_allclose(u, np.clip(prior + silent.residual_norm.mean.numpy(), -U_MAX, U_MAX), atol=1e-5)
