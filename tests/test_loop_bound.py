"""The feedback floor of the loop study (``studies.loop_bound``): what a linear predictor of the
open loop's error leaves, on errors whose predictability is known."""

import numpy as np
import pytest

from softflow.studies.loop_bound import lagged, predictor_residual, slow_share


def test_lagged_holds_each_period_and_those_before_it():
    error = np.arange(12.0).reshape(4, 3)  # (T+1, 3)
    X = lagged(error, lags=2)
    np.testing.assert_array_equal(X[2], [6, 7, 8, 3, 4, 5])  # now, then one period before
    np.testing.assert_array_equal(X[0], [0, 1, 2, 0, 1, 2])  # the first period repeated before the start


def test_a_sinusoid_is_predicted_exactly_and_only_its_first_periods_are_left():
    """Each coordinate a sine of one frequency, a phase of its own per reference: two lags predict
    it any number of periods ahead, so what is left is the first ``horizon`` periods alone."""
    t, horizon = np.arange(400), 21
    errors = [np.stack([np.sin(0.07 * t + phase + k) for k in range(3)], 1) for phase in (0.0, 0.9, 2.1, 3.3)]
    left = predictor_residual(errors, [lagged(e) for e in errors], horizon)
    first = np.array([np.sqrt(np.sum(e[:horizon] ** 2) / np.sum(e**2)) for e in errors])
    np.testing.assert_allclose(left, first, atol=2e-3)


def test_white_noise_is_left_whole():
    rng = np.random.default_rng(0)
    errors = [rng.normal(size=(2000, 3)) for _ in range(4)]
    left = predictor_residual(errors, [lagged(e) for e in errors], 5)
    assert left == pytest.approx(1.0, abs=0.02)


def test_the_slow_share_splits_a_sum_of_two_sines():
    t = np.arange(1000) * 0.01  # 10 s at 100 Hz: whole periods of both
    error = np.stack([np.sin(2 * np.pi * 0.5 * t) + 2 * np.sin(2 * np.pi * 2.0 * t)] * 3, 1)
    assert slow_share(error, 0.01, 1.0) == pytest.approx(1 / 5)  # amplitude 1 against 2: energy 1 : 4
