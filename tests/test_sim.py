"""The GVS simulator against closed-form and independent mechanics (issue: simulator checks 1-8)."""

import dataclasses

import numpy as np
import pytest

from softflow.data.excitation import sum_of_sines_excitation
from softflow.rod import dynamics, statics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT
from softflow.rod.validation import (
    MM,
    arc_tip,
    convergence_study,
    euler_bernoulli_frequencies,
    heavy_cantilever_tip,
    kelvin_voigt_damping_ratio,
    linear_modes,
    released_energy,
)


@pytest.mark.parametrize("direction", [(1, 0), (0, 1), (-1, 0), (0, -1), (np.sqrt(0.5), np.sqrt(0.5))])
def test_static_tip_is_the_circular_arc_without_gravity(direction):
    u = np.array([0.5, 2.0, 4.0])[:, None] * np.array(direction)[None]
    tip = Simulator(SIM_ROBOT, gravity="none").static_tip(u)
    np.testing.assert_allclose(tip, arc_tip(u, SIM_ROBOT), rtol=0, atol=1e-12)  # measured 4e-16 m: exact


def test_first_two_bending_frequencies_match_euler_bernoulli():
    frequencies, _ = linear_modes(Simulator(SIM_ROBOT, gravity="none", damping=False))
    in_plane = frequencies[::2][:2]  # the two bending planes are identical: modes come in pairs
    np.testing.assert_allclose(frequencies[1::2][:2], in_plane, rtol=1e-12)  # measured 4e-14
    # measured -0.007 % (mode 1) and +0.69 % (mode 2, lumped mass): 3x and 1.5x margin
    first, second = in_plane / euler_bernoulli_frequencies(SIM_ROBOT, 2) - 1
    assert abs(first) < 2e-4 and 0 < second < 0.01
    np.testing.assert_allclose(euler_bernoulli_frequencies(SIM_ROBOT, 2), [1.4278, 8.9480], rtol=1e-4)


def test_first_mode_damping_ratio_is_kelvin_voigt():
    _, ratios = linear_modes(Simulator(SIM_ROBOT, gravity="none"))
    expected = kelvin_voigt_damping_ratio(SIM_ROBOT, euler_bernoulli_frequencies(SIM_ROBOT, 1)[0])
    assert ratios[0] == pytest.approx(expected, rel=2e-4)  # measured -7.0e-5 (the frequency's error): 3x margin


def test_free_vibration_of_the_simulated_rod_has_the_first_mode_period_and_decay():
    """End to end through the time stepper: period and logarithmic decrement of a small release."""
    sim = Simulator(SIM_ROBOT, gravity="none")
    q0 = sim.static_q(np.array([[0.2, 0.0]]))
    q, qd = sim.integrate(np.zeros((1, 300, 2)), q0, np.zeros_like(q0))
    y = sim.tip_state(q[0], qd[0])[:, 1]
    peaks = [t for t in range(1, len(y) - 1) if y[t] > y[t - 1] and y[t] >= y[t + 1] and y[t] > 0]
    period = np.diff(peaks).mean() * sim.dt
    f1 = euler_bernoulli_frequencies(SIM_ROBOT, 1)[0]
    zeta = kelvin_voigt_damping_ratio(SIM_ROBOT, f1)
    # peaks on the 0.01 s grid: measured +0.26 % in the period and -0.16 % in the decrement, 4x and 6x margin
    assert period == pytest.approx(1 / (f1 * np.sqrt(1 - zeta**2)), rel=0.01)
    decrement = np.log(y[peaks[0]] / y[peaks[1]])
    assert decrement == pytest.approx(2 * np.pi * zeta / np.sqrt(1 - zeta**2), rel=0.01)


def test_energy_of_a_released_undamped_rod_is_conserved():
    """A bend of 0.1 m at the tip (a quarter of L), released without damping or gravity, for 5 s."""
    drifts = []
    for substeps in (4, 8):
        energy = released_energy(SIM_ROBOT, np.array([[1.0, 0.5]]), 500, substeps=substeps)[0]
        drifts.append(np.abs(energy - energy[0]).max() / energy[0])
    assert drifts[0] < 0.01  # measured 0.72 %
    assert drifts[1] < drifts[0] / 2.5  # measured 2.9x smaller at half the step: time integration, not the model


def test_energy_terms_are_consistent():
    """The convective force is the one that makes d/dt (qd^T M qd / 2) = qd^T (M qdd + c)."""
    sim = Simulator(SIM_ROBOT, gravity="none")
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.normal(size=(3, 2, sim.nq))
    h = 1e-6
    kinetic = lambda t: (
        0.5 * np.einsum("bi,bij,bj->b", qd + t * qdd, sim.mass_matrix(q + t * qd + 0.5 * t * t * qdd), qd + t * qdd)
    )
    numeric = (kinetic(h) - kinetic(-h)) / (2 * h)
    f, Jp, M, _ = sim._dynamics_terms(q)
    c = sim._convective_force(Jp, f["positions"], sim.kinematics.positions_along(q, qd, dynamics._CONVECTIVE_STEP))
    # measured 1.3e-9 (the convective term's second difference and this test's own, h = 1e-6): 8x margin
    np.testing.assert_allclose(numeric, np.einsum("bi,bi->b", qd, np.einsum("bij,bj->bi", M, qdd) + c), rtol=1e-8)


@pytest.fixture(scope="module")
def random_actuation():
    return sum_of_sines_excitation(2, 500, seed=7)


def test_u_sign_flip_mirrors_and_u_swap_swaps_axes(random_actuation):
    sim = Simulator(SIM_ROBOT)
    u = random_actuation[:, :100]
    X, X_neg, X_swap = sim.rollout(u), sim.rollout(-u), sim.rollout(u[..., ::-1])
    mirror = np.array([1, -1, -1, 1, -1, -1])
    np.testing.assert_array_equal(X_neg, X * mirror)  # measured: bit-exact
    # Swapping the axes reorders the arithmetic; the convective term's second difference
    # amplifies last-bit differences ~1e7-fold (measured 3.9e-10 m, 6e-9 m/s): 2.5x / 5x margin.
    swapped = X[..., [0, 2, 1, 3, 5, 4]]
    np.testing.assert_allclose(X_swap[..., :3], swapped[..., :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(X_swap[..., 3:], swapped[..., 3:], rtol=0, atol=3e-8)


def test_horizontal_sag_matches_the_heavy_elastica():
    tip = Simulator(HW_ROBOT, gravity="horizontal").static_tip(np.zeros((1, 2)))[0]
    expected = heavy_cantilever_tip(HW_ROBOT)
    assert expected[2] < -0.1  # a genuinely large deflection
    np.testing.assert_allclose(tip, expected, atol=0.2 * MM)  # measured 0.05 mm (0.03 % of the sag): 4x margin


def test_tip_converges_with_basis_order_and_step(random_actuation):
    u = random_actuation[:1, :150]  # 1.5 s of one episode (notebook 01 runs the full study)
    errors = convergence_study(
        SIM_ROBOT, u, dict(order=7, n_segments=64, substeps=8), {"order": [dict(order=k) for k in range(4)]}
    )["order"]
    assert all(later < earlier for earlier, later in zip(errors, errors[1:])), errors
    assert errors[-1] < 0.5 * MM  # the default order
    halved = convergence_study(SIM_ROBOT, u, {}, {"substeps": [dict(substeps=8)]})["substeps"][0]
    assert halved < 0.1 * MM


@pytest.mark.parametrize("gravity", ["vertical", "horizontal", "none"])
def test_inverse_static_recovers_u(gravity):
    grid = np.linspace(-4, 4, 9)
    u = np.stack(np.meshgrid(grid, grid), -1).reshape(-1, 2)
    sim = Simulator(SIM_ROBOT, gravity=gravity)
    np.testing.assert_allclose(sim.inverse_static(sim.static_tip(u)), u, rtol=0, atol=1e-10)  # measured 5e-15 N


def test_a_static_table_interpolates_the_equilibria_it_was_built_from(tmp_path, monkeypatch):
    """Built here (the tables a fresh clone needs ship in cache/): at its nodes the splines give
    the static solves exactly, between them within a micrometre (2e-8 m measured)."""
    monkeypatch.setattr(statics, "DATA_DIR", tmp_path)
    sim = Simulator(HW_ROBOT, "horizontal")
    table = statics.StaticTable(sim, u_range=1.0, step=0.5)  # 5 x 5 equilibria
    assert sorted(path.suffix for path in tmp_path.glob("static-table-*")) == [
        ".json",
        ".npz",
    ]  # the cache and its spec
    nodes = np.array([[-1.0, 0.5], [0.0, 0.0], [1.0, -1.0]])
    np.testing.assert_allclose(table.tip(nodes)[0], sim.static_tip(nodes), rtol=0, atol=1e-12)
    between = np.array([[-0.75, 0.25], [0.3, -0.6]])
    assert np.abs(table.tip(between)[0] - sim.static_tip(between)).max() < 1e-6  # m


def test_rollout_starts_at_rest_in_gravity_equilibrium():
    sim = Simulator(HW_ROBOT, gravity="horizontal")
    X = sim.rollout(np.zeros((2, 20, 2)))
    np.testing.assert_allclose(X[:, :, :3], np.broadcast_to(sim.static_tip(np.zeros((1, 2))), (2, 21, 3)), atol=1e-12)
    np.testing.assert_allclose(X[:, :, 3:], 0, atol=1e-12)  # measured 0 m and 7e-16 m/s


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.full((1, 5, 2), np.nan), "finite"),
        (np.full((1, 5, 2), np.inf), "finite"),
        (np.zeros((5, 2)), r"shape \(any, any, 2\)"),
        (np.zeros((1, 5, 3)), r"shape \(any, any, 2\)"),
        (np.zeros((1, 5, 2), dtype=complex), "real numbers"),
        (np.zeros((1, 5, 2), dtype=bool), "real numbers"),
        ([["a", "b"]], "real numbers"),
    ],
)
def test_rollout_rejects_bad_input(bad, message):
    with pytest.raises(ValueError, match=message):
        Simulator(SIM_ROBOT).rollout(bad)


@pytest.mark.parametrize(
    "call, arg",
    [("static_tip", np.zeros((2, 3))), ("inverse_static", np.zeros((2, 2))), ("static_tip", np.array([[np.nan, 0.0]]))],
)
def test_statics_reject_bad_input(call, arg):
    with pytest.raises(ValueError):
        getattr(Simulator(SIM_ROBOT), call)(arg)


@pytest.mark.parametrize("kwargs", [dict(gravity="sideways"), dict(order=-1), dict(substeps=0), dict(n_segments=2.5)])
def test_simulator_rejects_bad_options(kwargs):
    with pytest.raises(ValueError):
        Simulator(SIM_ROBOT, **kwargs)


def test_continuation_reaches_the_equilibrium_plain_newton_finds(monkeypatch):
    """Where Newton from the start wanders, gravity raised in eight steps reaches the same q."""
    sim = Simulator(HW_ROBOT, gravity="horizontal")
    u = np.array([[0.5, -0.3]])
    q_newton, _ = statics.equilibrium(sim, u)
    real, scales = statics._newton, []

    def wandering_once(sim, force, q, scale, tol, max_iter):
        scales.append(scale)
        return None if len(scales) == 1 else real(sim, force, q, scale, tol, max_iter)

    monkeypatch.setattr(statics, "_newton", wandering_once)
    q_continued, _ = statics.equilibrium(sim, u)
    assert scales == [1.0, *(np.arange(1, 9) / 8)]
    np.testing.assert_allclose(q_continued, q_newton, atol=1e-9)


def test_a_rod_that_gravity_folds_is_solved_by_continuation():
    """E x 0.1 of the horizontal hardware rod (calibrate_sag's softest bracket): plain Newton
    wanders there on some CPUs; the equilibrium found balances stiffness and gravity."""
    soft = dataclasses.replace(HW_ROBOT, youngs_modulus=0.1 * HW_ROBOT.youngs_modulus)
    sim = Simulator(soft, gravity="horizontal")
    q, _ = statics.equilibrium(sim, np.zeros((1, 2)))
    residual = sim.stiffness @ q[0] - statics.gravity_force(sim, q)[0]
    assert np.abs(residual).max() < 1e-9 * np.abs(sim.stiffness @ q[0]).max()
    assert sim.kinematics.tip_positions(q)[0, 2] < -0.1  # it sags by more than a third of its length
