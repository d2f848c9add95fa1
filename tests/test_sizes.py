"""Nothing assumes the paper's sizes: every model of the registry trains on a synthetic robot
with 3 inputs, a 2-D tip and a 1/12 s period, plans a reference and steps in those sizes."""

import numpy as np
import pytest

from softflow import control, data, training
from softflow.models import checkpoints, model_spec
from softflow.models.specs import CONTROLLERS, build_model
from softflow.profiles import TrainConfig

DT = 1 / 12  # s
B = np.array([[1.0, 0.5, -0.5], [0.0, 1.0, 1.0]])  # 3 inputs drive a 2-D tip: a redundant inverse
QUICK = TrainConfig(epochs=3, steps_per_epoch=60, batch_size=128, warmup_steps=10, val_samples=500, patience=3)


def simulate(u):
    """A damped point mass pushed by B u: u (E, T, 3) -> states (E, T+1, 4), [p, v] from rest."""
    states = np.zeros((u.shape[0], u.shape[1] + 1, 4))
    for t in range(u.shape[1]):
        p, v = states[:, t, :2], states[:, t, 2:]
        v = 0.8 * v + DT * u[:, t] @ B.T
        states[:, t + 1] = np.concatenate([p + DT * v, v], -1)
    return states


@pytest.fixture(scope="module")
def synthetic():
    rng = np.random.default_rng(0)
    phases = rng.uniform(0, 2 * np.pi, (40, 1, 3))
    rates = rng.uniform(0.2, 1.5, (40, 1, 3))
    u = np.sin(2 * np.pi * rates * np.arange(48)[None, :, None] * DT + phases)  # (40, 48, 3)
    train, val, test = data.split_episodes(40, seed=0)
    return data.Dataset(u, simulate(u), train, val, test, key="synthetic", robot=None, gravity=None, dt=DT)


@pytest.fixture(scope="module")
def trained(synthetic, tmp_path_factory):
    folder, models = tmp_path_factory.mktemp("models"), {}

    def get(name):
        if name not in models:
            dependencies = {dep: get(dep)[0] for dep in model_spec(name).requires}
            models[name] = training.train(
                name, synthetic, QUICK, folder / f"{name}.pt", dependencies=dependencies, progress=False
            )
        return models[name]

    return get


def test_the_dataset_declares_its_sizes(synthetic):
    assert (synthetic.dims.inputs, synthetic.dims.position, synthetic.dims.state) == (3, 2, 4)
    assert synthetic.dt == DT


# A model with the static prior needs a simulated rod's static table, which the synthetic robot has none of.
INVERSE = [name for name in CONTROLLERS if not build_model(name).needs_statics]


@pytest.mark.parametrize("name", INVERSE)
def test_every_model_trains_plans_and_steps_in_the_datas_sizes(name, synthetic, trained):
    model, checkpoint = trained(name)
    assert checkpoint["dims"] == {"inputs": 3, "position": 2}
    reference = synthetic.states[synthetic.test[0]]  # (49, 4)
    ctl = control.Controller(model, name)
    u = ctl.plan(reference)
    assert u.shape == (48, 3) and np.isfinite(u).all()
    reloaded = control.Controller(checkpoints.model_from_checkpoint(checkpoint), name)
    np.testing.assert_array_equal(reloaded.plan(reference), u)  # the record restores the sizes
    if ctl.has_step:  # per-step models: the real-time step gives the plan's u
        np.testing.assert_allclose(ctl.step(reference[10], reference[11]), u[10], atol=1e-4)


def test_the_mlp_learns_an_input_that_reaches_the_reference(synthetic, trained):
    """B u is what moves the tip, so the conditional mean of u reaches it too: the plan, run
    through the same dynamics, tracks far better than no input at all."""
    model, _ = trained("mlp")
    episodes = synthetic.test
    planned = control.Controller(model, "mlp").plan(synthetic.states[episodes])  # (E, T, 3)
    error = np.abs(simulate(planned)[..., :2] - synthetic.states[episodes, :, :2]).mean()
    idle = np.abs(simulate(np.zeros_like(planned))[..., :2] - synthetic.states[episodes, :, :2]).mean()
    assert error < 0.3 * idle


@pytest.mark.parametrize("name", ["rf-physical", "mlp-physical"])
def test_a_prior_model_says_it_needs_a_simulated_rods_statics(name, synthetic, tmp_path):
    with pytest.raises(ValueError, match="static"):
        training.train(name, synthetic, QUICK, tmp_path / f"{name}.pt", progress=False)
