"""The RF family: generative transport, the static prior, the consistency loss, sampling."""

import dataclasses
import warnings

import numpy as np
import pytest
import torch
from small_runs import QUICK, SMALL

from softflow import control, data, training
from softflow.models import checkpoints
from softflow.models.baselines import InverseMLP
from softflow.models.common import one_thread
from softflow.models.flow import MeanFlow, RectifiedFlow
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT, U_MAX


def fit(model, window, u, steps=1500):
    model.set_normalizer(window, u[None])
    optimizer = torch.optim.Adam(model.parameters(), lr=2e-3)
    for _ in range(steps):
        loss = model.compute_loss(window, u)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return model


def test_rf_keeps_both_modes_where_regression_averages_them():
    """Two actuations realise the same transition (u = +-1): the flow samples both,
    the MSE regression predicts their mean, which realises neither."""
    torch.manual_seed(0)
    window = torch.randn(512, 2, 6).repeat(2, 1, 1)
    u = torch.cat([torch.ones(512, 2), -torch.ones(512, 2)])
    with one_thread():
        flow = fit(RectifiedFlow(hidden=64, layers=2, steps=8), window, u)
        regression = fit(InverseMLP(hidden=64, layers=2), window, u)
    with torch.no_grad():
        sampled = flow.predict(window[:512])
        averaged = regression.predict(window[:512])
    assert averaged.abs().mean() < 0.2
    assert (sampled.abs() > 0.7).float().mean() > 0.9  # near +-1, not at the mean 0
    assert 0.3 < (sampled[:, 0] > 0).float().mean() < 0.7  # both modes, in proportion
    with torch.no_grad():
        one_euler_step = flow.predict(window[:512], steps=1)  # z + v(z, 0) = z + E[xi] - z: the mean
    assert one_euler_step.abs().mean() < 0.3  # the regression's answer, as the theory says


def test_a_one_step_flow_keeps_both_modes_in_one_call():
    """MeanFlow learns the average velocity over the whole path: one call from z lands on a
    mode, the same one its own 16 small steps reach from the same z."""
    torch.manual_seed(0)
    window = torch.randn(512, 2, 6).repeat(2, 1, 1)
    u = torch.cat([torch.ones(512, 2), -torch.ones(512, 2)])
    with one_thread():
        flow = fit(MeanFlow(hidden=64, layers=2, steps=1), window, u, steps=600)
    z = torch.randn(512, 2)
    with torch.no_grad():
        one, many = flow.predict(window[:512], noise=z), flow.predict(window[:512], noise=z, steps=16)
    assert (one.abs() > 0.7).float().mean() > 0.7  # measured 0.81: near +-1, not at the mean 0
    assert 0.3 < (one[:, 0] > 0).float().mean() < 0.7  # both modes, in proportion
    assert ((one > 0) == (many > 0)).float().mean() > 0.9  # measured 0.99: the span's average is the flow's


def test_rf_learns_held_out_transitions(dataset, trained):
    model, _ = trained("rf")
    window, u, _ = training.Sampler(dataset, dataset.test, 1, np.random.default_rng(0)).fixed(3000, 0)
    with torch.no_grad():
        mse = torch.mean((model.predict(window, noise=torch.zeros(len(window), 2)) - u) ** 2).item()
    assert mse < 0.5 * torch.var(u, dim=0).mean().item()


def test_rf_fwd_needs_its_trained_forward_surrogate_and_keeps_it_frozen(dataset, trained, tmp_path):
    with pytest.raises(ValueError, match=r"requires trained \['forward'\]"):
        training.train("rf-fwd", dataset, QUICK, tmp_path / "rf-fwd.pt", progress=False)
    model, _ = trained("rf-fwd")
    surrogate, _ = trained("forward")
    for a, b in zip(model.forward_model.state_dict().values(), surrogate.state_dict().values()):
        torch.testing.assert_close(a, b)  # unchanged by the RF-FWD training
    window, u, _ = training.Sampler(dataset, dataset.test, 1, np.random.default_rng(0)).fixed(2000, 0)
    with torch.no_grad():
        predicted = surrogate.predict_next(window[:, 0], u)
    step = window[:, 1] - window[:, 0]
    assert torch.mean((predicted - window[:, 1]) ** 2) < 0.5 * torch.mean(step**2)  # beats "no change" by 2x


@pytest.fixture(scope="module")
def table():
    return Simulator(SIM_ROBOT, gravity="vertical").static_table()


def test_static_table_inverse_matches_inverse_statics(table):
    sim = Simulator(SIM_ROBOT, gravity="vertical")
    u = np.random.default_rng(0).uniform(-4, 4, (20, 2))
    p = sim.static_tip(u)
    np.testing.assert_allclose(table.inverse(p), u, atol=1e-3)
    off_surface = p + np.random.default_rng(1).normal(0, 0.01, p.shape)  # dynamic states are off the surface
    np.testing.assert_allclose(table.inverse(off_surface), sim.inverse_static(off_surface), atol=1e-3)


def test_rf_physical_adds_its_prior(table):
    model = RectifiedFlow(prior=True)
    states = np.zeros((1, 3, 6))
    states[0, :, 0] = 0.4
    states[0, 2, 1] = 0.05
    prior = model.extras(states, table)["prior"]
    assert prior.shape == (1, 2, 2)
    np.testing.assert_allclose(prior[0, 1], table.inverse(states[0, 2, :3]), atol=1e-9)
    with pytest.raises(ValueError, match="static table"):
        model.extras(states)


def test_plans_are_reproducible_and_noise_can_be_fresh(dataset, trained):
    model, _ = trained("rf")
    controller = control.Controller(model, "rf", seed=3)
    reference = dataset.states[0]
    seeded = controller.plan(reference, noise="seeded")
    np.testing.assert_array_equal(seeded, controller.plan(reference, noise="seeded"))
    assert not np.allclose(seeded, controller.plan(reference, noise="seeded", seed=4))
    assert not np.allclose(seeded, controller.plan(reference, noise="fresh"))
    window = torch.as_tensor(
        data.gather_windows(reference[None], np.zeros(5, int), np.arange(5), 1), dtype=torch.float32
    )
    with torch.no_grad():
        centre = model.predict(window, noise=torch.zeros(5, 2)).numpy()
    np.testing.assert_allclose(controller.plan(reference)[:5], centre, atol=1e-6)  # z = 0 by default
    with pytest.raises(ValueError, match="noise"):
        controller.plan(reference, noise="none")


def test_samples_are_independent_draws_and_their_mean_is_a_plan(dataset, trained):
    model, _ = trained("rf")
    controller = control.Controller(model, "rf", seed=3)
    references = dataset.states[:2]
    samples = controller.sample(references, 5)
    assert samples.shape == (5, 2, references.shape[1] - 1, 2)
    assert samples.std(0).min() > 0  # every step differs between draws
    np.testing.assert_array_equal(controller.sample(references[0], 5), controller.sample(references[:1], 5)[:, 0])
    np.testing.assert_allclose(controller.plan(references, noise="seeded", n_samples=5), samples.mean(0))
    with pytest.raises(ValueError, match="positive integer"):
        controller.sample(references, 0)
    with pytest.raises(ValueError, match="n_samples"):
        controller.plan(references, n_samples=3)


def test_ensure_trained_uses_each_models_budget_and_reuses_the_checkpoint(dataset, tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path)
    longer = dataclasses.replace(QUICK, epochs=4)
    profile = dataclasses.replace(SMALL, train=QUICK, per_step_train=longer)
    _, checkpoint = training.ensure_trained("rf", profile, dataset)
    assert checkpoint["train_config"] == dataclasses.asdict(longer)  # a per-step model gets the longer budget
    assert checkpoints.checkpoint_path("rf", profile.name) == tmp_path / "small" / "rf.pt"
    stamp = (tmp_path / "small" / "rf.pt").stat().st_mtime_ns
    training.ensure_trained("rf", profile, dataset)
    assert (tmp_path / "small" / "rf.pt").stat().st_mtime_ns == stamp  # reused, not retrained


def test_rf_physical_plans_its_prior_plus_a_learned_residual(dataset, trained, table, monkeypatch):
    import copy

    from softflow.rod import statics

    model, _ = trained("rf-physical")
    controller = control.Controller(model, "rf-physical")  # the dataset's rod: simulation, vertical

    def no_second_table(*args, **kwargs):
        raise AssertionError("a plan built another static table")

    monkeypatch.setattr(statics.StaticTable, "__init__", no_second_table)  # built once, by the controller
    episode = dataset.test[0]
    states, u_true = dataset.states[episode], dataset.u[episode]
    prior = table.inverse(states[1:, :3])
    planned = controller.plan(states)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    assert rms(planned - u_true) < 0.5 * rms(prior - u_true)  # the residual corrects the quasi-static prior
    silent = copy.deepcopy(model)
    with torch.no_grad():
        silent.net[-1].weight.zero_()
        silent.net[-1].bias.zero_()  # no velocity: the flow stays at z = 0, the residual at its mean
    silent_controller = copy.copy(controller)
    silent_controller.model = silent
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", control.SaturationWarning)  # the prior alone exceeds 4 N at times
        silent_plan = silent_controller.plan(states)
    expected = np.clip(prior + silent.residual_norm.mean.numpy(), -U_MAX, U_MAX)
    np.testing.assert_allclose(silent_plan, expected, atol=1e-5)


@pytest.mark.parametrize("flow", [RectifiedFlow, MeanFlow])
def test_one_euler_step_from_tau_is_the_one_step_endpoint_estimate(flow):
    """The sampler (its first layer split: the condition's share once, the time's a constant) and
    RF-FWD's consistency term (the whole network on the joined inputs) share one flow: a single
    step from tau to 1 is xi_tau + (1 - tau) v, and predict is the integration from noise at 0."""
    torch.manual_seed(0)
    model = flow(hidden=32, layers=2).eval()
    window = torch.randn(16, 2, 6)
    condition, xi = model.condition(window), torch.randn(16, 2)
    with torch.no_grad():
        for tau in (0.0, 0.3, 0.9):
            taus = torch.full((16,), tau)
            np.testing.assert_allclose(
                model.integrate(xi, condition, 1, start=tau), model.endpoint(xi, taus, condition), atol=1e-6
            )
        u = model.predict(window, noise=xi, steps=3)
        np.testing.assert_array_equal(u, model.target_norm().unnormalize(model.integrate(xi, condition, 3)))
