"""The inverse-statics grid, RF-Physical's real-time prior: held to the table it tabulates and
to the exact inverse statics on the states a model sees, and exact where it cannot be close."""

import numpy as np
import pytest

from softflow.rod import statics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT

BOUND = 1e-3  # N: the grid's stated error (docs/speed.md); measured 5.6e-4 N on the paper dataset's states


@pytest.fixture(scope="module")
def rod():
    sim = Simulator(SIM_ROBOT, "vertical")
    table = sim.static_table()
    return sim, table, statics.InverseGrid(table)


def test_the_grid_gives_the_tables_inverse_on_every_state_of_a_dataset(rod, dataset):
    _, table, grid = rod
    p = dataset.states[..., :3].reshape(-1, 3)  # every tip position of 24 held-in and held-out episodes
    error = np.abs(grid.inverse(p) - table.inverse(p)).max()
    assert 1e-6 < error < BOUND  # above 1e-6: the grid interpolates, it does not call the table


def test_the_grid_is_within_its_bound_of_the_exact_inverse_statics(rod, dataset):
    sim, _, grid = rod
    p = dataset.states[dataset.test[0], ::10, :3]  # (21, 3): a held-out episode
    assert np.abs(grid.inverse(p) - sim.inverse_static(p)).max() < BOUND


def test_points_off_the_grid_and_at_the_tables_edge_are_solved_by_the_table(rod):
    _, table, grid = rod
    p = np.array(
        [
            [0.1, 0.0, 0.0],  # chord a quarter of the rod: below the grid's lengths
            [-0.2, 0.05, 0.0],  # behind the base: an arc actuation beyond the table's range
        ]
    )
    coordinates = grid.coordinates(p)
    assert not ((coordinates >= grid.low) & (coordinates <= grid.high)).all(-1).any()
    np.testing.assert_array_equal(grid.inverse(p), table.inverse(p))
    u = np.array([[table.u_range, 1.0]])  # a tip the table's inverse clips to its edge: a kink
    tip, _ = table.tip(u)
    assert ((grid.coordinates(tip) > grid.low) & (grid.coordinates(tip) < grid.high)).all()  # on the grid
    np.testing.assert_array_equal(grid.inverse(tip), table.inverse(tip))


def test_one_point_at_a_time_gives_the_batchs_prior(rod, dataset):
    """A step's single point gives the batch's prior, also where the table solves the point (off
    the grid, at the table's edge)."""
    _, table, grid = rod
    tip, _ = table.tip(np.array([[table.u_range, 1.0]]))  # a kink cell
    p = np.concatenate([dataset.states[0, ::5, :3], [[0.1, 0.0, 0.0], [-0.2, 0.05, 0.0]], tip])  # (N, 3)
    one_at_a_time = np.concatenate([grid.inverse(p[i : i + 1]) for i in range(len(p))])
    np.testing.assert_array_equal(one_at_a_time, grid.inverse(p))
    assert grid.solved_by_table(p[-3:]).all() and not grid.solved_by_table(p[:-3]).any()


def test_the_grid_coordinates_are_the_arcs_actuation_and_the_chord_length(rod, dataset):
    _, _, grid = rod
    p = dataset.states[0, :, :3]
    coordinates = grid.coordinates(p)
    np.testing.assert_allclose(coordinates[:, :2], statics.arc_actuation(SIM_ROBOT, p), rtol=0, atol=1e-12)
    np.testing.assert_allclose(coordinates[:, 2], np.linalg.norm(p, axis=-1), rtol=0, atol=1e-15)
    np.testing.assert_allclose(statics._chord_point(SIM_ROBOT, coordinates), p, rtol=0, atol=1e-12)


def test_the_grid_is_built_once_and_read_back(rod, tmp_path, monkeypatch):
    _, table, grid = rod
    monkeypatch.setattr(statics, "DATA_DIR", tmp_path)
    built = statics.InverseGrid(table, arcs=9, lengths=3)
    (path,) = tmp_path.glob("*.npz")
    assert path.name.startswith("inverse-grid-")
    read = statics.InverseGrid(table, arcs=9, lengths=3)
    np.testing.assert_array_equal(read.u, built.u)
    assert statics.InverseGrid(table, arcs=11, lengths=3).u.shape != built.u.shape  # another grid, another file
    assert len(list(tmp_path.glob("*.npz"))) == 2
