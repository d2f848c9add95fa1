"""The two-segment rod against closed-form mechanics: piecewise arcs, Euler-Bernoulli
frequencies, Kelvin-Voigt damping, equilibria that rollouts settle on, and the least-norm
inverse statics of a redundant rod (four inputs, a 3-D point)."""

import dataclasses
import itertools
import math

import numpy as np
import pytest
from scipy.optimize import minimize

from softflow.rod.cables import cable_actuation, cable_directions, cable_displacements, cable_tensions
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT, TWO_SEGMENT_ROD, Robot, rod_folder
from softflow.rod.statics import StaticTable
from softflow.rod.validation import (
    arc_disk_positions,
    arc_tip,
    euler_bernoulli_frequencies,
    kelvin_voigt_damping_ratio,
    linear_modes,
)
from softflow.store import content_key


def test_the_rod_is_the_simulation_rod_in_two_segments():
    for field in ("length", "diameter", "cable_distance", "youngs_modulus", "damping", "density"):
        assert getattr(TWO_SEGMENT_ROD, field) == getattr(SIM_ROBOT, field), field
    assert TWO_SEGMENT_ROD.segment_lengths == (0.2, 0.2) and TWO_SEGMENT_ROD.n_inputs == 4
    assert TWO_SEGMENT_ROD.cable_groups == ((0, 1, 2, 3), (4, 5, 6, 7))  # middle disk, then tip
    middle, tip = np.array(TWO_SEGMENT_ROD.cable_angles[:4]), np.array(TWO_SEGMENT_ROD.cable_angles[4:])
    np.testing.assert_allclose(tip - middle, math.pi / 4)  # holes turned by 45 degrees
    np.testing.assert_allclose(middle, SIM_ROBOT.cable_angles)


def test_the_rods_keep_their_cache_keys():
    """Every field but the name keys a rod (cable_anchors at its default too): the keys the
    shipped data, checkpoints (checkpoints/hw-*-5e469dc9) and study rows are found under."""
    assert SIM_ROBOT.parameters()["cable_anchors"] == ()
    assert content_key(Simulator(SIM_ROBOT).spec()) == "3cb3e905b33d78c3"
    assert content_key(Simulator(HW_ROBOT, gravity="horizontal").spec()) == "fb14cbdfe60dc8dd"
    assert rod_folder(HW_ROBOT, "horizontal") == "hw-horizontal-5e469dc9"
    assert rod_folder(HW_ROBOT, "vertical") == "hw-vertical-5e469dc9"
    assert rod_folder(SIM_ROBOT, "horizontal") == "sim-horizontal-146cd570"
    assert content_key(Simulator(TWO_SEGMENT_ROD).spec()) != content_key(Simulator(SIM_ROBOT).spec())


def test_gravity_free_statics_are_piecewise_circular_arcs_over_the_input_range():
    """Segment 1 bends with (u_1,2 + u_3,4) r / EI, segment 2 with u_3,4 r / EI: the middle
    disk and the tip sit on the closed-form arcs, each segment's strain basis exact."""
    corners = np.array(list(itertools.product([-4.0, 0.0, 4.0], repeat=4)))  # includes u = 0 and cancelling pairs
    u = np.concatenate([corners, np.random.default_rng(0).uniform(-4, 4, (40, 4))])
    sim = Simulator(TWO_SEGMENT_ROD, gravity="none")
    disks = sim.disk_positions(sim.static_q(u))  # (B, 2, 3): middle disk, tip
    expected = arc_disk_positions(u, TWO_SEGMENT_ROD)
    np.testing.assert_allclose(disks, expected, rtol=0, atol=1e-12)  # measured 4e-16 m: exact
    np.testing.assert_allclose(sim.static_tip(u), arc_tip(u, TWO_SEGMENT_ROD), rtol=0, atol=1e-12)


def _in_plane_error(robot):
    frequencies, _ = linear_modes(Simulator(robot, gravity="none", damping=False))
    in_plane = frequencies[::2][:2]  # the two bending planes are identical: modes come in pairs
    np.testing.assert_allclose(frequencies[1::2][:2], in_plane, rtol=1e-11)  # measured 2e-13
    return in_plane / euler_bernoulli_frequencies(robot, 2) - 1


def test_bending_frequencies_are_as_close_to_euler_bernoulli_as_the_one_segment_rods():
    """Measured side by side: mode 1 -63 ppm (one segment -70; both near the -71 ppm floor of
    the 32 lumped masses), mode 2 +0.25 % (one segment +0.69 %)."""
    two, one = _in_plane_error(TWO_SEGMENT_ROD), _in_plane_error(SIM_ROBOT)
    assert np.all(np.abs(two) <= np.abs(one)), (two, one)
    assert abs(two[0]) < 1e-4 and 0 < two[1] < 0.005


def test_first_mode_damping_ratio_is_kelvin_voigt_as_close_as_the_one_segment_rods():
    expected = kelvin_voigt_damping_ratio(SIM_ROBOT, euler_bernoulli_frequencies(SIM_ROBOT, 1)[0])
    two = linear_modes(Simulator(TWO_SEGMENT_ROD, gravity="none"))[1][0] / expected - 1
    one = linear_modes(Simulator(SIM_ROBOT, gravity="none"))[1][0] / expected - 1
    assert abs(two) <= abs(one) and abs(two) < 2e-4  # measured -6.3e-5 and -7.0e-5 (the frequencies' errors)


@pytest.mark.parametrize("gravity", ["vertical", "horizontal"])
def test_a_rollout_under_constant_u_settles_on_the_static_tip(gravity):
    sim = Simulator(TWO_SEGMENT_ROD, gravity=gravity)
    u = np.array([[1.5, -2.5, 1.0, 2.0]])
    X = sim.rollout(np.repeat(u[:, None], 1000, axis=1))  # (1, 1001, 6); 10 s: the first mode decays ~1e-5
    assert np.abs(X[0, -1, :3] - sim.static_tip(u)[0]).max() < 1e-5  # m; measured 6e-7 (vertical), 1e-6 (horizontal)
    assert np.abs(X[0, 0, :3] - X[0, -1, :3]).max() > 0.05  # it really moved (measured 0.12 and 0.16 m)


@pytest.mark.parametrize("gravity", ["none", "vertical", "horizontal"])
def test_inverse_statics_reaches_the_point_with_no_more_force_than_needed(gravity):
    """Points reached by random u in the actuation range: the inverse reaches them again, with
    |u| no larger than the u that made them (it is the least-norm one, tested below)."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity=gravity)
    u = np.random.default_rng(1).uniform(-4, 4, (6, 4))
    p = sim.static_tip(u)  # (6, 3)
    found = sim.inverse_static(p)
    np.testing.assert_allclose(sim.static_tip(found), p, rtol=0, atol=1e-12)  # measured 3e-16 m
    assert np.all(np.linalg.norm(found, axis=1) <= np.linalg.norm(u, axis=1))  # measured ratios 0.65-0.98


@pytest.mark.parametrize("gravity", ["none", "vertical"])
def test_the_rest_tip_needs_no_force_and_an_unreachable_point_is_named(gravity):
    """At rest the tip cannot move along the rod's axis to first order (d p/d u has rank 2):
    the least-norm inverse is u = 0, not a division by that zero singular value. A point just
    beyond the tip (stretching the rod) has no exact fit, and the error says so."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity=gravity)
    rest = sim.static_tip(np.zeros((1, 4)))
    np.testing.assert_array_equal(sim.inverse_static(rest), np.zeros((1, 4)))
    with pytest.raises(ValueError, match=r"no equilibrium that reaches it exactly .* 4 inputs"):
        sim.inverse_static(np.array([[0.4, 1e-3, 0.0]]))


def test_least_norm_inverse_matches_a_brute_force_search_on_the_closed_form_arcs():
    """Without gravity the tip is the closed-form piecewise arc: SLSQP from 20 random starts
    on it (no GVS involved) finds no reaching u of smaller norm."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity="none")
    p = sim.static_tip(np.array([[3.0, -1.0, -2.0, 2.5], [-2.0, 3.5, 1.0, -3.0]]))
    found = sim.inverse_static(p)
    starts = np.random.default_rng(2).uniform(-6, 6, (20, 4))
    for target, ours in zip(p, found):
        reach = {"type": "eq", "fun": lambda u, target=target: arc_tip(u[None], TWO_SEGMENT_ROD)[0] - target}
        norms = [
            np.linalg.norm(fit.x)
            for fit in (
                minimize(lambda u: u @ u, start, constraints=[reach], method="SLSQP", tol=1e-14) for start in starts
            )
            if fit.success and np.abs(arc_tip(fit.x[None], TWO_SEGMENT_ROD)[0] - target).max() < 1e-9
        ]
        assert len(norms) >= 5
        assert np.linalg.norm(ours) <= min(norms) + 1e-7  # measured: 2e-12 N above SLSQP's best, u within 2e-7 N


def test_least_norm_inverse_is_the_minimum_along_the_solutions_under_gravity():
    """The u that reach p form a curve; scanned by fixing u_1 on a grid and solving for the
    other three (Newton on static_tip), |u| is smallest at the inverse's answer."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity="horizontal")
    p = sim.static_tip(np.array([[3.0, -1.0, -2.0, 2.5]]))[0]
    found = sim.inverse_static(p[None])[0]
    u = np.repeat(found[None], 9, 0)  # (9, 4)
    u[:, 0] += np.linspace(-2, 2, 9)
    for _ in range(8):
        tip = sim.static_tip(u)
        J = np.stack([(sim.static_tip(u + 1e-6 * np.eye(4)[k]) - tip) / 1e-6 for k in (1, 2, 3)], -1)  # (9, 3, 3)
        u[:, 1:] += np.linalg.solve(J, (p - tip)[..., None])[..., 0]
    np.testing.assert_allclose(sim.static_tip(u), np.broadcast_to(p, (9, 3)), rtol=0, atol=1e-9)
    norms = np.linalg.norm(u, axis=1)  # measured 3.663 N at the answer, 3.682 and 3.680 at u_1 -+ 0.5 N
    assert norms.argmin() == 4 and np.linalg.norm(found) <= norms.min() + 1e-9


def test_cables_realise_u_through_holes_turned_by_45_degrees():
    u = np.random.default_rng(3).uniform(-4, 4, (50, 4))
    tensions = cable_tensions(u, TWO_SEGMENT_ROD, pretension=0.5)  # (50, 8)
    np.testing.assert_allclose(cable_actuation(tensions, TWO_SEGMENT_ROD), u, atol=1e-12)
    assert tensions.min() >= 0.5 - 1e-12
    # u_3 alone pulls both tip pairs (at 45 and -45 degrees) equally, each by u_3 / sqrt(2)
    single = cable_tensions(np.array([[0.0, 0.0, 3.0, 0.0]]), TWO_SEGMENT_ROD)[0]
    np.testing.assert_allclose(single, [0, 0, 0, 0, 3 / math.sqrt(2), 0, 0, 3 / math.sqrt(2)], atol=1e-12)


def test_cable_displacements_are_the_lengths_of_the_deformed_cable_paths():
    """Each cable traced through the bent rod up to its disk (fine centreline, offset by R r_c)."""
    sim = Simulator(TWO_SEGMENT_ROD, gravity="vertical", n_segments=400)
    q = sim.static_q(np.array([[3.0, -2.0, -1.0, 4.0], [-1.0, 4.0, 2.0, 0.5]]))
    positions, rotations = sim.centerline(q)
    expected = []
    for direction, anchor in zip(cable_directions(TWO_SEGMENT_ROD), TWO_SEGMENT_ROD.anchors):
        nodes = slice(0, round(anchor / TWO_SEGMENT_ROD.length * sim.kinematics.n_segments) + 1)
        path = positions[:, nodes] + rotations[:, nodes] @ (TWO_SEGMENT_ROD.cable_radius * np.array([0.0, *direction]))
        expected.append(np.linalg.norm(np.diff(path, axis=1), axis=-1).sum(1) - anchor)
    np.testing.assert_allclose(
        cable_displacements(sim.bend_angles(q), TWO_SEGMENT_ROD), np.stack(expected, -1), atol=1e-6
    )


def test_the_lift_and_the_table_ask_for_two_inputs():
    sim = Simulator(TWO_SEGMENT_ROD)
    with pytest.raises(ValueError, match="static_lift needs a rod with 2 inputs; 'two' has 4"):
        sim.static_lift(np.zeros((1, 2)))
    with pytest.raises(ValueError, match="StaticTable needs a rod with 2 inputs"):
        StaticTable(sim)


def test_bad_input_and_bad_rods_are_refused():
    sim = Simulator(TWO_SEGMENT_ROD)
    with pytest.raises(ValueError, match=r"shape \(any, any, 4\)"):
        sim.rollout(np.zeros((1, 5, 2)))
    with pytest.raises(ValueError, match=r"exceeds .* N, the actuation along it that curls 'two' into a full circle"):
        sim.static_tip(np.array([[20.0, 0.0, 20.0, 0.0]]))
    with pytest.raises(ValueError, match="cannot share a hole"):
        dataclasses.replace(TWO_SEGMENT_ROD, cable_angles=SIM_ROBOT.cable_angles * 2)
    with pytest.raises(ValueError, match="one arc length per cable"):
        dataclasses.replace(TWO_SEGMENT_ROD, cable_anchors=(0.2, 0.4))
    with pytest.raises(ValueError, match=r"cable_anchors must lie in \(0, length = 0.4\]"):
        dataclasses.replace(TWO_SEGMENT_ROD, cable_anchors=(0.2,) * 4 + (0.5,) * 4)
    with pytest.raises(ValueError, match="each anchor disk must end 3 or 4 cables; got 2"):
        Robot(**{**dataclasses.asdict(TWO_SEGMENT_ROD), "cable_anchors": (0.2,) * 2 + (0.4,) * 6})


def test_disk_positions_take_any_leading_shape():
    sim = Simulator(TWO_SEGMENT_ROD, gravity="none")
    q = sim.static_q(np.array([[1.0, 0.0, 0.0, 2.0], [0.0, -1.0, 3.0, 0.0]]))
    stacked = sim.disk_positions(np.stack([q, q]))  # (2, 2, S, 3)
    assert stacked.shape == (2, 2, 2, 3)
    np.testing.assert_array_equal(stacked[1], sim.disk_positions(q))
    np.testing.assert_array_equal(sim.disk_positions(q)[:, -1], sim.tip_positions(q))
