"""Cable tensions and cable length changes."""

import numpy as np
import pytest

from softflow.rod.cables import cable_actuation, cable_directions, cable_displacements, cable_tensions
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT


@pytest.mark.parametrize("robot", [SIM_ROBOT, HW_ROBOT])
def test_tensions_realise_u_and_stay_non_negative(robot):
    u = np.random.default_rng(0).uniform(-4, 4, (200, 2))
    tensions = cable_tensions(u, robot, pretension=0.5)
    np.testing.assert_allclose(cable_actuation(tensions, robot), u, atol=1e-12)
    assert tensions.min() >= 0.5 - 1e-12


def test_four_cable_split_is_the_antagonistic_difference():
    tensions = cable_tensions(np.array([[3.0, -1.0]]), SIM_ROBOT)
    np.testing.assert_allclose(tensions, [[3.0, 0.0, 0.0, 1.0]], atol=1e-12)  # T1a - T1b = 3, T2a - T2b = -1


@pytest.mark.parametrize("robot", [SIM_ROBOT, HW_ROBOT])
def test_displacement_equals_the_length_of_the_deformed_cable_path(robot):
    """Trace each cable through the bent rod (fine centreline, offset by R r_c) and measure it."""
    sim = Simulator(robot, gravity="vertical", n_segments=400)
    q = sim.static_q(np.array([[3.0, -2.0], [-1.0, 4.0]]))
    positions, rotations = sim.centerline(q)
    expected = []
    for direction in cable_directions(robot):
        offset = robot.cable_radius * np.array([0.0, *direction])
        path = positions + rotations @ offset
        expected.append(np.linalg.norm(np.diff(path, axis=1), axis=-1).sum(1) - robot.length)
    np.testing.assert_allclose(cable_displacements(sim.bend_angles(q), robot), np.stack(expected, -1), atol=1e-6)


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="pretension"):
        cable_tensions(np.zeros((1, 2)), SIM_ROBOT, pretension=-1)
    with pytest.raises(ValueError, match="shape"):
        cable_displacements(np.zeros((3,)), SIM_ROBOT)
