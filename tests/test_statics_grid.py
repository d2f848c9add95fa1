"""The inverse-statics grid, RF-Physical's real-time prior as the step interpolates it
(``control.step.GridPrior``): held to the table it tabulates and to the exact inverse statics on
the states a model sees, and flagged where it cannot be close."""

import numpy as np
import pytest
import torch

from softflow.control.step import GridPrior
from softflow.rod import statics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT

BOUND = 1e-3  # N: the grid's stated error (docs/speed.md); measured 5.6e-4 N on the paper dataset's states


@pytest.fixture(scope="module")
def rod():
    sim = Simulator(SIM_ROBOT, "vertical")
    table = sim.static_table()
    return sim, table, statics.InverseGrid(table)


def prior(grid, p):
    """The step's prior (B, 2) float64 at tips p (B, 3), and (B,) bool: the tips it flags."""
    with torch.no_grad():
        u, flagged = GridPrior(grid)(torch.as_tensor(np.asarray(p), dtype=torch.float32))
    return u.double().numpy(), flagged.numpy()


def test_the_grid_gives_the_tables_inverse_on_every_state_of_a_dataset(rod, dataset):
    _, table, grid = rod
    p = dataset.states[..., :3].reshape(-1, 3)  # every tip position of 24 held-in and held-out episodes
    u, flagged = prior(grid, p)
    error = np.abs(u - table.inverse(p))[~flagged].max()
    assert 1e-6 < error < BOUND  # above 1e-6: the grid interpolates, it does not call the table
    # flagged: the cells beside the table's clipped edge, 0.19 % of these states (7.5e-5 of the paper dataset's)
    assert flagged.mean() < 5e-3


def test_the_grid_is_within_its_bound_of_the_exact_inverse_statics(rod, dataset):
    sim, _, grid = rod
    p = dataset.states[dataset.test[0], ::10, :3]  # (21, 3): a held-out episode
    u, flagged = prior(grid, p)
    assert not flagged.any() and np.abs(u - sim.inverse_static(p)).max() < BOUND


def test_points_off_the_grid_and_at_the_tables_edge_are_flagged(rod):
    _, table, grid = rod
    p = np.array(
        [
            [0.1, 0.0, 0.0],  # chord a quarter of the rod: below the grid's lengths
            [-0.2, 0.05, 0.0],  # behind the base: an arc actuation beyond the table's range
        ]
    )
    assert prior(grid, p)[1].all()
    tip, _ = table.tip(np.array([[table.u_range, 1.0], [2.0, 1.0]]))  # at the table's clipped edge: a kink
    np.testing.assert_array_equal(prior(grid, tip)[1], [True, False])


def test_one_point_at_a_time_gives_the_batchs_prior(rod, dataset):
    """A step's single point gives the batch's prior and flag."""
    _, table, grid = rod
    tip, _ = table.tip(np.array([[table.u_range, 1.0]]))  # a kink cell
    p = np.concatenate([dataset.states[0, ::5, :3], [[0.1, 0.0, 0.0], [-0.2, 0.05, 0.0]], tip])  # (N, 3)
    u, flagged = prior(grid, p)
    one_at_a_time = [prior(grid, p[i : i + 1]) for i in range(len(p))]
    np.testing.assert_array_equal(np.concatenate([a for a, _ in one_at_a_time]), u)
    np.testing.assert_array_equal(np.concatenate([b for _, b in one_at_a_time]), flagged)
    assert flagged[-3:].all() and not flagged[:-3].any()


def test_the_grid_coordinates_are_the_arcs_actuation_and_the_chord_length(rod, dataset):
    _, _, grid = rod
    p = dataset.states[0, :, :3]
    with torch.no_grad():
        coordinates = GridPrior(grid).coordinates(torch.as_tensor(p, dtype=torch.float32)).double().numpy()
    np.testing.assert_allclose(coordinates[:, :2], statics.arc_actuation(SIM_ROBOT, p), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(coordinates[:, 2], np.linalg.norm(p, axis=-1), rtol=1e-6, atol=0)
    np.testing.assert_allclose(statics._chord_point(SIM_ROBOT, coordinates), p, rtol=0, atol=1e-6)


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
