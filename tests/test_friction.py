"""Cable friction in the twin: capstan tensions with a Dahl state, a hysteresis loop that grows
with the friction coefficient, and, without friction, the frictionless plant to the bit.

tests/data/twin_golden.npz was written by the plant before friction existed: the commands of
``golden_u`` through the model rod (HW_ROBOT, vertical and horizontal) replayed across
TYPICAL_GAP (states, q, tensions).
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from softflow import hardware
from softflow.hardware.plant import CablePlant
from softflow.rod.cables import cable_actuation
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT, TWO_SEGMENT_ROD
from softflow.store import content_key

GOLDEN = Path(__file__).parent / "data" / "twin_golden.npz"


def golden_u():
    """The actuation the golden replay was made from: (2, 60, 2) N."""
    t = np.arange(60) * 0.01
    return np.stack(
        [
            np.stack([3.0 * np.sin(2 * np.pi * 1.3 * t), 2.0 * np.cos(2 * np.pi * 0.7 * t) - 2.0], -1),
            np.stack([-2.5 * np.sin(2 * np.pi * 0.9 * t), 3.5 * np.sin(2 * np.pi * 1.7 * t)], -1),
        ]
    )


class PlantBeforeFriction(CablePlant):
    """The plant's step as it was before cable friction, line for line: with mu = 0 the capstan
    mean factor is exactly 1 and the Dahl state is never read, so the plant must do exactly this
    arithmetic."""

    def step(self, command):
        sim, h = self.sim, DT / self.substeps
        follow = 1.0 - np.exp(-h / self.gap.motor_lag) if self.gap.motor_lag > 0 else 1.0
        tensions = np.zeros_like(self.motor)
        for _ in range(self.substeps):
            self.motor = self.motor + follow * (command - self.motor)
            tension = self.stiffness * np.maximum(self._cable_stretch(self.motor, self.q + 0.5 * h * self.qd), 0.0)
            self.q, self.qd = (
                x[:, -1] for x in sim.integrate(cable_actuation(tension, self.robot)[:, None], self.q, self.qd)
            )
            tensions += tension / self.substeps
        return tensions


@pytest.mark.parametrize("gravity", ["vertical", "horizontal"])
def test_without_friction_the_plant_replays_as_before_bit_for_bit(gravity):
    golden = np.load(GOLDEN)
    tag = f"hw_{gravity}"
    commands = hardware.cable_commands(golden_u(), Simulator(HW_ROBOT, gravity))
    # Against the file, made on another CPU: numpy's SIMD kernels (AVX2 or AVX-512) round the last
    # bits differently and the rollout amplifies them; 1e-9 m is far below any change of the plant.
    np.testing.assert_allclose(commands, golden[f"{tag}_commands"], rtol=1e-6, atol=1e-9)
    # any sliding length: without friction it is never read
    for gap in (hardware.TYPICAL_GAP, dataclasses.replace(hardware.TYPICAL_GAP, sliding_length=1e-3)):
        now = CablePlant(HW_ROBOT, gravity, gap).replay(commands)
        before = PlantBeforeFriction(HW_ROBOT, gravity, gap).replay(commands)
        for name in ("states", "q", "tensions"):
            np.testing.assert_array_equal(now[name], before[name])  # the same arithmetic, to the bit
            np.testing.assert_allclose(now[name], golden[f"{tag}_{name}"], rtol=1e-6, atol=1e-9)


def test_every_term_keys_a_gap():
    """A cache keyed by a gap changes with any of its terms, the friction terms included."""
    assert hardware.TYPICAL_GAP.parameters() == dataclasses.asdict(hardware.TYPICAL_GAP)
    assert hardware.FRICTION_GAP.parameters() == {**hardware.TYPICAL_GAP.parameters(), "cable_friction": 0.15}
    longer = dataclasses.replace(hardware.FRICTION_GAP, sliding_length=1e-3)
    assert content_key(longer.parameters()) != content_key(hardware.FRICTION_GAP.parameters())
    assert dataclasses.replace(hardware.FRICTION_GAP, cable_friction=0.0) == hardware.TYPICAL_GAP
    assert "cable_friction" not in hardware.GAP_TERMS  # the closed_loop study's grid keeps its cells


def test_friction_terms_are_checked():
    with pytest.raises(ValueError, match=r"cable_friction must be a friction coefficient >= 0 .*got -0\.1"):
        hardware.RealityGap(cable_friction=-0.1)
    with pytest.raises(ValueError, match=r"sliding_length must be a length > 0 m"):
        hardware.RealityGap(cable_friction=0.1, sliding_length=0.0)
    with pytest.raises(ValueError, match="cable_friction must be finite"):
        hardware.RealityGap(cable_friction=float("nan"))


def test_capstan_tensions_of_a_hand_worked_case():
    """mu = 0.25 over 0.4 rad: a = 0.1; sliding towards the motor the anchored end carries
    2 N e^-0.1 = 1.809675 N, the mean along the cable 2 N (1 - e^-0.1) / 0.1 = 1.903252 N;
    sliding away the ratio inverts; relaxed (z = 0) the cable is uniform."""
    anchored, mean = hardware.capstan_tensions(2.0, 0.4, 0.25, np.array([1.0, -1.0, 0.0]))
    np.testing.assert_allclose(anchored, [1.809675, 2.210342, 2.0], atol=1e-6)
    np.testing.assert_allclose(mean, [1.903252, 2.103418, 2.0], atol=1e-6)
    # the series below |a| = 1e-4 meets the closed form
    a = np.array([0.99e-4, 1.01e-4])
    _, mean = hardware.capstan_tensions(1.0, 1.0, 1.0, a)
    np.testing.assert_allclose(mean, -np.expm1(-a) / a, rtol=1e-13)


def test_the_dahl_state_saturates_sliding_and_does_not_care_for_the_rate():
    length = 5e-4
    z = hardware.dahl_state(np.zeros(1), np.array([10 * length]), length)
    np.testing.assert_allclose(z, 1 - np.exp(-10.0), rtol=1e-14)
    back = hardware.dahl_state(np.ones(1), np.array([-2 * length]), length)
    np.testing.assert_allclose(back, -1 + 2 * np.exp(-2.0), rtol=1e-14)
    slow = np.zeros(1)
    for _ in range(100):  # the same slide in a hundred steps
        slow = hardware.dahl_state(slow, np.array([0.03 * length]), length)
    np.testing.assert_allclose(slow, hardware.dahl_state(np.zeros(1), np.array([3 * length]), length), rtol=1e-12)
    np.testing.assert_array_equal(hardware.dahl_state(np.array([0.3]), np.array([0.0]), length), [0.3])  # at rest


def test_a_sliding_cable_obeys_the_capstan_bound():
    """Hand-worked on an arc: without gravity the rod bends into a circular arc whose chord
    from the base to the tip makes half its bend angle theta with the rod's axis, so
    theta = 2 atan2(y, x) from the tip alone. Cable 1 (at +y) is pulled in by a slow ramp of u1,
    so it slides towards its motor and its anchored end carries e^(-mu theta) of its tension at
    the motor; cables 2 and 3 are paid out, sliding away, and carry e^(+mu theta)."""
    mu = 0.3
    gap = hardware.RealityGap(cable_friction=mu)
    sim = Simulator(HW_ROBOT, "none")
    t = np.arange(300) * DT
    u = np.zeros((1, 300, 2))
    u[0, :, 0] = 4.0 * (1 - np.cos(np.pi * t / 6.0)) / 2  # 0 -> 4 N over 6 s, at 2 N and rising at 3 s
    plant = CablePlant(HW_ROBOT, "none", gap)
    plant.replay(hardware.cable_commands(u, sim))
    x, y = plant.tip_state()[0, :2]
    theta = 2 * np.arctan2(y, x)
    assert theta > 0.2  # a real bend, so the bound is far from 1
    # sliding, not sticking: cable 1 slid 17 sliding lengths (its stretch and its path), cables
    # 2 and 3 only their path's 7, so their state is 2 e^-7 short of -1 (a ratio 2e-4 lower)
    np.testing.assert_allclose(plant.friction_state[0], [1, -1, -1], atol=3e-3)
    tensions = plant.tensions()
    ratio = tensions["anchored"][0] / tensions["base"][0]
    np.testing.assert_allclose(ratio, np.exp([-mu * theta, mu * theta, mu * theta]), rtol=3e-4)
    assert ratio[0] == pytest.approx(np.exp(-mu * theta), rel=1e-5)


@pytest.fixture(scope="module")
def loops():
    """The vertical twin's hysteresis loops for friction coefficients 0 (TYPICAL_GAP), 0.15
    (FRICTION_GAP) and 0.3, the rest of the gap typical, in one batch (mu = 0.05, 0.83 % of the
    reach when measured, is in docs/assumptions.md)."""
    return hardware.hysteresis_loops(hardware.TYPICAL_GAP, (0.0, 0.15, 0.3))


def test_loops_in_one_batch_are_the_loops_drawn_alone_bit_for_bit():
    """A rod without friction in a batch with friction takes the capstan's arithmetic, whose
    mean factor is then exactly 1: the frictionless plant's tension, to the bit."""
    period = 0.4  # s: short, the bits are what is compared
    batched = hardware.hysteresis_loops(hardware.TYPICAL_GAP, (0.3, 0.0), period=period)
    for mu, loop in batched.items():
        alone = hardware.hysteresis_loop(dataclasses.replace(hardware.TYPICAL_GAP, cable_friction=mu), period=period)
        for field in ("u", "gap", "down", "up"):
            np.testing.assert_array_equal(getattr(loop, field), getattr(alone, field))
        assert (loop.width, loop.reach) == (alone.width, alone.reach)
    assert not np.array_equal(batched[0.3].gap, batched[0.0].gap)  # each rod rubbed with its own friction


def test_without_friction_there_is_no_loop(loops):
    """What is left without friction is the rod's ringing after the rate's part is removed,
    0.16 % of the reach when measured; FRICTION_GAP's is more than ten times wider."""
    loop = loops[0.0]
    assert loop.reach == pytest.approx(0.084, abs=0.005)  # HW_ROBOT reaches about 84 mm at 4 N
    assert loop.width < 2.5e-3
    assert loops[0.15].width > 10 * loop.width


def test_the_loop_widens_with_friction_and_friction_gaps_is_a_few_per_cent(loops):
    widths = [loops[mu].width for mu in (0.0, 0.15, 0.3)]
    assert widths[0] < widths[1] < widths[2]
    assert 0.01 < widths[1] < 0.05  # FRICTION_GAP: a few per cent of the reach
    friction = loops[0.15]
    assert (friction.gap[np.abs(friction.u) > 2.0] > 0).all()  # the down branch lies above the up branch
    assert hardware.FRICTION_GAP.cable_friction == 0.15


def test_hysteresis_loop_refuses_what_it_cannot_cycle():
    with pytest.raises(ValueError, match="period of at least"):
        hardware.hysteresis_loop(hardware.NO_GAP, period=0.01)
    with pytest.raises(ValueError, match="two-input rod"):
        hardware.hysteresis_loop(hardware.NO_GAP, robot=TWO_SEGMENT_ROD)
    with pytest.raises(ValueError, match="each once"):
        hardware.hysteresis_loops(hardware.NO_GAP, (0.1, 0.1))
    with pytest.raises(ValueError, match="coefficients >= 0"):
        CablePlant(HW_ROBOT, "vertical", cable_friction=[0.1, -0.1])
    with pytest.raises(ValueError, match="a friction for each of 2 rods; got 3"):
        CablePlant(HW_ROBOT, "vertical", cable_friction=[0.1, 0.2]).reset(3)
