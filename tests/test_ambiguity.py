"""The conditional-spread estimator on cases worked by hand: additive noise of known size is
recovered, a deterministic map sits at the floor, a two-valued inverse shows its full
spread; and on the simulator's transitions the inverse is nearly one-valued."""

import numpy as np
import pytest

from softflow.studies.ambiguity import conditional_spread, transition_spread


@pytest.fixture(scope="module")
def cloud():
    rng = np.random.default_rng(0)
    condition = rng.uniform(0, 1, (20000, 3))
    return rng, condition, np.sin(3 * condition[:, :2])


def test_noise_of_known_size_is_recovered(cloud):
    rng, condition, smooth = cloud
    noisy = conditional_spread(condition, smooth + rng.normal(0, 0.1, smooth.shape))
    assert noisy.spread == pytest.approx(0.1 * np.sqrt(2), rel=0.1)  # two channels of 0.1 each
    assert noisy.floor < 0.1 * noisy.spread


def test_a_deterministic_map_sits_near_the_floor_and_a_two_valued_one_does_not(cloud):
    rng, condition, smooth = cloud
    exact = conditional_spread(condition, smooth)
    assert exact.spread < 0.05 and exact.floor < 0.05
    two_valued = conditional_spread(condition, smooth + rng.choice([-1.0, 1.0], (len(smooth), 1)))
    assert two_valued.spread == pytest.approx(np.sqrt(2), rel=0.05)  # |u - u'| = 2 per channel half the time


def test_the_simulators_inverse_is_nearly_one_valued(dataset):
    measured = transition_spread(dataset.states, dataset.u, dataset.train)
    assert measured.points == len(dataset.train) * dataset.u.shape[1]
    assert measured.spread < 0.1 * dataset.u[dataset.train].std() * np.sqrt(2)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="shape"):
        conditional_spread(np.zeros((10, 3)), np.zeros((9, 2)))
    with pytest.raises(ValueError, match="at least 3"):
        conditional_spread(np.zeros((2, 3)), np.zeros((2, 2)))
