"""A new user's slips are refused with a message that says what was expected: states in
millimetres or from another rod at the real-time step, a shape sized in millimetres, the
forward surrogate loaded as a controller, a non-positive sample period, a sag calibration
from a hanging rod or with the tip above the axis."""

import warnings

import numpy as np
import pytest

from softflow import control, data, hardware
from softflow.control import metrics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT, U_MAX

REST = np.array([SIM_ROBOT.length, 0.0, 0.0, 0.0, 0.0, 0.0])  # the simulation rod hanging straight, at rest


@pytest.fixture(scope="module")
def rf():
    return control.load_controller("rf")


def test_step_refuses_millimetres_and_names_the_state(rf):
    with pytest.raises(ValueError, match=r"^x_t tip position x = 400 m is \d+ training standard deviations .*metres"):
        rf.step(1e3 * REST, REST)
    with pytest.raises(ValueError, match=r"^x_next tip position x = 400 m at index \(1,\) is \d+ training standard"):
        rf.step(np.stack([REST, REST]), np.stack([REST, 1e3 * REST]))


def test_step_refuses_another_rods_states():
    """The simulation rod (0.40 m) at rest, stepped on the hardware twin's model (0.45 m)."""
    twin = control.load_controller("rf-fwd", "paper", HW_ROBOT, "vertical")
    with pytest.raises(ValueError, match=r"x_t tip position x = 0.4 m is 1\d training standard deviations from the "):
        twin.step(REST, REST)


def test_step_checks_the_workspace_as_plan_does_and_none_bypasses_it(rf):
    mean, std = (b.numpy()[1].astype(float) for b in (rf.model.state_norm.mean, rf.model.state_norm.std))
    for k, refused in ((7.5, False), (8.5, True)):
        states = np.tile(REST, (2, 1))
        states[:, 1] = mean + k * std  # k training standard deviations out in y
        if refused:
            with pytest.raises(ValueError, match=r"reference tip position y = .* training standard deviations"):
                rf.plan(states)
            with pytest.raises(ValueError, match=r"x_t tip position y = .* training standard deviations"):
                rf.step(states[0], states[1])
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", control.SaturationWarning)
                np.testing.assert_allclose(rf.step(states[0], states[1]), rf.plan(states)[0], atol=1e-5)
    unchecked = control.Controller(rf.model, "rf", workspace_margin=None)
    with pytest.warns(control.SaturationWarning):
        assert np.abs(unchecked.step(1e3 * REST, 1e3 * REST)).max() == U_MAX  # what a units slip commanded


def test_load_controller_refuses_the_forward_surrogate_and_lists_the_controllers():
    with pytest.raises(
        ValueError,
        match=r'^"forward" is the forward-dynamics surrogate used by RF-FWD, not a controller; load one of \[.*rf-fwd',
    ):
        control.load_controller("forward")
    with pytest.raises(ValueError, match=r"controller must be one of \['mlp', .*\]; got 'rf_fwd'"):
        control.load_controller("rf_fwd")


IN_MILLIMETRES = {
    "shape": lambda sim: data.shape_reference(sim, "circle", size=120),
    "burst": lambda sim: data.burst_circle_reference(sim, radius=150),
}


@pytest.mark.parametrize("make", IN_MILLIMETRES.values(), ids=IN_MILLIMETRES)
def test_a_path_in_millimetres_is_refused_with_the_rods_reach(make):
    with pytest.raises(
        ValueError,
        match=r"reaches 1[25]0 m from the rod's axis, farther than the rod is long \(0.4 m\): size, radius and centre "
        r"are in metres. At \|u\| <= 4 N this rod's tip reaches at most 0.2\d\d m from its rest position",
    ):
        make(Simulator(SIM_ROBOT))


@pytest.mark.parametrize("dt", [-0.01, 0.0, float("nan"), float("inf"), "0.01"])
def test_metrics_need_a_positive_finite_sample_period(dt):
    signal = np.sin(np.linspace(0, 10, 200))
    expected = rf"dt must be a finite sample period > 0 s; got {dt!r}".replace("(", r"\(").replace(")", r"\)")
    for call in (
        lambda: metrics.phase_lag(signal, signal, dt),
        lambda: metrics.input_energy(np.ones((10, 2)), dt),
        lambda: metrics.fitting_lag(200, dt),
    ):
        with pytest.raises(ValueError, match=expected):
            call()


def test_sag_calibration_needs_a_horizontal_rod_sagging_down():
    rest_tip = Simulator(HW_ROBOT, gravity="horizontal").static_tip(np.zeros((1, 2)))[0]
    with pytest.raises(TypeError, match="gravity"):
        hardware.calibrate_sag(HW_ROBOT, rest_tip)  # the mounting must be stated
    with pytest.raises(ValueError, match=r"got gravity='vertical': a rod hanging along gravity, or without it, does "):
        hardware.calibrate_sag(HW_ROBOT, [HW_ROBOT.length, 0.0, 0.0], gravity="vertical")
    with pytest.raises(ValueError, match=r"rest_tip z = 0.1\d+ m is above the rod's axis.*expected a negative z"):
        hardware.calibrate_sag(HW_ROBOT, rest_tip * [1, 1, -1], gravity="horizontal")
