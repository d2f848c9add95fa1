"""The closed loop on a rig made of the simulator itself: without correction it sends the
open-loop plan, integral action removes a constant disturbance, the watchdog holds the
command while the marker is lost, learning across repetitions shrinks the error, and bad
input is refused before the first command."""

import numpy as np
import pytest

from softflow import control
from softflow.control import closed_loop
from softflow.data.references import Reference, shape_reference
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT


class SimRig:
    """The simulation rod as a rig: u (plus a constant disturbance) held for DT, the exact tip
    as a frame every step, none (NaN) at the steps in ``blind``; ``measure`` raises at ``fail``."""

    def __init__(self, sim, disturbance=(0.0, 0.0), blind=(), fail=()):
        self.sim, self.disturbance, self.blind, self.fail = sim, np.asarray(disturbance), set(blind), set(fail)
        self.q, self.qd, self.steps, self.sent = sim.rest_q()[None], np.zeros((1, sim.nq)), 0, []

    def command(self, u):
        q, qd = self.sim.integrate((np.asarray(u) + self.disturbance)[None, None], self.q, self.qd)
        self.q, self.qd = q[:, -1], qd[:, -1]
        self.steps += 1
        self.sent.append(np.array(u))

    def measure(self):
        if self.steps in self.fail:
            raise OSError("camera unplugged")
        tip = self.sim.tip_positions(self.q)[0]
        return [(self.steps * DT, np.full(3, np.nan) if self.steps in self.blind else tip)]


@pytest.fixture(scope="module")
def sim():
    return Simulator(SIM_ROBOT)


@pytest.fixture(scope="module")
def controller(trained):
    return control.Controller(trained("mlp")[0], "mlp")


def hold(sim, u_target=(1.0, -0.5), steps=600):
    """Stay at the equilibrium of u_target from the first sample on."""
    tip = sim.static_tip(np.array([u_target]))[0]
    states = np.tile(np.concatenate([tip, np.zeros(3)]), (steps + 1, 1))
    return Reference("hold", "shape", states, np.arange(steps + 1) >= steps - 50)


def test_without_correction_the_loop_sends_the_plan(sim, controller):
    reference = shape_reference(sim, "circle", size=0.04)
    rig = SimRig(sim)
    run = closed_loop.run_loop(controller, reference, rig.measure, rig.command, correction=closed_loop.NO_CORRECTION)
    np.testing.assert_allclose(run.u, controller.plan(reference.states), atol=1e-4)
    assert (run.clipped, run.watchdog_events, run.lost_frames) == (0, 0, 0)
    np.testing.assert_allclose(run.estimates[1:, :3], sim.rollout(run.u[None])[0, 1:-1, :3], atol=2e-3)


def test_integral_action_removes_a_constant_disturbance(sim, controller):
    reference = hold(sim)
    final = {}
    for name, correction in (("none", closed_loop.NO_CORRECTION), ("pi", closed_loop.PI())):
        rig = SimRig(sim, disturbance=(0.4, 0.0))
        closed_loop.run_loop(controller, reference, rig.measure, rig.command, correction=correction)
        final[name] = np.linalg.norm(sim.tip_positions(rig.q)[0] - reference.states[-1, :3])
    assert final["none"] > 0.01 and final["pi"] < 0.1 * final["none"]


def test_the_watchdog_holds_while_the_marker_is_lost_and_survives_a_failing_camera(sim, controller):
    reference = shape_reference(sim, "circle", size=0.04)
    rig = SimRig(sim, blind=range(100, 130), fail={150, 151})
    run = closed_loop.run_loop(controller, reference, rig.measure, rig.command, watchdog_frames=5)
    assert run.watchdog_events == 1 and run.lost_frames == 30 + 2
    assert run.held_steps == 30 - 5
    held = np.array(rig.sent[106:130])
    assert np.all(held == held[0]) and np.array_equal(held[0], rig.sent[105])


def test_learning_across_repetitions_shrinks_the_error(sim, controller):
    reference = shape_reference(sim, "circle", size=0.04)
    runs = closed_loop.learn_by_repetition(
        controller,
        reference,
        lambda: SimRig(sim, disturbance=(0.2, -0.2)),
        repetitions=3,
        correction=closed_loop.NO_CORRECTION,
    )
    assert len(runs) == 3
    rmse = []
    for run, _ in runs:
        achieved = sim.rollout((run.u + np.array([0.2, -0.2]))[None])[0]
        rmse.append(np.sqrt(np.mean(np.sum((achieved[:, :3] - reference.states[:, :3])[reference.mask] ** 2, 1))))
    assert rmse[2] < 0.5 * rmse[0]


def test_learning_leaves_the_start_transient_of_a_displaced_rig_alone(sim, controller):
    """A rig that starts away from the reference's first state (a reality gap's sag) shows an
    error no input removes at once; learnt, it pumps the first commands (closed_loop.SETTLE)."""
    reference = shape_reference(sim, "circle", size=0.04)
    displaced = sim.static_q(np.array([[1.0, 0.0]]))

    def make_rig():
        rig = SimRig(sim)
        rig.q = displaced.copy()
        return rig

    early = int(closed_loop.SETTLE[0] / DT)
    change = {}
    for label, settle in (("ramped", closed_loop.SETTLE), ("from the start", (0.0, DT))):
        (first, _), (second, _) = closed_loop.learn_by_repetition(
            controller, reference, make_rig, repetitions=2, settle=settle, correction=closed_loop.NO_CORRECTION
        )
        change[label] = np.sqrt(np.mean((second.u[:early] - first.u[:early]) ** 2))
    assert change["ramped"] < 0.3 * change["from the start"]
    with pytest.raises(ValueError, match="settle"):
        closed_loop.learn_by_repetition(controller, reference, make_rig, settle=(1.0, 0.5))


def test_bad_input_is_refused_before_the_first_command(sim, controller):
    reference = shape_reference(sim, "circle", size=0.04)
    in_mm = Reference("mm", "shape", reference.states * 1000, reference.mask)
    rig = SimRig(sim)
    with pytest.raises(ValueError, match="training standard deviations"):
        closed_loop.run_loop(controller, in_mm, rig.measure, rig.command)
    assert rig.sent == []
    with pytest.raises(ValueError, match="feedforward"):
        closed_loop.run_loop(controller, reference, rig.measure, rig.command, feedforward=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="PI gains"):
        closed_loop.PI(-1.0, 0.0)
