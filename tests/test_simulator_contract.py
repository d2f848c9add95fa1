"""What users of the simulator rely on: the numbers of the simulator before it was split
(golden file), equilibria that rollouts settle on, results that do not depend on how the
batch is scheduled, and clear errors for input that cannot be right."""

import numpy as np
import pytest
from make_sim_golden import GOLDEN, golden_outputs

from softflow.rod.dynamics import MIN_THREAD_CHUNK, Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT


def test_simulator_reproduces_the_golden_file_made_before_the_split():
    """Rollouts and equilibria to 1e-8 m: bit-identical on the machine that wrote the file, but
    BLAS kernels differ across CPUs (an AVX-512 Xeon gives rollouts 1.9e-9 m away, the old flat
    package as much as the new one), while any change of the mechanics moves them by far more.
    The Gauss-Newton results stop at |du| < 1e-10, so they are compared at that tolerance (the
    lift Jacobian, through a 1e-6 forward difference of gravity, differs by 1.5e-11)."""
    expected = np.load(GOLDEN)
    actual = golden_outputs()
    assert sorted(actual) == sorted(expected.files)
    for key in expected.files:
        solved = key.endswith(("inverse_static", "lift_u", "lift_jacobian"))
        np.testing.assert_allclose(actual[key], expected[key], rtol=0, atol=1e-10 if solved else 1e-8, err_msg=key)


@pytest.mark.parametrize("gravity", ["vertical", "horizontal"])
def test_a_rollout_under_constant_u_settles_on_the_static_tip(gravity):
    sim = Simulator(SIM_ROBOT, gravity=gravity)
    u = np.array([[1.5, -2.5]])
    X = sim.rollout(np.repeat(u[:, None], 1000, axis=1))  # 10 s: the first mode (zeta 0.11) decays ~1e-5
    settled = np.abs(X[0, -1, :3] - sim.static_tip(u)[0]).max()
    assert settled < 1e-4  # m; measured about 1e-6
    assert np.abs(X[0, 0, :3] - X[0, -1, :3]).max() > 0.05  # it really moved


def test_a_rollout_does_not_depend_on_threads_or_chunk_size():
    u = np.random.default_rng(3).uniform(-4, 4, (2 * MIN_THREAD_CHUNK + 1, 30, 2))  # two threads' worth
    reference = Simulator(SIM_ROBOT, threads=1, chunk_size=256).rollout(u)
    X = Simulator(SIM_ROBOT, threads=2).rollout(u)
    np.testing.assert_allclose(X, reference, rtol=0, atol=1e-12)
    for threads, chunk_size in ((2, 1), (2, 2), (1, 3)):
        X = Simulator(SIM_ROBOT, threads=threads, chunk_size=chunk_size).rollout(u[:5])
        np.testing.assert_allclose(X, reference[:5], rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(robot=None), "robot must be a softflow.rod.Robot"),
        (dict(chunk_size=0), "chunk_size must be an integer >= 1; got 0"),
        (dict(threads=0), "threads must be an integer >= 1; got 0"),
        (dict(dt="0.01"), "dt must be a positive number of seconds; got '0.01'"),
        (dict(dt=float("nan")), "dt must be a positive number"),
        (dict(dt=-0.01), "dt must be a positive number"),
    ],
)
def test_simulator_options_are_checked(kwargs, message):
    kwargs = {"robot": SIM_ROBOT, **kwargs}
    with pytest.raises(ValueError, match=message):
        Simulator(**kwargs)


def test_an_empty_batch_or_an_impossible_actuation_is_refused():
    sim = Simulator(SIM_ROBOT)
    with pytest.raises(ValueError, match="at least one episode"):
        sim.rollout(np.zeros((0, 5, 2)))
    with pytest.raises(ValueError, match=r"\|u\| = 4.24e\+03 N exceeds 14.4 N.*u in newtons\?"):
        sim.rollout(np.full((1, 5, 2), 3000.0))  # millinewtons
    with pytest.raises(ValueError, match="exceeds 14.4 N"):
        sim.static_tip(np.array([[15.0, 0.0]]))
    with pytest.raises(ValueError, match="at least one point"):
        sim.inverse_static(np.zeros((0, 3)))


@pytest.mark.parametrize(
    "point, nearest_mm",
    [
        ([120.0, 50.0, 0.0], r"\d{5,}\.\d mm"),  # millimetres for metres
        ([0.0, 0.0, 0.0], r"400\.0 mm"),  # the base: the arc start sits on a stationary point
        ([-0.3, 0.05, 0.0], r"\d+\.\d mm"),  # behind the base
    ],
)
def test_inverse_statics_of_an_unreachable_point_names_the_nearest_equilibrium(point, nearest_mm):
    sim = Simulator(SIM_ROBOT)
    reachable = sim.static_tip(np.array([[1.0, -1.0]]))
    with pytest.raises(
        ValueError,
        match=r"p\[1\] = .* is outside the static workspace: the nearest equilibrium "
        r"found \(\|u\| <= 14.4 N\) is " + nearest_mm,
    ):
        sim.inverse_static(np.concatenate([reachable, [point]]))


def test_inverse_statics_still_fits_points_a_few_centimetres_off_the_static_surface():
    sim = Simulator(HW_ROBOT, gravity="horizontal")
    u = np.array([[2.0, 1.0]])
    off = sim.static_tip(u) + np.array([[0.0, 0.03, 0.0]])  # a moving tip is off the static surface
    fitted = sim.inverse_static(off)
    assert np.linalg.norm(sim.static_tip(fitted) - off) < np.linalg.norm(sim.static_tip(u) - off)


def test_stacked_frames_are_the_separate_calls_bit_for_bit():
    """A step stacks q and q +- eps qd into one frames call (what costs is the sequential product
    over segments, per call); every row is computed alone, so the bits are those of three calls."""
    kinematics = Simulator(SIM_ROBOT).kinematics
    q, qd = np.random.default_rng(3).normal(size=(2, 5, kinematics.nq))
    here, plus, minus, eps = kinematics.frames_along(q, qd, 1e-3)
    for name, value in kinematics.frames(q).items():
        np.testing.assert_array_equal(here[name], value, err_msg=name)
    np.testing.assert_array_equal(plus, kinematics.frames(q + eps * qd)["positions"])
    np.testing.assert_array_equal(minus, kinematics.frames(q - eps * qd)["positions"])
