"""Metrics against hand-worked cases."""

import numpy as np
import pytest

from softflow.control.metrics import actuation_mae, input_energy, latency, peak_speed, phase_lag, tracking_rmse
from softflow.rod.robots import DT


def test_rmse_of_a_hand_worked_case_ignores_masked_samples():
    reference = np.zeros((3, 6))
    achieved = np.zeros((3, 6))
    achieved[0, :3] = [0.003, 0.004, 0.0]  # 5 mm off
    achieved[2, :3] = [1.0, 1.0, 1.0]  # in the approach segment: masked out
    rmse = tracking_rmse(achieved, reference, mask=[True, True, False])
    assert rmse == pytest.approx(np.sqrt(0.005**2 / 2))  # 3.536 mm
    in_plane = tracking_rmse(achieved, reference, mask=[True, True, False], axes=(1, 2))
    assert in_plane == pytest.approx(np.sqrt(0.004**2 / 2))  # the x error does not count in y-z


def test_peak_speed_of_a_hand_worked_case():
    states = np.zeros((3, 6))
    states[0, 3:] = [0.0, 3.0, 4.0]  # 5 m/s
    states[1, 3:] = [1.0, 0.0, 0.0]
    states[2, 3:] = [9.0, 0.0, 0.0]  # masked out
    assert peak_speed(states, mask=[True, True, False]) == pytest.approx(5.0)


@pytest.mark.parametrize("delay", [0.0, 0.02, 0.0375, -0.051])
def test_phase_lag_recovers_a_known_sub_sample_delay(delay):
    dt = 0.01
    t = np.arange(600) * dt
    reference = np.stack([np.sin(2 * np.pi * 0.7 * t), np.cos(2 * np.pi * 0.4 * t)], -1)
    achieved = np.stack([np.sin(2 * np.pi * 0.7 * (t - delay)), np.cos(2 * np.pi * 0.4 * (t - delay))], -1)
    assert phase_lag(achieved, reference, dt) == pytest.approx(delay, abs=2e-4)  # a fiftieth of a sample


def test_input_energy_and_mae_of_hand_worked_cases():
    u = np.array([[1.0, 2.0], [3.0, 0.0]])
    assert input_energy(u, 0.01) == pytest.approx((1 + 4 + 9) * 0.01)
    np.testing.assert_allclose(actuation_mae(u, np.array([[0.0, 2.5], [3.5, 0.0]])), [0.75, 0.25])


def test_latency_reports_median_and_p99():
    result = latency(lambda: sum(range(100)), repeats=50, warmup=1)
    assert 0 < result["median"] <= result["p99"]


def test_bad_inputs_are_rejected():
    with pytest.raises(ValueError, match="mask"):
        tracking_rmse(np.zeros((3, 6)), np.zeros((3, 6)), mask=[False, False, False])
    with pytest.raises(ValueError, match="axes"):
        tracking_rmse(np.zeros((3, 6)), np.zeros((3, 6)), axes=(3,))
    with pytest.raises(ValueError, match="same shape"):
        phase_lag(np.zeros(500), np.zeros(600), 0.01)
    with pytest.raises(ValueError, match="longer"):
        phase_lag(np.zeros(50), np.zeros(50), 0.01)
    with pytest.raises(ValueError, match="finite"):
        input_energy(np.array([[np.nan, 0.0]]), 0.01)


def test_a_short_reference_gets_a_phase_lag_over_fewer_shifts():
    """A fast shape can be shorter than the 0.5 s lag window needs (103 samples): its lag is
    searched over the shifts that fit, and a delayed copy still shows its delay."""
    from softflow.control.planning import score
    from softflow.data.references import Reference

    t = np.arange(80) * DT
    reference = np.zeros((80, 6))
    reference[:, 1], reference[:, 2] = np.sin(2 * np.pi * t), np.cos(2 * np.pi * t)
    achieved = reference.copy()
    achieved[:, 1:3] = np.stack([np.sin(2 * np.pi * (t - 0.03)), np.cos(2 * np.pi * (t - 0.03))], -1)
    row = score("m", Reference("fast", "shape", reference, np.ones(80, bool)), np.zeros((79, 2)), achieved)
    assert row["phase_lag_s"] == pytest.approx(0.03, abs=2e-3)
