"""two_segment: an inverse that is many-valued by construction. The two-segment rod's four inputs
hold its 3-D tip at a point with a whole curve of u (the middle disk says which), so a model shown
the tip alone cannot know u, while one shown the tip and the middle disk nearly can. Table I's
models trained on the tip, and three of them on the tip and the middle disk, each scored open loop
on the rod's shapes, random references and 3-D paths, per step on u, and on where its u takes the
tip in one step of the true simulator (a u unlike the true one may still move the tip right).
Fixed before any paper cell ran (docs/assumptions.md, "The two-segment study").
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from softflow import data, training
from softflow.control.planning import Controller, load_controller, pad_plans, plan_all, score
from softflow.data.dataset import tip_of
from softflow.data.references import (
    PATH3D_STARTS,
    STRUCTURED,
    Reference,
    cached_references,
    depth_circle_reference,
    random_references,
    shape_reference,
)
from softflow.models.checkpoints import checkpoint_path
from softflow.models.specs import model_spec
from softflow.profiles import FIXED_BUDGET, PROFILES, Profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import TWO_SEGMENT_ROD, rod_folder
from softflow.store import atomic_write, cached_arrays
from softflow.studies import ambiguity
from softflow.studies.study import FLOOR, Grid, floor_rows, held_out_plan, training_spec, unnamed

GRAVITY = "vertical"
FLOOR_OBSERVATION = "simulator"  # the floor's cell: it learns on the true simulator, it observes nothing


@dataclass(frozen=True, kw_only=True)
class TwoSegmentGrid(Grid):
    data: Profile  # whose data knobs make the two-segment rod's datasets
    observations: dict[str, tuple[str, ...]]  # observation: models trained on it
    ilc_iterations: int  # the floor's trials (0: no floor)
    shapes: tuple[str, ...]
    n_random: int
    paths: int  # 3-D paths, of PATH3D_STARTS
    draws: int
    check_episodes: int  # held-out episodes of the tip-step check


TWO_SEGMENT = {  # per profile: the data, the grid and the references
    "ci": TwoSegmentGrid(
        data=replace(PROFILES["ci"], n_episodes=64),  # the four-input rollouts were most of notebook 12's ci run
        observations={"tip": ("mlp", "rf")},
        seeds=(0,),
        ilc_iterations=0,  # no floor
        shapes=("circle", "char_C"),
        n_random=2,
        paths=1,
        draws=4,
        check_episodes=1,
        train=FIXED_BUDGET["ci"],
    ),
    "paper": TwoSegmentGrid(
        data=PROFILES["paper"],
        observations={"tip": ("mlp", "lstm", "transformer", "rf", "rf-fwd"), "tip+disk": ("mlp", "rf", "rf-fwd")},
        seeds=(0, 1, 2),
        ilc_iterations=40,
        shapes=STRUCTURED,
        n_random=24,
        paths=len(PATH3D_STARTS),
        draws=16,
        check_episodes=20,
        train=FIXED_BUDGET["paper"],  # 20 000 steps, no early stop
    ),
}


def cells(profile_name: str) -> list[dict]:
    grid = TWO_SEGMENT[profile_name]
    floor = [dict(study="two_segment", model=FLOOR, seed=0, observation=FLOOR_OBSERVATION)]
    return (floor if grid.ilc_iterations else []) + [
        dict(study="two_segment", model=model, seed=seed, observation=observation)
        for observation, names in grid.observations.items()
        for model in names
        for seed in grid.seeds
    ]


def references(sim: Simulator, profile_name: str, observation: str = "tip", names=None) -> list[Reference]:
    """The profile's references for the two-segment rod as ``observation`` sees them: its shapes,
    Rand1..Rand<n_random>, then its 3-D paths; ``names``: only those, in that order (the random
    set, a static lift of minutes when not cached, is made only when one of it is asked for).
    Each is made once with the middle disk and cached; "tip" keeps the tip's state of it."""
    grid = TWO_SEGMENT[profile_name]
    random_set = names is None or any(str(name).startswith("Rand") for name in names)
    made = [
        *(cached_references(sim, f"two-segment-{name}", _shape(name))[0] for name in grid.shapes),
        *(cached_references(sim, f"two-segment-random-{grid.n_random}", _random(grid.n_random)) if random_set else []),
        *(cached_references(sim, f"two-segment-path3d-{a}", _path(a))[0] for a in PATH3D_STARTS[: grid.paths]),
    ]
    if names is not None:
        by_name = {r.name: r for r in made}
        unknown = [name for name in names if name not in by_name]
        if unknown:
            raise ValueError(
                f"no reference {unknown} in the {profile_name!r} two-segment grid; expected some of {list(by_name)}"
            )
        made = [by_name[name] for name in names]
    return made if observation == "tip+disk" else [replace(r, states=tip_of(r.states)) for r in made]


def _shape(name: str):
    def least_norm_shape(sim):
        return [shape_reference(sim, name, observation="tip+disk")]

    return least_norm_shape


def _random(n: int):
    def random_sines(sim):
        return random_references(sim, n, observation="tip+disk")

    return random_sines


def _path(start: float):
    def depth_circle(sim):
        return [depth_circle_reference(sim, start, observation="tip+disk")]

    return depth_circle


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model and seed trained on the tip, or on the tip and the middle disk, with the study's
    fixed budget: its u error and the spread of a flow's draws on the held-out episodes, where its
    u takes the tip in one step, and its tracking of every reference (z = 0; a flow also with the
    mean of its draws); or the ILC floor on every reference. One row per reference and plan."""
    grid, sim = TWO_SEGMENT[profile_name], Simulator(TWO_SEGMENT_ROD, GRAVITY)
    scored = references(sim, profile_name)
    if cell["model"] == FLOOR:
        rows, trials = floor_rows(sim, scored, grid.ilc_iterations)
        return [unnamed(row, ilc_best_trial=int(t)) for row, t in zip(rows, trials)]
    observation = cell["observation"]
    dataset = _dataset(profile_name, observation)
    model, checkpoint = trained_model(cell["model"], profile_name, observation, cell["seed"], workdir, device, dataset)
    controller = Controller(model, cell["model"], robot=TWO_SEGMENT_ROD, gravity=GRAVITY, workspace_margin=None)
    measured = dict(
        **ambiguity.cached_spread(dataset, workdir),
        **ambiguity.per_step_scores(controller, dataset, grid.draws),
        **tip_steps(controller, dataset, sim, grid.draws, _true_steps(grid, dataset, sim, workdir)),
        best_val=float(checkpoint["best_val"]),
        epochs_run=int(checkpoint["epochs_run"]),
        train_minutes=float(checkpoint["wall_seconds"]) / 60,
    )
    plans = {"zero": {}}
    if controller.generative:
        plans[f"mean-of-{grid.draws}"] = dict(noise="seeded", n_samples=grid.draws)
    rows = tracking(controller, references(sim, profile_name, observation), scored, sim, plans)
    return [unnamed(row, **measured) for row in rows]


def tracking(controller: Controller, planned_on, scored, sim: Simulator, plans: dict) -> list[dict]:
    """Table I's rows for each way of planning in ``plans`` ({name: plan options}): each reference
    planned as the controller observes it (``planned_on``, e.g. with the middle disk's path), every
    plan run from rest in one batched rollout (the simulator is batch-invariant), the tip scored
    against ``scored`` (the same references, tip only); each row names its ``plan``."""
    planned = [plan_all(controller, planned_on, **options)[0] for options in plans.values()]
    _, padded = pad_plans([u for plan in planned for u in plan])
    achieved = sim.rollout(padded).reshape(len(plans), len(scored), -1, 6)  # (plans, R, T_max + 1, 6)
    return [
        dict(score(controller.name, r, u, X[: r.n_steps + 1], sim.dt), plan=name)
        for name, plan, outcomes in zip(plans, planned, achieved)
        for r, u, X in zip(scored, plan, outcomes)
    ]


def tip_steps(controller: Controller, dataset: data.Dataset, sim: Simulator, draws: int, truth: dict) -> dict:
    """Where the controller's u takes the tip in one step of the true simulator from the true state,
    against the true next tip: RMS in mm over the transitions of ``truth`` (``_true_steps``, the
    dataset's first test episodes). A flow also with one seeded draw and with the mean of ``draws``
    draws (clipped as a plan is): the mean of two valid u need not be one."""
    check = replace(dataset, test=dataset.test[: len(truth["q"])])
    planned, _ = held_out_plan(controller, check)
    row = dict(tip_step_mm=_tip_step(sim, truth, planned))
    if controller.generative:
        samples = np.clip(controller.sample(check.states[check.test], draws), -controller.u_limit, controller.u_limit)
        row.update(
            tip_step_mm_draw=_tip_step(sim, truth, samples[0]),
            tip_step_mm_mean_of_draws=_tip_step(sim, truth, samples.mean(0)),
        )
    return row


def _tip_step(sim: Simulator, truth: dict, u) -> float:
    """RMS distance (mm) between the tip one sample after (q, qd) under u (E, T, m) and the true next tip."""
    nq, m = sim.nq, u.shape[-1]
    reached, _ = sim.integrate(u.reshape(-1, 1, m), truth["q"].reshape(-1, nq), truth["qd"].reshape(-1, nq))
    error = sim.tip_positions(reached[:, 1]) - truth["tip"].reshape(-1, 3)
    return 1e3 * float(np.sqrt(np.mean(np.sum(error**2, axis=-1))))


def _true_steps(grid: TwoSegmentGrid, dataset: data.Dataset, sim: Simulator, workdir: Path) -> dict:
    """The true (q, qd) (E, T, nq) before each transition of the first ``check_episodes`` test
    episodes and the tip after it (E, T, 3), re-simulated from their u; cached per dataset (both
    observations share it)."""
    episodes = dataset.test[: grid.check_episodes]

    def compute():
        q, qd = sim.integrate(dataset.u[episodes], sim.rest_q(), np.zeros(sim.nq))  # (E, T+1, nq) each
        return dict(q=q[:, :-1], qd=qd[:, :-1], tip=dataset.states[episodes, 1:, :3])

    stem = data.dataset_path(grid.data, TWO_SEGMENT_ROD, GRAVITY).stem
    return cached_arrays(workdir, "true-steps", dict(dataset=stem, episodes=episodes.tolist()), compute)


def _dataset(profile_name: str, observation: str) -> data.Dataset:
    grid = TWO_SEGMENT[profile_name]
    return data.load_dataset(grid.data, TWO_SEGMENT_ROD, GRAVITY, observation=observation, progress=False)


def trained_model(
    name: str,
    profile_name: str,
    observation: str,
    seed: int,
    workdir: Path,
    device: str = "cpu",
    dataset: data.Dataset | None = None,
):
    """(model, checkpoint) of ``name`` as the study's cell trains it: on the profile's dataset of
    ``observation`` (``dataset``, when already loaded) with the study's fixed budget, into
    ``workdir`` (found there when it exists)."""
    return training.ensure_trained(
        name,
        TWO_SEGMENT[profile_name].budget(profile_name),
        _dataset(profile_name, observation) if dataset is None else dataset,
        TWO_SEGMENT_ROD,
        GRAVITY,
        seed=seed,
        root=_models_root(workdir, profile_name, observation),
        device=device,
    )


def trained_controllers(
    workdir: Path, profile_name: str, observation: str, models, seed: int = 0, *, train_missing: bool = False
) -> list[Controller]:
    """The controllers of ``models`` (names) that the study's cells trained for ``observation`` into
    ``workdir`` (the sweep's folder of this study), each planning as the study plans: extrapolation
    is measured, not refused. Where this machine has not trained a seed-0 paper model of the tip,
    its shipped copy (``ship_models``) stands in; other models not trained here are left out (a
    fresh clone has the study's rows, not its models), or trained now as their cells train them
    with ``train_missing`` (the ci models: seconds each)."""
    root, rod = _models_root(workdir, profile_name, observation), rod_folder(TWO_SEGMENT_ROD, GRAVITY)
    shipped = profile_name == "paper" and observation == "tip" and seed == 0  # ship_models' copies
    controllers = []
    for name in dict.fromkeys(models):
        path = checkpoint_path(name, profile_name, rod, seed=seed, root=root)
        if not path.is_file() and shipped:
            path = checkpoint_path(name, profile_name, rod, shipped=True)
        if not path.is_file() and train_missing:
            trained_model(name, profile_name, observation, seed, workdir)
        if path.is_file():
            controller = load_controller(path, robot=TWO_SEGMENT_ROD, gravity=GRAVITY)
            controller.workspace_margin = None
            controllers.append(controller)
    return controllers


def ship_models(workdir: Path, models=None) -> list[Path]:
    """Copy the study's seed-0 paper models of the tip (``models``: names, default every one
    trained so far, with RF-FWD's surrogate, unless one is already shipped and the study used it)
    from ``workdir`` (the sweep's folder of this study, or of one that trains its models the
    same way: the one_step study's)
    into checkpoints/, where ``load_controller(name, robot=TWO_SEGMENT_ROD)`` finds them current
    (``Profile.rod_train``). A shipped file is never overwritten: one that differs is a
    ValueError. Returns the shipped paths."""
    root, rod = _models_root(workdir, "paper", "tip"), rod_folder(TWO_SEGMENT_ROD, GRAVITY)
    names = TWO_SEGMENT["paper"].observations["tip"] if models is None else models
    shipped = []
    for name in dict.fromkeys(n for model in names for n in (*model_spec(model).requires, model)):
        source, target = (
            checkpoint_path(name, "paper", rod, root=root),
            checkpoint_path(name, "paper", rod, shipped=True),
        )
        if not source.is_file() and (models is None or (name not in names and target.is_file())):
            continue  # not trained here: every model the study has so far, or a surrogate already shipped
        if not source.is_file():
            raise ValueError(f"no seed-0 {name!r} of the study in {source.parent}; run its cell first")
        weights = source.read_bytes()
        if not target.exists():
            with atomic_write(target) as f:
                f.write(weights)
        elif target.read_bytes() != weights:
            raise ValueError(f"{target} is shipped and differs from {source}: remove it by hand to ship again")
        shipped.append(target)
    return shipped


def _models_root(workdir: Path, profile_name: str, observation: str) -> Path:
    return Path(workdir) / "models" / profile_name / observation


def models(cell: dict, profile_name: str) -> dict:
    if cell["model"] == FLOOR:
        return {}
    return training_spec(cell["model"], TWO_SEGMENT[profile_name].budget(profile_name), seed=cell["seed"])
