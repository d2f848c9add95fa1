"""The ILC floor: on references made by actuation (a plan that tracks them exactly exists)
it learns that plan from its own trials, from a quasi-static start tens of millimetres off."""

import numpy as np
import pytest

from softflow import data
from softflow.control import floor
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT


def test_ilc_learns_a_reachable_reference():
    sim = Simulator(SIM_ROBOT)
    references = data.random_references(sim, 2, seconds=2.0, seed=7)
    plans, reached, history = floor.ilc_plans(sim, references, iterations=6)
    assert history.shape == (7, 2)
    assert np.all(history[0] > 5.0)  # the quasi-static start ignores the rod's dynamics
    assert np.all(history.min(0) < history[0] / 10)
    for r, u, X, best in zip(references, plans, reached, history.min(0)):
        assert u.shape == (r.n_steps, 2) and X.shape == r.states.shape
        np.testing.assert_allclose(1e3 * np.sqrt(np.mean(np.sum((X[:, :3] - r.states[:, :3]) ** 2, 1))), best)
        np.testing.assert_allclose(sim.rollout(u[None])[0], X)  # the plan reaches what it reports


def test_bad_settings_are_refused():
    sim = Simulator(SIM_ROBOT)
    references = data.random_references(sim, 1, seconds=0.5)
    for bad in (dict(iterations=-1), dict(cutoff_hz=60.0), dict(gain=0.0), dict(gain=1.5)):
        with pytest.raises(ValueError):
            floor.ilc_plans(sim, references, **bad)
