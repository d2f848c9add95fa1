"""Data, references, the floor and the study for the two-segment rod (four inputs, a 3-D tip):
its excitation draws every input, its dataset carries the middle disk, its y-z lift is the
least-norm equilibrium, its 3-D paths are reachable where the one-segment rod's are not, and
the paper's one-segment datasets stay exactly what they were."""

import dataclasses
import warnings

import numpy as np
import pytest

from softflow import control, data, store, training
from softflow.control import floor
from softflow.control.planning import evaluate_many
from softflow.data import dataset as dataset_module
from softflow.data import references
from softflow.models import checkpoints
from softflow.profiles import PROFILES, Profile, TrainConfig, get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT, TWO_SEGMENT_ROD, U_MAX
from softflow.studies import sweep, two_segment

TINY = Profile("tiny", n_episodes=6, episode_seconds=0.3)  # the one-segment fingerprint's
FEW = Profile("few", n_episodes=10, episode_seconds=0.3)  # one episode to validate on, one to test
SMALL = Profile("two-small", n_episodes=10, episode_seconds=1.0)
QUICK = TrainConfig(epochs=2, steps_per_epoch=30, batch_size=128, warmup_steps=10, val_samples=200, patience=2)


@pytest.fixture(scope="module")
def sim():
    return Simulator(TWO_SEGMENT_ROD)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    folder = tmp_path_factory.mktemp("data")
    return {
        observation: data.load_dataset(FEW, TWO_SEGMENT_ROD, data_dir=folder, observation=observation, progress=False)
        for observation in dataset_module.OBSERVATIONS
    }


# Fingerprints of the paper's two-input excitation, taken from the code before it drew m inputs
# (the ci profile had 200 episodes then; the golden keeps that size).
EXCITATION = {
    "ci": (
        200,
        "dataset-ci-269b0ce0d43adaae",
        2710.016659771551,
        326273.6111442601,
        [3.5041588243414785, 0.6402664166222041, 1.9471225881288636, 1.347579224288167, -0.39874890479794833],
    ),
    "paper": (
        3000,
        "dataset-paper-8df80c0b23ad822f",
        -9350.52360415183,
        4716834.442212062,
        [-0.463464914384323, -1.3505996302468433, -3.4372256929110683, 0.706447695654727, 0.1101306266124143],
    ),
}


@pytest.mark.parametrize("name", ["ci", "paper"])
def test_the_shipped_datasets_keep_their_keys_and_excitation(name):
    n_episodes, key, total, squares, first = EXCITATION[name]
    profile = dataclasses.replace(get_profile(name), n_episodes=n_episodes)
    assert data.dataset_path(profile).stem == key
    u = data.polynomial_excitation(profile.n_episodes, 500, np.random.default_rng(profile.seed))  # (E, 500, 2)
    np.testing.assert_allclose([u.sum(), np.square(u).sum()], [total, squares], rtol=1e-12)
    flat = u.reshape(-1)
    np.testing.assert_allclose(flat[:: len(flat) // 12 + 1][:5], first, rtol=1e-12)


def test_the_one_segment_dataset_is_what_it_was(tmp_path):
    """The tiny dataset's key (every rod field keys it), and its arrays and states as the code
    before the two-segment data made them (states to 1e-7: another CPU's SIMD kernels round the
    last bits differently, and the excitation's rollouts amplify that to about 1e-8)."""
    made = data.load_dataset(TINY, data_dir=tmp_path, progress=False)
    assert made.key == "dataset-tiny-8ca531bcdfdba1ce"
    assert sorted(np.load(tmp_path / f"{made.key}.npz").files) == ["states", "test", "train", "u", "val"]
    np.testing.assert_allclose([made.states.sum(), np.abs(made.states).sum()], [35.85247527012816, 285.19322665928615])
    np.testing.assert_allclose(
        made.states[:, -1].reshape(-1)[::5][:4],
        [0.33736947637754794, 0.012867743531730468, -0.5691422408743776, -0.08624714751753576],
        rtol=0,
        atol=1e-7,
    )
    u = data.sum_of_sines_excitation(24, 500, 1000, u_max=3.0, frequencies=(0.1, 1.0))  # Table I's random family
    np.testing.assert_allclose([u.sum(), np.square(u).sum()], [218.67538072928926, 48132.799201861395], rtol=1e-12)


def test_every_input_gets_its_own_polynomial():
    u = data.polynomial_excitation(400, 500, np.random.default_rng(0), n_inputs=4)
    assert u.shape == (400, 500, 4)
    peaks = np.abs(u).max(1)  # (E, 4)
    assert peaks.min() >= 0.5 - 1e-12 and peaks.max() <= U_MAX
    assert np.all(peaks.max(0) > 3.9)
    assert np.abs(np.corrcoef(peaks.T) - np.eye(4)).max() < 0.2  # drawn independently


def test_the_dataset_carries_the_middle_disk(tiny, sim):
    tip, both = tiny["tip"], tiny["tip+disk"]
    assert tip.u.shape == (10, 30, 4) and tip.states.shape == (10, 31, 6) and both.states.shape == (10, 31, 12)
    assert (tip.dims.inputs, tip.dims.position, both.dims.position) == (4, 3, 6)
    assert both.key == f"{tip.key}-tip+disk" and tip.key == data.dataset_path(FEW, TWO_SEGMENT_ROD).stem
    np.testing.assert_array_equal(dataset_module.tip_of(both.states), tip.states)
    np.testing.assert_allclose(
        tip.states[:2], sim.rollout(tip.u[:2]), rtol=0, atol=1e-12
    )  # the tip as a rollout gives it

    q, qd = sim.integrate(tip.u[:2], sim.rest_q(), np.zeros(sim.nq))  # (2, 31, nq)
    disk = both.states[:2]
    np.testing.assert_array_equal(disk[..., 3:6], sim.disk_positions(q)[..., 0, :])
    # the disk's velocity J qd against a central difference of its exact position along qd
    eps = 1e-4 / np.maximum(np.abs(qd).max(-1, keepdims=True), 1e-12)  # at rest: any step
    along = (sim.disk_positions(q + eps * qd) - sim.disk_positions(q - eps * qd)) / (2 * eps[..., None])
    np.testing.assert_allclose(disk[..., 9:12], along[..., 0, :], rtol=0, atol=1e-8)  # m/s; peaks near 0.3 m/s
    np.testing.assert_allclose(
        disk[..., 6:9], along[..., 1, :], rtol=0, atol=1e-7
    )  # the rollout's own: 1.6e-8 relative


def test_an_observation_needs_a_disk_and_a_known_name(tmp_path):
    with pytest.raises(ValueError, match="observation 'tip\\+disk' needs a rod of several segments"):
        data.load_dataset(TINY, SIM_ROBOT, data_dir=tmp_path, observation="tip+disk", progress=False)
    with pytest.raises(ValueError, match=r"observation must be one of \['tip', 'tip\+disk'\]; got 'disk'"):
        data.load_dataset(TINY, TWO_SEGMENT_ROD, data_dir=tmp_path, observation="disk", progress=False)


YZ = np.array([[0.05, 0.0], [0.08, -0.06], [-0.1, 0.03], [0.0, 0.12]])  # m, about the rest tip (0, 0)


def test_the_lift_is_the_least_norm_equilibrium_at_its_yz(sim):
    lift = references.least_norm_lift(sim, YZ)
    tip = lift.positions[:, -1]
    np.testing.assert_allclose(tip[:, 1:], YZ, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sim.static_tip(lift.u), tip, rtol=0, atol=1e-12)
    # its depth is the gentlest: the least-norm u that reaches the lifted 3-D point is the same u
    np.testing.assert_allclose(sim.inverse_static(tip), lift.u, rtol=0, atol=1e-8)  # measured 3e-10 N
    # and any other u that puts the tip at that y-z needs more force
    other = sim.static_tip(np.array([[2.0, 0.5, -1.0, 1.5]]))
    assert np.linalg.norm(references.least_norm_lift(sim, other[:, 1:]).u) < np.linalg.norm([2.0, 0.5, -1.0, 1.5])


def test_lift_rates_are_the_derivative_of_the_lift(sim):
    """d position / d(y, z) of the tip and the middle disk from the least-norm conditions, against
    a central difference of the lift."""
    lift, step = references.least_norm_lift(sim, YZ[:2]), 1e-5
    for k in range(2):
        shift = step * np.eye(2)[k]
        plus, minus = references.least_norm_lift(sim, YZ[:2] + shift), references.least_norm_lift(sim, YZ[:2] - shift)
        difference = (plus.positions - minus.positions) / (2 * step)
        np.testing.assert_allclose(lift.rates[..., k], difference, rtol=0, atol=1e-6)  # measured 2e-7


def test_the_3d_paths_deepest_points_are_reached_and_the_one_segment_rod_cannot_follow():
    """Where the depth wave is deepest (45 degrees past the start) the least-norm equilibrium reaches
    the point within the actuation range; a rod of one segment has only the lift's depth there."""
    sim = Simulator(TWO_SEGMENT_ROD)
    angles = np.deg2rad(np.array(references.PATH3D_STARTS) + 45)
    yz = references.DEPTH_RADIUS * np.stack([np.cos(angles), np.sin(angles)], -1)  # the rest tip is (0, 0)
    lift = references.least_norm_lift(sim, yz)
    target = lift.positions[:, -1] - [references.DEPTH_SWING, 0, 0]
    deep = references.least_norm_statics(sim, target, [0, 1, 2], lift.u)
    assert np.abs(deep.positions[:, -1] - target).max() <= references.REACH_TOLERANCE
    assert np.abs(deep.u).max() <= 3.0  # measured 2.8 N: a newton of the range left for the dynamics
    np.testing.assert_allclose(sim.inverse_static(target), deep.u, rtol=0, atol=1e-8)
    with pytest.raises(ValueError, match="the 3-D path leaves the static workspace of 'sim': its nearest"):
        references.depth_circle_reference(Simulator(SIM_ROBOT))


def shipped_references(sim, kind, build):
    """The committed copy (``cache/``) of a cached_references entry, by today's key; None if absent."""
    spec = references.references_spec(sim, kind, build.__name__)
    return store.read_npz(store.cache_file(store.SHIPPED_CACHE, f"references-{kind}", spec))


def test_the_shipped_references_are_what_their_key_computes(sim):
    """The study's shapes and 3-D paths and the ci grid's random references are committed under
    today's key (minutes of least-norm static solves a fresh clone's notebook 12 skips); samples of
    the shipped circle are the least-norm lift of their y-z, tip and middle disk."""
    grid = two_segment.TWO_SEGMENT
    builds = {f"two-segment-{name}": two_segment._shape(name) for name in grid["paper"].shapes}
    builds |= {f"two-segment-path3d-{a}": two_segment._path(a) for a in references.PATH3D_STARTS}
    builds[f"two-segment-random-{grid['ci'].n_random}"] = two_segment._random(grid["ci"].n_random)
    assert [kind for kind, build in builds.items() if shipped_references(sim, kind, build) is None] == []
    circle = shipped_references(sim, "two-segment-circle", builds["two-segment-circle"])
    samples = circle["states_0"][np.flatnonzero(circle["mask_0"])[::200]]  # (K, 12): tip, disk, their velocities
    lift = references.least_norm_lift(sim, samples[:, 1:3])
    np.testing.assert_allclose(lift.positions[:, 1], samples[:, :3], rtol=0, atol=1e-8)  # this CPU's last bits
    np.testing.assert_allclose(lift.positions[:, 0], samples[:, 3:6], rtol=0, atol=1e-8)


def test_the_floor_learns_with_four_inputs(sim):
    """From the least-norm quasi-static start tens of millimetres off, through the damped inverse."""
    reference = data.random_references(sim, 1, seconds=1.0, seed=7, u_max=1.0)
    plans, reached, history = floor.ilc_plans(sim, reference, iterations=3)
    assert plans[0].shape == (100, 4) and reached[0].shape == (101, 6)
    np.testing.assert_allclose(sim.rollout(plans[0][None])[0], reached[0])  # the plan reaches what it reports
    assert history[0, 0] > 20.0 and history.min() < history[0, 0] / 10  # measured 53.1 -> 3.3 mm


def test_the_floor_start_runs_linear_over_a_step_whose_least_norm_fit_does_not_converge(sim):
    """A far lateral point of a paper random reference (Rand9) where the least-norm iteration
    cycles: the start leaves it out and runs linear between its neighbours."""
    states = np.zeros((21, 6))  # steps 0, 10 and 19 are fitted (every 10th and the last)
    states[1:, :3] = sim.static_tip(np.array([[0.5, 0.0, 0.5, 0.0]]))
    states[20, :3] = sim.static_tip(np.array([[0.0, 0.5, 0.0, 0.5]]))[0]
    states[11, :3] = [0.1082, 0.2355, 0.2184]  # no fit in 50 steps (nor in 400)
    reference = data.Reference("far", "random", states, np.ones(21, bool))
    (start,), (inverse,) = floor.least_norm_start(sim, [reference])
    assert np.isfinite(start).all() and np.isfinite(inverse).all()
    np.testing.assert_allclose(start[10], start[0] + (start[19] - start[0]) * 10 / 19, rtol=1e-12)
    np.testing.assert_allclose(sim.static_tip(start[[0, 19]])[:, 1:], states[[1, 20], 1:3], atol=1e-9)


@pytest.mark.parametrize("profile", ["ci", "paper"])
def test_the_rods_own_budget_is_the_one_its_study_trains_with(profile):
    """So the study's seed-0 models, shipped, are what load_controller and `softflow train
    --robot two` look for; every other rod keeps its profile's per-model budgets."""
    study = two_segment.TWO_SEGMENT[profile].budget(profile)
    for model in ("mlp", "lstm", "transformer", "rf", "rf-fwd", "forward"):
        assert get_profile(profile).train_config(model, TWO_SEGMENT_ROD.name) == study.train_config(model)
        assert get_profile(profile).train_config(model, SIM_ROBOT.name) == get_profile(profile).train_config(model)
    assert study.train_config("mlp") == study.train_config("lstm")  # one budget for every model


def test_a_two_segment_model_loads_plans_and_steps(tiny, sim, tmp_path, monkeypatch):
    """A model of the rod is trained with the rod's own budget (``Profile.rod_train``, as its study
    trains them) and load_controller finds it current by that identity; a model of the tip and the
    middle disk plans a tip+disk reference and refuses one in millimetres."""
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path / "trained")
    rods_own = (("two", dataclasses.replace(QUICK, epochs=1)),)
    monkeypatch.setitem(PROFILES, "ci", dataclasses.replace(FEW, name="ci", train=QUICK, rod_train=rods_own))
    profile = get_profile("ci")
    dataset = data.load_dataset(profile, TWO_SEGMENT_ROD, data_dir=tmp_path / "data", progress=False)
    _, checkpoint = training.ensure_trained("mlp", profile, dataset, TWO_SEGMENT_ROD)
    assert checkpoint["epochs_run"] == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # current: no staleness warning
        controller = control.load_controller("mlp", "ci", TWO_SEGMENT_ROD)
    assert controller.plan(dataset.states[0]).shape == (30, 4)

    both = tiny["tip+disk"]
    model, _ = training.train("rf", both, QUICK, tmp_path / "rf.pt", progress=False)
    flow = control.Controller(model, "rf", robot=TWO_SEGMENT_ROD)
    reference = both.states[both.test[0]]  # (31, 12)
    u = flow.plan(reference)
    assert u.shape == (30, 4) and np.isfinite(u).all()
    np.testing.assert_allclose(flow.step(reference[4], reference[5]), u[4], atol=1e-4)
    with pytest.raises(ValueError, match="reference tip position .* training standard deviations"):
        flow.plan(1e3 * reference)  # millimetres
    made = references.random_references(sim, 1, seconds=0.3, observation="tip+disk")[0]
    np.testing.assert_array_equal(
        dataset_module.tip_of(made.states), references.random_references(sim, 1, seconds=0.3)[0].states
    )


def test_the_study_runs_in_process_and_scores_every_observation(sim, tmp_path, monkeypatch):
    """The ci grid's machinery on a small dataset and one random reference: a model of each
    observation, every column the pre-registration lists."""
    grid = dataclasses.replace(
        two_segment.TWO_SEGMENT["ci"],
        data=SMALL,
        observations={"tip": ("mlp",), "tip+disk": ("rf",)},
        shapes=(),
        n_random=1,
        paths=0,
        draws=3,
        train=QUICK,
    )
    monkeypatch.setitem(two_segment.TWO_SEGMENT, "ci", grid)
    for module in (dataset_module, references):  # its dataset and references: never in the repository's data/
        monkeypatch.setattr(module, "DATA_DIR", tmp_path / "data")
    result = sweep.run_sweep("two_segment", "ci", client=None, device="cpu", root=tmp_path, progress=False)
    assert result.failures == []
    rows = result.rows
    assert sorted(rows.groupby(["observation", "model", "plan"]).size().index.tolist()) == [
        ("tip", "mlp", "zero"),
        ("tip+disk", "rf", "mean-of-3"),
        ("tip+disk", "rf", "zero"),
    ]
    assert {"rmse_mm", "phase_lag_s", "input_energy", "mae_u4", "u_rmse_test", "tip_step_mm", "cell_seconds"} <= set(
        rows.columns
    )
    assert {"conditional_spread", "conditional_spread_floor", "best_val", "train_minutes"} <= set(rows.columns)
    flows = rows[rows.model == "rf"]
    for column in ("u_rmse_draw", "u_rmse_mean_of_draws", "draw_spread", "spread_error_spearman"):
        assert flows[column].notna().all()
    assert flows[["tip_step_mm_draw", "tip_step_mm_mean_of_draws"]].notna().all().all()
    assert (rows.tip_step_mm > 0).all() and (rows.rmse_mm > 0).all()

    # the notebook's models are the cells' own: found where the cells trained them, planned as the study plans
    found = two_segment.trained_controllers(tmp_path / "two_segment", "ci", "tip", ["mlp", "rf"])
    assert [c.name for c in found] == ["mlp"] and found[0].workspace_margin is None  # no rf on the tip was trained
    measured, _ = evaluate_many(found, two_segment.references(sim, "ci"), sim)
    study = rows[rows.model == "mlp"].set_index("reference").rmse_mm
    np.testing.assert_allclose(measured.set_index("reference").rmse_mm, study.loc[measured.reference], rtol=1e-9)

    # the one-step check from the true state with the true u lands on the true next tip
    dataset = data.load_dataset(SMALL, TWO_SEGMENT_ROD, progress=False)
    truth = two_segment._true_steps(grid, dataset, sim, tmp_path)
    assert two_segment._tip_step(sim, truth, dataset.u[dataset.test[:1]]) < 1e-6  # mm


def test_references_by_name_come_in_that_order_without_the_random_lift(sim, tmp_path, monkeypatch):
    """Named shapes and paths of the paper grid come from the shipped cache; its 24 random
    references (not shipped: a static lift of minutes) are made only when one is asked for."""
    monkeypatch.setattr(references, "DATA_DIR", tmp_path)  # nothing cached on this machine's side
    monkeypatch.setattr(two_segment, "_random", lambda n: pytest.fail("the random set was built"))
    picked = two_segment.references(sim, "paper", "tip", names=["path3d-0", "circle"])
    assert [r.name for r in picked] == ["path3d-0", "circle"]
    assert picked[1].states.shape[-1] == 6  # the tip's state of the cached tip-and-disk reference
    with pytest.raises(ValueError, match=r"no reference \['hexagon'\] in the 'paper' two-segment grid"):
        two_segment.references(sim, "paper", names=["hexagon"])


def test_a_fresh_clone_plans_with_the_shipped_seed_0_models_of_the_tip(tmp_path):
    """The study's folder holds no model: the shipped seed-0 tip models stand in (paper, tip,
    seed 0 only), each planning as the study plans."""
    names = ["mlp", "rf-fwd"]
    shipped = two_segment.trained_controllers(tmp_path, "paper", "tip", names)
    assert [c.name for c in shipped] == names and all(c.workspace_margin is None for c in shipped)
    assert two_segment.trained_controllers(tmp_path, "paper", "tip+disk", names) == []
    assert two_segment.trained_controllers(tmp_path, "paper", "tip", names, seed=1) == []
    assert two_segment.trained_controllers(tmp_path, "ci", "tip", names) == []
