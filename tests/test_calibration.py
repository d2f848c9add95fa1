"""Calibration against hand-checkable cases: the identity for a rod identified as the model,
the identified rod's statics hit the model's tips, a lead undoes a motor lag, and on the twin
a calibrated plan tracks better than the plan made for the model rod."""

import numpy as np
import pytest

from softflow import hardware
from softflow.hardware.calibration import RAMP_SECONDS, Calibration
from softflow.rod import statics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT

GAP = hardware.RealityGap(youngs_modulus=-0.15, density=0.10)


@pytest.fixture(scope="module")
def horizontal():
    model = Simulator(HW_ROBOT, "horizontal")
    return model, Calibration(model, Simulator(GAP.plant_robot(HW_ROBOT), "horizontal"))


def test_the_calibrated_rods_table_ships(horizontal, tmp_path, monkeypatch):
    """The identified rod's static table (3 721 static solves) ships in cache/: found under
    today's key, it is read, not built (tests/test_sim.py builds one)."""
    monkeypatch.setattr(statics, "DATA_DIR", tmp_path)
    _, calibration = horizontal
    calibration.rod.static_table()
    assert not any(tmp_path.iterdir())


def test_a_rod_identified_as_the_model_changes_nothing():
    model = Simulator(HW_ROBOT, "vertical")
    u = np.random.default_rng(0).uniform(-3, 3, (2, 150, 2))
    np.testing.assert_allclose(Calibration(model, model).actuation(u), u, atol=1e-6)


def test_the_identified_rod_holds_its_tip_where_the_model_rod_would_after_the_ramp(horizontal):
    model, calibration = horizontal
    u = np.random.default_rng(1).uniform(-2, 2, (1, 2 * int(RAMP_SECONDS / DT), 2))
    mapped = calibration.actuation(u)
    np.testing.assert_array_equal(mapped[0, 0], u[0, 0])  # nothing at the first step: the ramp
    after = slice(int(RAMP_SECONDS / DT), None)
    wanted, _ = model.static_table().tip(u[0, after])
    reached, J = calibration.rod.static_table().tip(mapped[0, after])
    unmapped, _ = calibration.rod.static_table().tip(u[0, after])
    # as close as that rod's reachable surface allows (least squares: the residual is normal to it)
    assert np.abs(np.einsum("tij,ti->tj", J, reached - wanted)).max() < 1e-9
    assert np.abs(reached - wanted).max() < 0.1 * np.abs(unmapped - wanted).max()
    assert np.abs(mapped[0, after] - u[0, after]).max() > 0.3  # N: the softer, heavier rod needs other inputs
    one_step = calibration.actuation(u[0, 130:131], first_step=130)  # the loop's call, one step at a time
    np.testing.assert_allclose(one_step, mapped[0, 130:131], atol=1e-12)


def test_a_command_lead_undoes_the_motor_lag():
    sim = Simulator(HW_ROBOT, "vertical")
    t = np.arange(200) * DT
    u = np.stack([2 * np.sin(2 * np.pi * 1.0 * t), np.zeros_like(t)], -1)[None]
    ideal = hardware.CablePlant(HW_ROBOT, "vertical").replay(hardware.cable_commands(u, sim))["states"]
    lagging = hardware.CablePlant(HW_ROBOT, "vertical", hardware.RealityGap(motor_lag=0.02))
    plain = lagging.replay(hardware.cable_commands(u, sim))["states"]
    led = lagging.replay(hardware.cable_commands(u, sim, lead=0.02))["states"]
    assert np.abs(led - ideal)[..., :3].max() < 0.2 * np.abs(plain - ideal)[..., :3].max()
    stepper = hardware.StepCommands(sim, lead=0.02)
    np.testing.assert_allclose(
        np.array([stepper(u_t) for u_t in u[0]]), hardware.cable_commands(u, sim, lead=0.02)[0], atol=1e-12
    )
    with pytest.raises(ValueError, match="lead"):
        hardware.cable_commands(u, sim, lead=-0.01)


def test_a_calibrated_open_loop_tracks_the_twin_better(horizontal):
    model, calibration = horizontal
    from softflow.data.references import hardware_references

    class StaticController:  # the quasi-static plan of the model rod: a stand-in for a learned model
        def plan(self, states, **_):
            return model.static_table().inverse(states[1:, :3])

    reference = hardware_references(model)[2]  # the circle
    runs = {
        name: hardware.run_twin(StaticController(), [reference], model, GAP, calibration=c)[0]
        for name, c in (("model", None), ("calibrated", calibration))
    }
    # a third off at least: the static part of the gap goes, the quasi-static plan's own lag stays
    assert runs["calibrated"].rmse_true_mm[0] < 2 / 3 * runs["model"].rmse_true_mm[0]


def test_a_calibration_needs_one_configuration():
    with pytest.raises(ValueError, match="configuration"):
        Calibration(Simulator(HW_ROBOT, "vertical"), Simulator(HW_ROBOT, "horizontal"))
