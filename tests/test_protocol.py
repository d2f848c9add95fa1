"""The protocol's open choices, each checked on what it must do to a reference: the lifts
against the statics lift they replace, starting on the path from the path's own first
pose, and coverage on states that are (or are far from) training states."""

import numpy as np
import pytest

from softflow import data
from softflow.data import references
from softflow.data.references import Reference
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT
from softflow.studies import protocol
from softflow.studies.table1 import TABLE1


@pytest.fixture(scope="module")
def sim():
    return Simulator(SIM_ROBOT)


@pytest.fixture(scope="module")
def circle(sim):
    return data.shape_reference(sim, "circle", size=0.08)


def test_lifts_change_only_what_they_name(sim, circle):
    def lifted(lift):
        return protocol.apply(sim, [circle], protocol.Protocol(lift=lift))[0][0]

    assert np.array_equal(lifted("statics").states, circle.states)
    zero = lifted("zero-velocity")
    assert np.array_equal(zero.states[:, :3], circle.states[:, :3]) and not zero.states[:, 3:].any()
    constant = lifted("px-constant")
    assert np.ptp(constant.states[:, 0]) == 0 and not constant.states[:, 3].any()
    assert np.array_equal(constant.states[:, 1:3], circle.states[:, 1:3])
    # central differences of the statics-lifted positions agree with its exact chain-rule velocities
    differenced = lifted("finite-difference").states[1:-1, 3:]
    exact = circle.states[1:-1, 3:]
    assert np.abs(differenced - exact).max() < 0.01 * np.abs(exact).max()
    assert np.array_equal(lifted("finite-difference").mask, circle.mask)


def test_approach_scored_or_replaced_by_starting_on_the_path(sim, circle):
    scored, start = protocol.apply(sim, [circle], protocol.Protocol(approach="scored"))
    assert start is None and scored[0].mask.all() and not circle.mask.all()
    (on_path,), start_q = protocol.apply(sim, [circle], protocol.Protocol(approach="on-path"))
    np.testing.assert_array_equal(on_path.states, circle.states[circle.mask])
    assert on_path.mask.all() and start_q.shape == (1, sim.nq)
    tip = sim.tip_positions(start_q)[0]
    assert np.linalg.norm(tip - on_path.states[0, :3]) < 1e-4  # the rod starts where the path does
    held = sim.rollout(np.zeros((1, 5, 2)) + sim.static_table().inverse(tip[None]), start_q=start_q)[0]
    assert np.abs(held[:, :3] - tip).max() < 1e-6  # at rest there: an equilibrium


def test_actuation_made_references_keep_their_states(sim):
    (random,) = data.random_references(sim, 1, seconds=1.0)
    kept, _ = protocol.apply(sim, [random], protocol.Protocol(lift="zero-velocity"))
    assert kept[0] is random
    with pytest.raises(ValueError, match="structured paths only"):
        protocol.apply(sim, [random], protocol.Protocol(approach="on-path"))
    with pytest.raises(ValueError, match="lift"):
        protocol.Protocol(lift="spline")
    with pytest.raises(ValueError, match="speed"):
        protocol.Protocol(speed=0.0)


def test_coverage_is_one_on_training_states_and_zero_far_away(dataset):
    states = dataset.states[dataset.train[0]]
    inside = Reference("inside", "shape", states, np.ones(len(states), bool))
    far = Reference("far", "shape", states + np.array([0, 1.0, 0, 0, 0, 0]), np.ones(len(states), bool))
    assert protocol.coverage([inside, far], dataset).tolist() == [1.0, 0.0]


def test_the_ci_protocol_shapes_ship(sim, tmp_path, monkeypatch):
    """The shapes of the ci protocol study's speed cells ship in cache/ (test_shipped_rows runs
    one of them): found under today's key, read, not built (the test below builds its own)."""
    monkeypatch.setattr(references, "DATA_DIR", tmp_path)
    shapes = protocol.shapes_at(sim, TABLE1["ci"].shapes, 0.5)
    assert [r.name for r in shapes] == list(TABLE1["ci"].shapes) and not any(tmp_path.iterdir())


def test_shapes_at_a_speed_are_faster(sim):
    slow, fast = (protocol.shapes_at(sim, ("circle",), speed)[0] for speed in (0.15, 0.45))
    masked = lambda r: r.states[r.mask]  # noqa: E731
    mean_speed = [np.linalg.norm(masked(r)[:, 4:6], axis=1).mean() for r in (slow, fast)]
    assert mean_speed[1] / mean_speed[0] == pytest.approx(3.0, rel=0.05)
    assert fast.mask.sum() < slow.mask.sum() / 2.5
