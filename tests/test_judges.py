"""The referees of a real robot (softflow.studies.judges) on a system whose tip is known in closed
form: a linear response to the inputs' history, another offset per run (a recording session).
A judge fitted on other runs puts the recorded inputs near zero error, is blind to the scored
run's offset, grows with every known perturbation of the inputs, and is never fitted on what it
scores."""

import numpy as np
import pytest

from softflow.studies import judges

PERIOD = 0.01
STEPS = 6000  # 60 s a run


def smooth_inputs(rng, steps=STEPS, m=3):
    """White noise smoothed twice over 1 s, 20 degrees RMS per input: one stationary excitation,
    like the trunk's random runs."""
    white = rng.standard_normal((steps + 198, m))
    box = np.ones(100) / 100
    smooth = np.stack([np.convolve(np.convolve(w, box, "valid"), box, "valid") for w in white.T], 1)
    return 20 * smooth / smooth.std(0)  # (T, m)


RESPONSE = np.random.default_rng(0).normal(0, 1e-4, (len(judges.lags(PERIOD)), 3, 3))  # m per degree, per lag


def tip_of(u, offset):
    """The tip (T+1, 3): linear in the judge's own history of u, plus the run's offset (m)."""
    h = judges.histories(u, judges.lags(PERIOD)).reshape(len(u) + 1, -1, u.shape[1])  # (T+1, L, m)
    return np.einsum("tlm,lmk->tk", h, RESPONSE) + offset


@pytest.fixture(scope="module")
def runs():
    rng = np.random.default_rng(1)
    made = {}
    for name in ("a", "b", "c"):
        u = smooth_inputs(rng)
        made[name] = (u, tip_of(u, rng.normal(0, 0.01, 3)))  # sessions 1 cm apart
    return made


@pytest.fixture(scope="module")
def fitted(runs):
    return judges.fit_judges(runs, ["c"], PERIOD)


def test_a_judge_is_never_fitted_on_the_run_it_scores(runs, fitted):
    assert {(row["judge"], row["scores"]) for row in judges.provenance(fitted)} == {("ridge", "c"), ("kernel", "c")}
    assert all(row["fitted_on"] != row["scores"] for row in judges.provenance(fitted))
    assert sorted(row["fitted_on"] for row in judges.provenance(fitted) if row["judge"] == "kernel") == ["a", "b"]
    with pytest.raises(ValueError, match="fitted on other runs"):
        judges.fit("ridge", runs, "c", PERIOD)


@pytest.mark.parametrize("kind", judges.KINDS)
def test_the_recorded_inputs_are_judged_near_their_own_path_and_every_perturbation_farther(kind, runs, fitted):
    u, tip = runs["c"]
    judge = fitted[(kind, "c")]
    floor = judges.judged_errors(judge, u, tip, u, 100, 250).mean()
    motion = 1e3 * np.sqrt(np.mean(np.sum((tip - tip.mean(0)) ** 2, -1)))  # mm
    assert floor < (0.05 if kind == "ridge" else 0.1) * motion
    for family in ("delay", "noise"):
        errors = [
            judges.judged_errors(judge, u, tip, judges.perturbed(u, name), 100, 250).mean()
            for name in judges.perturbations()
            if name.startswith(family)
        ]
        assert floor < errors[0] and np.all(np.diff(errors) > 0), (family, floor, errors)  # growing with the size
    for name in ("scale 0.9", "scale 1.1"):
        assert judges.judged_errors(judge, u, tip, judges.perturbed(u, name), 100, 250).mean() > floor


@pytest.mark.parametrize("kind", judges.KINDS)
def test_the_scored_runs_session_offset_changes_nothing(kind, runs, fitted):
    u, tip = runs["c"]
    plan = judges.perturbed(u, "noise 2")
    judged = judges.judged_errors(fitted[(kind, "c")], u, tip, plan, 50, 250)
    moved = judges.judged_errors(fitted[(kind, "c")], u, tip + np.array([0.02, -0.01, 0.005]), plan, 50, 250)
    np.testing.assert_allclose(moved, judged, rtol=1e-9, atol=1e-9)


def test_the_perturbations_are_what_they_say():
    u = smooth_inputs(np.random.default_rng(2), 500)
    np.testing.assert_array_equal(judges.perturbed(u, "delay 5")[5:], u[:-5])
    np.testing.assert_array_equal(judges.perturbed(u, "delay 5")[:5], np.repeat(u[:1], 5, 0))
    noise = judges.perturbed(u, "noise 2") - u
    np.testing.assert_allclose(np.sqrt(np.mean(noise**2, 0)), 2.0)
    assert np.abs(np.diff(noise, axis=0)).max() < 0.5 * np.abs(noise).max()  # smooth, not white
    np.testing.assert_array_equal(judges.perturbed(u, "scale 1.1"), 1.1 * u)
    with pytest.raises(ValueError, match="perturbation must be one of"):
        judges.perturbed(u, "shift 3")


def test_a_history_holds_the_inputs_before_each_step():
    u = np.arange(20.0).reshape(10, 2)  # u[t] = (2t, 2t + 1)
    h = judges.histories(u, np.array([1, 3]))
    assert h.shape == (11, 4)
    np.testing.assert_array_equal(h[5], [8, 9, 4, 5])  # u[4], u[2]
    np.testing.assert_array_equal(h[0], [0, 1, 0, 1])  # u[0] before the start
