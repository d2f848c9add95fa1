"""The studies ``python -m softflow sweep`` runs: each a grid of independent cells and the
function that turns one cell into result rows. A new study is one entry in ``STUDIES``.

table1: Tables I and II with confidence intervals. Every model of the paper at its own
    budget, three training seeds (seed 0 is the shipped model), scored open loop on the
    eight shapes and 24 random references (Rand1..Rand4 are the paper's), plus the ILC floor.
protocol: Table I under each choice the paper leaves open (``protocol``), with the seed-0
    models (no retraining) and the ILC floor; the conditions were fixed before any ran.
data_size: issue 15's first question, fixed before any ran: is it the prior or being
    generative that helps? MLP, MLP-Physical, RF and RF-Physical trained on 100 / 300 / 1000 /
    3000 episodes, 3 seeds, the same 20 000 optimiser steps each (no early stop), scored on
    Table I's references and per step on the held-out test episodes.
closed_loop: Table III extended: the twin's RF-FWD open loop and in closed loop (``loop``):
    integral correction, the model conditioned on the estimate instead of the reference,
    learning across repetitions, each also calibrated on an identification run
    (``calibration``); camera latency 0 / 33 / 66 ms and 10 % lost frames; open / calibrated
    open / closed / calibrated closed under each doubled gap term.
ambiguity: issue 15's inverses that are genuinely ambiguous, fixed before any ran: the MLP
    against RF and RF-FWD on each dataset variant (``variants``: a folded workspace, a weakly
    damped rod under piecewise-constant actuation, positions only, finite-difference
    velocities with 0 / 0.5 / 2 mm position noise), per step and open loop.
fwd_lambda: RF-FWD's consistency weight, fixed before any ran: lambda 0 / 0.03 / 0.1 / 0.3 / 1
    at the full budget, 3 seeds, with what the consistency term sees (the surrogate's error,
    the one-step endpoint estimate against a short Euler rollout).
twin_burst: where the twin's loops break: the burst circle continued to a 0.2 s period, open
    loop, closed loop and learning across repetitions, scored per revolution.
"""
from __future__ import annotations

import copy
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from scipy import stats as scipy_stats

from . import ambiguity, data, floor, hardware, identification, loop, stress, train
from .calibration import Calibration
from .control import Controller, SaturationWarning, evaluate, score
from .profiles import Profile, TrainConfig, get_profile
from .protocol import Protocol, apply, coverage, shapes_at
from .report import FLOOR
from .robots import HW_ROBOT, SIM_ROBOT
from .sim import Simulator
from .store import cache_file, cached_arrays
from .trajectories import (STRUCTURED, cached_references, evaluation_references, hardware_burst_reference,
                           hardware_references, random_references)
from .variants import VARIANTS, variant_dataset


@dataclass(frozen=True)
class Study:
    """A grid of cells and the function that turns one cell into measurements.

    ``cells(profile_name)``: JSON-able dicts, each naming its study, model, seed and condition.
    ``run_cell(cell, profile_name, device, workdir, key)``: a dict of JSON-able measurements,
    or a list of them (one row each, e.g. per reference), that depends on nothing but its
    arguments (its rows are cached by them). ``workdir`` is the study's folder, for files
    cells share (datasets) or own (name those by ``key``).
    ``version``: bump it when a change alters the numbers run_cell returns; every cached row
    of the study is then recomputed.
    """

    cells: Callable[[str], list[dict]]
    run_cell: Callable[[dict, str, str, Path, str], dict | list[dict]]
    version: int = 1


# ---------------------------------------------------------------------------- smoke
SMOKE_DATA = Profile("smoke", n_episodes=20, episode_seconds=1.0)  # 16 / 2 / 2 episodes: train / val / test


def _smoke_cells(profile_name: str) -> list[dict]:
    return [dict(study="smoke", model="mlp", hidden=16, seed=seed, condition="tiny") for seed in (0, 1)]


def _smoke_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> dict:
    """A tiny MLP on a tiny dataset, scored per step on the test episodes: seconds per cell,
    the same for every profile (it tries the machinery, not the science)."""
    dataset = data.load_dataset(SMOKE_DATA, data_dir=workdir / "data", progress=False)  # shared; safe to race
    config = TrainConfig(epochs=2, steps_per_epoch=20, batch_size=64, warmup_steps=5, val_samples=200,
                         seed=cell["seed"])
    model, checkpoint = train.train(cell["model"], dataset, config, workdir / "models" / f"{key}.pt",
                                    model_kwargs={"hidden": cell["hidden"]}, device=device, progress=False)
    n_steps = dataset.u.shape[1]
    episodes, steps = np.repeat(dataset.test, n_steps), np.tile(np.arange(n_steps), len(dataset.test))
    window = torch.as_tensor(train.gather_windows(dataset.states, episodes, steps, model.context), dtype=torch.float32)
    with torch.no_grad():
        u_hat = model.predict(window).numpy()
    return dict(best_val=float(checkpoint["best_val"]), epochs_run=int(checkpoint["epochs_run"]),
                u_rmse=float(np.sqrt(np.mean((u_hat - dataset.u[episodes, steps]) ** 2))))


# ---------------------------------------------------------------------------- table1
TABLE1 = {  # per profile: the grid, and the references it is scored on
    "ci": dict(models=("mlp", "rf"), seeds=(0, 1), shapes=("circle", "char_S"), n_random=4, ilc_iterations=8),
    "paper": dict(models=("mlp", "lstm", "transformer", "rf", "rf-physical", "rf-fwd"), seeds=(0, 1, 2),
                  shapes=STRUCTURED, n_random=24, ilc_iterations=40),
}
EXTRA_RANDOM_SEED = 1001  # Rand5.. (Rand1..Rand4 are the paper's, seed 1000)


def table1_references(sim: Simulator, profile_name: str):
    """The profile's Table I references: its shapes, then Rand1..Rand<n_random> (cached)."""
    grid = TABLE1[profile_name]
    paper_set = evaluation_references(sim)
    shapes = [r for r in paper_set if r.name in grid["shapes"]]
    random = [r for r in paper_set if r.family == "random"][: grid["n_random"]]
    extra = grid["n_random"] - len(random)
    if extra > 0:
        random += cached_references(sim, f"random-extra-{extra}", _more_random(extra, first=len(random) + 1))
    return shapes + random


def _more_random(n: int, first: int):
    def more_random(sim):
        made = random_references(sim, n, seed=EXTRA_RANDOM_SEED)
        return [replace(r, name=f"Rand{first + k}") for k, r in enumerate(made)]
    return more_random


def _table1_cells(profile_name: str) -> list[dict]:
    grid = TABLE1[profile_name]
    return [dict(study="table1", model=FLOOR, seed=0)] + [dict(study="table1", model=model, seed=seed)
                                                          for model in grid["models"] for seed in grid["seeds"]]


def _table1_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model and seed trained (or the shipped model reused) and scored on every reference;
    or the ILC floor on every reference. One row per reference."""
    profile, sim = get_profile(profile_name), Simulator(SIM_ROBOT)
    references = table1_references(sim, profile_name)
    if cell["model"] == FLOOR:
        rows, trials = _floor_rows(sim, references, TABLE1[profile_name]["ilc_iterations"])
        return [_unnamed(row, ilc_best_trial=int(t)) for row, t in zip(rows, trials)]
    dataset = data.load_dataset(profile, progress=False)
    model, checkpoint = train.ensure_trained(cell["model"], profile, dataset, seed=cell["seed"],
                                             root=workdir / "models" / profile_name, device=device)
    results, _ = evaluate(Controller(model, cell["model"]), references, sim)
    trained = dict(best_val=float(checkpoint["best_val"]), epochs_run=int(checkpoint["epochs_run"]),
                   train_minutes=float(checkpoint["wall_seconds"]) / 60)
    return [_unnamed(row, **trained) for row in results.to_dict("records")]


def _floor_rows(sim: Simulator, references, iterations: int, start_q=None):
    """The ILC floor's scored row for each reference, and the trial that gave it."""
    plans, reached, history = floor.ilc_plans(sim, references, iterations=iterations, start_q=start_q)
    return [score(FLOOR, r, u, X) for r, u, X in zip(references, plans, reached)], np.argmin(history, axis=0)


def held_out_plan(controller: Controller, dataset: data.Dataset) -> tuple[np.ndarray, float]:
    """The controller's plan for the dataset's held-out test episodes and its u error (N, RMS
    over steps and both inputs), the per-step error every study reports. Planned without the
    workspace check, whatever the controller's margin (a held-out paper episode lies 10 training
    standard deviations out: the studies measure extrapolation, they do not refuse it), and
    without the saturation warning (the clipped plan is what is judged)."""
    unchecked = copy.copy(controller)
    unchecked.workspace_margin = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)
        planned = unchecked.plan(dataset.states[dataset.test])
    return planned, float(np.sqrt(np.mean((planned - dataset.u[dataset.test]) ** 2)))


def _unnamed(row: dict, **more) -> dict:
    """A scored row without its model name (the cell names it), with ``more`` columns."""
    return {**{k: v for k, v in row.items() if k != "model"}, **more}


# ---------------------------------------------------------------------------- protocol
PROTOCOLS = {  # condition -> the protocol it scores with; "table1" is Table I's
    "table1": Protocol(),
    "approach-scored": Protocol(approach="scored"),
    "on-path": Protocol(approach="on-path"),
    "px-constant": Protocol(lift="px-constant"),
    "zero-velocity": Protocol(lift="zero-velocity"),
    "finite-difference": Protocol(lift="finite-difference"),
    "z-seeded": Protocol(noise="seeded"),
    "z-fresh": Protocol(noise="fresh"),
    **{f"speed-{v:g}": Protocol(speed=v) for v in (0.3, 0.5, 0.75, 1.0, 1.5)},
}
PROTOCOL_GRID = {
    "ci": dict(conditions=("table1", "zero-velocity", "z-fresh", "speed-0.5"), ilc_iterations=4),
    "paper": dict(conditions=tuple(PROTOCOLS), ilc_iterations=15),  # shapes settle within 10 trials
}
WITH_RANDOM = ("table1", "z-seeded", "z-fresh")  # conditions that change something on Rand1..Rand4


def _protocol_cells(profile_name: str) -> list[dict]:
    models = (*TABLE1[profile_name]["models"], FLOOR)
    return [dict(study="protocol", model=model, seed=0, condition=condition)
            for condition in PROTOCOL_GRID[profile_name]["conditions"] for model in models
            if not (model == FLOOR and PROTOCOLS[condition].noise != "zero")]  # the floor draws no noise


def protocol_references(sim: Simulator, profile_name: str, condition: str):
    """The references a condition scores, before the protocol is applied: the profile's shapes
    at the condition's speed, and Rand1..Rand4 where the condition changes them."""
    protocol = PROTOCOLS[condition]
    shapes = shapes_at(sim, TABLE1[profile_name]["shapes"], protocol.speed)
    random = [r for r in evaluation_references(sim) if r.family == "random"] if condition in WITH_RANDOM else []
    return shapes + random


def _protocol_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """A seed-0 model (or the floor) scored under one protocol; each row carries the
    reference's coverage by the training states."""
    profile, sim, protocol = get_profile(profile_name), Simulator(SIM_ROBOT), PROTOCOLS[cell["condition"]]
    references, start_q = apply(sim, protocol_references(sim, profile_name, cell["condition"]), protocol)
    dataset = data.load_dataset(profile, progress=False)
    covered = dict(zip((r.name for r in references), coverage(references, dataset)))
    if cell["model"] == FLOOR:
        rows, _ = _floor_rows(sim, references, PROTOCOL_GRID[profile_name]["ilc_iterations"], start_q)
    else:
        model, _ = train.ensure_trained(cell["model"], profile, dataset, device=device)
        controller = Controller(model, cell["model"])
        options = dict(noise=protocol.noise) if controller.generative else {}
        rows = evaluate(controller, references, sim, start_q=start_q, **options)[0].to_dict("records")
    return [_unnamed(row, coverage=covered[row["reference"]], speed=protocol.speed) for row in rows]


# ---------------------------------------------------------------------------- data size
DATA_SIZE = {
    "ci": dict(sizes=(50, 200), models=("mlp", "mlp-physical"), seeds=(0,),
               train=TrainConfig(epochs=3, steps_per_epoch=100, batch_size=256, warmup_steps=20, val_samples=2000,
                                 patience=3)),
    "paper": dict(sizes=(100, 300, 1000, 3000), models=("mlp", "mlp-physical", "rf", "rf-physical"), seeds=(0, 1, 2),
                  train=TrainConfig(epochs=40, steps_per_epoch=500, patience=40)),  # 20 000 steps, no early stop
}


def _size_cells(profile_name: str) -> list[dict]:
    grid = DATA_SIZE[profile_name]
    return [dict(study="data_size", model=model, seed=seed, episodes=size)
            for size in grid["sizes"] for model in grid["models"] for seed in grid["seeds"]]


def _size_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model trained on the first ``episodes`` episodes of the profile's dataset with the
    study's fixed budget, scored open loop on Table I's references and per step on the
    held-out test episodes (the same for every size)."""
    profile, sim = get_profile(profile_name), Simulator(SIM_ROBOT)
    dataset = data.subset(data.load_dataset(profile, progress=False), cell["episodes"])
    config = replace(DATA_SIZE[profile_name]["train"], seed=cell["seed"])
    path = workdir / "models" / profile_name / f"{cell['model']}-n{cell['episodes']}-seed{cell['seed']}.pt"
    model, checkpoint = train.train(cell["model"], dataset, config, path, device=device, progress=False)
    controller = Controller(model, cell["model"], workspace_margin=None)  # few episodes: extrapolation is measured
    _, per_step = held_out_plan(controller, dataset)
    results, _ = evaluate(controller, table1_references(sim, profile_name), sim)
    return [_unnamed(row, u_rmse_test=per_step, best_val=float(checkpoint["best_val"]))
            for row in results.to_dict("records")]


# ---------------------------------------------------------------------------- ambiguity
# Fixed before any ran (issue 15 section 3): every variant of ``variants.VARIANTS`` with its
# own 1000 episodes, the MLP against RF and RF-FWD, 3 seeds, data_size's 20 000 optimiser steps
# (RF-FWD's surrogate the same), scored on Table I's references (made on the variant's rod)
# and per step on the variant's held-out episodes; flows also planned with the mean of 16 draws.
AMBIGUITY = {
    "ci": dict(variants=("paper", "position-only"), models=("mlp", "rf"), seeds=(0,), episodes=60, draws=8,
               train=DATA_SIZE["ci"]["train"]),
    "paper": dict(variants=tuple(VARIANTS), models=("mlp", "rf", "rf-fwd"), seeds=(0, 1, 2), episodes=1000, draws=16,
                  train=DATA_SIZE["paper"]["train"]),
}


def _ambiguity_cells(profile_name: str) -> list[dict]:
    grid = AMBIGUITY[profile_name]
    return [dict(study="ambiguity", model=model, seed=seed, variant=variant)
            for variant in grid["variants"] for model in grid["models"] for seed in grid["seeds"]]


def _ambiguity_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model and seed trained on one variant's data, scored per step on its held-out
    episodes (for a flow: also the spread of its draws and how it ranks their error) and open
    loop on Table I's references; one row per reference and plan (z = 0; flows: the mean of draws)."""
    grid, variant = AMBIGUITY[profile_name], VARIANTS[cell["variant"]]
    dataset = variant_dataset(variant, grid["episodes"])
    budget = replace(get_profile(profile_name), train=grid["train"], per_step_train=grid["train"])
    model, _ = train.ensure_trained(cell["model"], budget, dataset, variant.robot, seed=cell["seed"],
                                    root=workdir / "models" / variant.name, device=device)
    controller = Controller(model, cell["model"], robot=variant.robot, u_limit=variant.u_max, observe=variant.observe,
                            workspace_margin=None)  # hidden channels shrink the training spread: measure, not refuse
    measured = dict(_spread(dataset, workdir), **_per_step(controller, dataset, grid["draws"]))
    sim = Simulator(variant.robot)
    references = table1_references(sim, profile_name)
    plans = {"zero": {}, f"mean-of-{grid['draws']}": dict(noise="seeded", n_samples=grid["draws"])}
    return [_unnamed(row, plan=plan, **measured)
            for plan, options in plans.items() if controller.generative or not options
            for row in evaluate(controller, references, sim, variant.u_max, **options)[0].to_dict("records")]


def _spread(dataset: data.Dataset, workdir: Path) -> dict:
    """The conditional spread of u in the dataset's training transitions and its floor (both
    inputs together, ``ambiguity.conditional_spread``), cached per dataset (a variant's cells
    share it)."""
    def compute():
        measured = ambiguity.transition_spread(dataset.states, dataset.u, dataset.train)
        return dict(conditional_spread=measured.spread, conditional_spread_floor=measured.floor)

    cached = cached_arrays(cache_file(workdir, "spread", dict(dataset=dataset.key, episodes=len(dataset.train))), compute)
    return {k: float(v) for k, v in cached.items()}


def _per_step(controller: Controller, dataset: data.Dataset, draws: int) -> dict:
    """u error (N, RMS) on the held-out transitions; for a flow also a single draw's and the
    mean of ``draws`` draws' error, the draws' spread, and the Spearman correlation of the
    spread with the z = 0 error per transition (does its uncertainty flag its mistakes?)."""
    X, u = dataset.states[dataset.test], dataset.u[dataset.test]
    planned, error_rms = held_out_plan(controller, dataset)

    def rms(a):  # per input, as held_out_plan's
        return float(np.sqrt(np.mean(np.square(a))))

    row = dict(u_rmse_test=error_rms)
    if controller.generative:
        samples = controller.sample(X, draws)  # (draws, E, T, 2)
        spread = np.linalg.norm(samples.std(0), axis=-1)
        error = np.linalg.norm(planned - u, axis=-1)
        row.update(u_rmse_draw=rms(samples - u), u_rmse_mean_of_draws=rms(samples.mean(0) - u),
                   draw_spread=rms(samples.std(0)),
                   spread_error_spearman=float(scipy_stats.spearmanr(spread.ravel(), error.ravel())[0]))
    return row


# ---------------------------------------------------------------------------- RF-FWD's consistency weight
# Fixed before any ran (issue 15 section 4): lambda in {0, 0.03, 0.1, 0.3, 1} x seeds 0-2 at
# RF-FWD's full paper budget. lambda = 0 is RF and lambda = 1 the shipped RF-FWD: those cells
# share the table1 study's models (same seeds, same budget), as do the forward surrogates.
LAMBDA_GRID = {
    "ci": dict(weights=(0.0, 1.0), seeds=(0,), diagnostic_points=2000),
    "paper": dict(weights=(0.0, 0.03, 0.1, 0.3, 1.0), seeds=(0, 1, 2), diagnostic_points=20000),
}
DIAGNOSTIC_TAUS = (0.05, 0.25, 0.5, 0.75, 0.95)  # where the one-step endpoint estimate is checked
DIAGNOSTIC_EULER = 4  # steps of the short Euler rollout it is compared with


def _lambda_cells(profile_name: str) -> list[dict]:
    grid = LAMBDA_GRID[profile_name]
    return [dict(study="fwd_lambda", model="rf-fwd", seed=seed, consistency=weight)
            for weight in grid["weights"] for seed in grid["seeds"]]


def _lambda_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """RF-FWD with one consistency weight and seed, scored open loop on Table I's references
    and per step, with the forward surrogate's one-step error and the consistency term's
    endpoint estimate against a short Euler rollout (``_consistency_diagnostics``)."""
    profile, sim, weight = get_profile(profile_name), Simulator(SIM_ROBOT), cell["consistency"]
    dataset = data.load_dataset(profile, progress=False)
    name = "rf" if weight == 0 else "rf-fwd"  # lambda = 0 is RF: no surrogate to train or attach
    kwargs = None if weight in (0.0, 1.0) else dict(consistency=weight)
    shared = workdir.parent / "table1" / "models" / profile_name
    model, checkpoint = train.ensure_trained(name, profile, dataset, seed=cell["seed"], model_kwargs=kwargs,
                                             root=shared, device=device)
    forward, _ = train.ensure_trained("forward", profile, dataset, seed=cell["seed"], root=shared, device=device)
    controller = Controller(model, name, workspace_margin=None)  # as the other studies' cells: measure, not refuse
    measured = dict(u_rmse_test=held_out_plan(controller, dataset)[1], best_val=float(checkpoint["best_val"]),
                    epochs_run=int(checkpoint["epochs_run"]),
                    **_consistency_diagnostics(model, forward, dataset, LAMBDA_GRID[profile_name]["diagnostic_points"]))
    results, _ = evaluate(controller, table1_references(sim, profile_name), sim)
    return [_unnamed(row, **measured) for row in results.to_dict("records")]


def _consistency_diagnostics(model, forward, dataset: data.Dataset, points: int) -> dict:
    """What RF-FWD's consistency term sees, on held-out transitions: the surrogate's one-step
    error (mm of tip position), and at each tau of DIAGNOSTIC_TAUS the u error (N, RMS per
    input) and the consistency residual (normalised increment, RMS) of the loss's one-step
    endpoint estimate xi_tau + (1 - tau) v against a DIAGNOSTIC_EULER-step Euler rollout from tau."""
    rng = np.random.default_rng(0)
    x, x_next, u = _diagnostic_transitions(dataset, points, rng)
    window = torch.stack([x, x_next], 1)
    out = {}
    with torch.inference_mode():
        predicted = forward.predict_next(x, u)
        out["forward_step_mm"] = float(1e3 * torch.sqrt(torch.mean((predicted - x_next)[:, :3] ** 2)))
        condition, norm = model.condition(window), model.target_norm()
        xi, z = norm.normalize(u), torch.as_tensor(rng.standard_normal((len(u), 2)), dtype=torch.float32)
        target = forward.delta_norm.normalize(x_next - x)
        for tau_value in DIAGNOSTIC_TAUS:
            tau = torch.full((len(u),), tau_value)
            xi_tau = (1 - tau_value) * z + tau_value * xi
            one_step = xi_tau + (1 - tau_value) * model.velocity(xi_tau, tau, condition)
            rolled, h = xi_tau, (1 - tau_value) / DIAGNOSTIC_EULER
            for k in range(DIAGNOSTIC_EULER):
                rolled = rolled + h * model.velocity(rolled, tau + k * h, condition)
            for label, estimate in (("one_step", one_step), ("euler", rolled)):
                u_hat = norm.unnormalize(estimate)
                out[f"{label}_u_error_tau{tau_value:g}"] = float(torch.sqrt(torch.mean((u_hat - u) ** 2)))
                out[f"{label}_residual_tau{tau_value:g}"] = float(
                    torch.sqrt(torch.mean((forward.increment(x, u_hat) - target) ** 2)))
    return out


def consistency_floor(forward, dataset: data.Dataset, points: int) -> float:
    """The consistency residual (normalised increment, RMS) at the true u on the diagnostics'
    held-out transitions: the surrogate's own one-step error, what the term reports even for a
    perfect inverse. Only the residual above it carries information about u."""
    x, x_next, u = _diagnostic_transitions(dataset, points, np.random.default_rng(0))
    with torch.inference_mode():
        return float(torch.sqrt(forward.compute_loss(torch.stack([x, x_next], 1), u)))  # its training loss, held out


def _diagnostic_transitions(dataset: data.Dataset, points: int, rng: np.random.Generator):
    """``points`` held-out transitions (x_t, x_t+1, u) drawn with ``rng``, as float tensors."""
    held_out = [a.reshape(-1, a.shape[-1]) for a in dataset.transitions(dataset.test)]
    pick = rng.choice(len(held_out[0]), min(points, len(held_out[0])), replace=False)
    return tuple(torch.as_tensor(a[pick], dtype=torch.float32) for a in held_out)


# ---------------------------------------------------------------------------- closed loop
LOOP_MODES = {  # mode -> hardware.run_twin options (repetitions: the profile's)
    "open": dict(loop="open"),
    "open-calibrated": dict(loop="open", calibrated=True),
    "closed": dict(loop="closed"),
    "closed-calibrated": dict(loop="closed", calibrated=True),
    "closed-estimate": dict(loop="closed", condition="estimate"),
    "closed-ilc": dict(loop="closed", repetitions=None),
    "closed-ilc-calibrated": dict(loop="closed", repetitions=None, calibrated=True),
}
GAP_MODES = ("open", "open-calibrated", "closed", "closed-calibrated")  # under each doubled gap term
LOOP_GRID = {
    "ci": dict(configs=("vertical",), modes=("open", "closed", "closed-ilc-calibrated"), references=1, repetitions=2,
               latencies=(), dropped=False, gaps=()),
    "paper": dict(configs=("vertical", "horizontal"), modes=tuple(LOOP_MODES), references=5, repetitions=5,
                  latencies=(0.0, 0.066), dropped=True, gaps=hardware.GAP_TERMS),
}
CAMERA_LATENCY = 0.033  # s: one frame at 30 fps


def _loop_cells(profile_name: str) -> list[dict]:
    grid = LOOP_GRID[profile_name]
    cell = dict(study="closed_loop", model="rf-fwd", seed=0, latency=CAMERA_LATENCY, dropped=0.0, gap="typical")
    cells = [dict(cell, gravity=g, mode=mode, **_learning(mode)) for g in grid["configs"] for mode in grid["modes"]]
    cells += [dict(cell, gravity=g, mode="closed", latency=latency)
              for g in grid["configs"] for latency in grid["latencies"]]
    cells += [dict(cell, gravity=g, mode="closed", dropped=0.1) for g in grid["configs"] if grid["dropped"]]
    return cells + [dict(cell, gravity=g, mode=mode, gap=f"2x {term}") for term in grid["gaps"]
                    for g in grid["configs"] for mode in GAP_MODES]


def _learning(mode: str) -> dict:
    """The cell field that names the learning law's revision in modes that learn across
    repetitions (``loop.SETTLE``: the first revision also learnt the start transient)."""
    return dict(settle=list(loop.SETTLE)) if "repetitions" in LOOP_MODES[mode] else {}


def _gap(name: str) -> hardware.RealityGap:
    """"typical" or "2x <term>": TYPICAL_GAP with that term doubled (notebook 06's sensitivity study)."""
    return hardware.TYPICAL_GAP if name == "typical" else hardware.TYPICAL_GAP.doubled(name.removeprefix("2x "))


def _twin_setup(cell: dict, profile_name: str, device: str, workdir: Path):
    """The twin model of the cell's configuration, its simulator, the gap, the run_twin options
    of the cell's loop mode, and the identified terms (empty unless calibrated)."""
    profile, gravity = get_profile(profile_name), cell["gravity"]
    sim = Simulator(HW_ROBOT, gravity)
    dataset = data.load_dataset(profile, HW_ROBOT, gravity, progress=False)
    model, _ = train.ensure_trained(cell["model"], profile, dataset, HW_ROBOT, gravity, device=device)
    options, gap = dict(LOOP_MODES[cell["mode"]]), _gap(cell["gap"])
    if "repetitions" in options:
        options["repetitions"] = LOOP_GRID[profile_name]["repetitions"]
    identified = {}
    if options.pop("calibrated", False):  # an identification run on this rig first, as on a real one
        fit = _identified_twin(sim, gap, profile.identification_seconds, workdir)
        options["calibration"] = Calibration.identified(sim, fit)
        identified = {f"identified_{term}": getattr(fit.gap, term) for term in identification.FITTED}
    controller = Controller(model, cell["model"], robot=HW_ROBOT, gravity=gravity)
    return controller, sim, gap, dict(options, camera_latency=cell["latency"], dropped=cell["dropped"]), identified


def _loop_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """The twin model of one configuration on Table III's references under the cell's gap, in
    one loop mode; one row per reference."""
    controller, sim, gap, options, identified = _twin_setup(cell, profile_name, device, workdir)
    references = hardware_references(sim)[: LOOP_GRID[profile_name]["references"]]
    rows, _ = hardware.run_twin(controller, references, sim, gap, **options)
    return [dict(row, **identified) for row in rows.drop(columns=["gravity", "loop"]).to_dict("records")]


def _identified_twin(sim: Simulator, gap: hardware.RealityGap, seconds: float, workdir: Path):
    """``identification.identify_twin``, cached in the sweep's workdir: the calibrated cells of
    one configuration and gap share the same identification run (deterministic, ~2 min)."""
    def compute():
        fit = identification.identify_twin(sim, gap, seconds=seconds)
        return dict({term: getattr(fit.gap, term) for term in identification.FITTED}, rmse_mm=fit.rmse_mm,
                    evaluations=fit.evaluations)

    cached = cached_arrays(cache_file(workdir, "identified", dict(simulator=sim.spec(), gap=asdict(gap), seconds=seconds)),
                           compute)
    fitted = hardware.RealityGap(**{term: float(cached[term]) for term in identification.FITTED})
    return identification.Identified(fitted, float(cached["rmse_mm"]), int(cached["evaluations"]))


# ---------------------------------------------------------------------------- twin burst
# Fixed before any ran: the burst circle continued to a 0.2 s period (paper profile; the ci
# profile a short, steep one) under TYPICAL_GAP with 33 ms latency, in the open loop, the
# integral-corrected closed loop and learning across repetitions; broken as in notebook 05.
BURST_GRID = {
    "ci": dict(modes=("open", "closed"), periods=(2.0, 0.3), duration=4.0),
    "paper": dict(modes=("open", "closed", "closed-ilc"), periods=(5.0, 0.2), duration=12.0 * 4.8 / 3.8),
}


def _burst_cells(profile_name: str) -> list[dict]:
    cell = dict(study="twin_burst", model="rf-fwd", seed=0, latency=CAMERA_LATENCY, dropped=0.0, gap="typical")
    return [dict(cell, gravity=g, mode=mode, **_learning(mode)) for g in LOOP_GRID[profile_name]["configs"]
            for mode in BURST_GRID[profile_name]["modes"]]


def _burst_run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One loop mode on the twin's speeding-up burst circle; one row per complete revolution
    (its period, reference speed and y-z RMSE of the true tip, as notebook 05 scores the burst)."""
    controller, sim, gap, options, _ = _twin_setup(cell, profile_name, device, workdir)
    grid = BURST_GRID[profile_name]
    reference = hardware_burst_reference(sim, grid["periods"], grid["duration"])
    rows, runs = hardware.run_twin(controller, [reference], sim, gap, **options)
    centre = sim.tip_positions(sim.rest_q()[None])[0, 1:]
    breakdown = stress.burst_breakdown(reference, {cell["mode"]: runs[reference.name]}, sim.robot.length, centre)
    counts = rows.iloc[0][["rmse_mm", "clipped", "watchdog_events", "repetition"]].to_dict()
    return [dict(row, reference=reference.name, **{f"whole_{k}": v for k, v in counts.items()})
            for row in breakdown.drop(columns="model").to_dict("records")]


STUDIES = {
    "smoke": Study(_smoke_cells, _smoke_run),
    "table1": Study(_table1_cells, _table1_run),
    "protocol": Study(_protocol_cells, _protocol_run),
    "data_size": Study(_size_cells, _size_run),
    "closed_loop": Study(_loop_cells, _loop_run, version=2),
    "twin_burst": Study(_burst_cells, _burst_run),
    "ambiguity": Study(_ambiguity_cells, _ambiguity_run),
    "fwd_lambda": Study(_lambda_cells, _lambda_run),
}
