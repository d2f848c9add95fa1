"""fwd_lambda: RF-FWD's consistency weight and what the consistency term sees."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from softflow import data, training
from softflow.control.planning import Controller, evaluate
from softflow.profiles import get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT
from softflow.studies.study import Grid, held_out_plan, training_spec, unnamed
from softflow.studies.table1 import table1_references


@dataclass(frozen=True, kw_only=True)
class LambdaGrid(Grid):
    weights: tuple[float, ...]  # lambda, the consistency term's weight
    diagnostic_points: int  # held-out transitions of the consistency diagnostics


# Fixed before any ran: lambda in {0, 0.03, 0.1, 0.3, 1} x seeds 0-2 at
# RF-FWD's full paper budget. lambda = 0 is RF and lambda = 1 the shipped RF-FWD: those cells
# share the table1 study's models (same seeds, same budget), as do the forward surrogates.
LAMBDA_GRID = {
    "ci": LambdaGrid(weights=(0.0, 1.0), seeds=(0,), diagnostic_points=2000),
    "paper": LambdaGrid(weights=(0.0, 0.03, 0.1, 0.3, 1.0), seeds=(0, 1, 2), diagnostic_points=20000),
}
DIAGNOSTIC_TAUS = (0.05, 0.25, 0.5, 0.75, 0.95)  # where the one-step endpoint estimate is checked
DIAGNOSTIC_EULER = 4  # steps of the short Euler rollout it is compared with


def cells(profile_name: str) -> list[dict]:
    grid = LAMBDA_GRID[profile_name]
    return [
        dict(study="fwd_lambda", model="rf-fwd", seed=seed, consistency=weight)
        for weight in grid.weights
        for seed in grid.seeds
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """RF-FWD with one consistency weight and seed, scored open loop on Table I's references
    and per step, with the forward surrogate's one-step error and the consistency term's
    endpoint estimate against a short Euler rollout (``_consistency_diagnostics``)."""
    profile, sim, weight = get_profile(profile_name), Simulator(SIM_ROBOT), cell["consistency"]
    dataset = data.load_dataset(profile, progress=False)
    name, kwargs = _model(weight)
    shared = workdir.parent / "table1" / "models" / profile_name
    model, checkpoint = training.ensure_trained(
        name, profile, dataset, seed=cell["seed"], model_kwargs=kwargs, root=shared, device=device
    )
    forward, _ = training.ensure_trained("forward", profile, dataset, seed=cell["seed"], root=shared, device=device)
    controller = Controller(model, name, workspace_margin=None)  # as the other studies' cells: measure, not refuse
    measured = dict(
        u_rmse_test=held_out_plan(controller, dataset)[1],
        best_val=float(checkpoint["best_val"]),
        epochs_run=int(checkpoint["epochs_run"]),
        **_consistency_diagnostics(model, forward, dataset, LAMBDA_GRID[profile_name].diagnostic_points),
    )
    results, _ = evaluate(controller, table1_references(sim, profile_name), sim)
    return [unnamed(row, **measured) for row in results.to_dict("records")]


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
        out["forward_step_mm"] = float(
            1e3 * torch.sqrt(torch.mean((predicted - x_next)[:, : forward.dims.position] ** 2))
        )
        condition, norm = model.condition(window), model.target_norm()
        xi = norm.normalize(u)
        z = torch.as_tensor(rng.standard_normal((len(u), u.shape[-1])), dtype=torch.float32)
        for tau_value in DIAGNOSTIC_TAUS:
            tau = torch.full((len(u),), tau_value)
            xi_tau = (1 - tau_value) * z + tau_value * xi
            one_step = model.endpoint(xi_tau, tau, condition)
            rolled = model.integrate(xi_tau, condition, DIAGNOSTIC_EULER, start=tau_value)
            for label, estimate in (("one_step", one_step), ("euler", rolled)):
                u_hat = norm.unnormalize(estimate)
                out[f"{label}_u_error_tau{tau_value:g}"] = float(torch.sqrt(torch.mean((u_hat - u) ** 2)))
                out[f"{label}_residual_tau{tau_value:g}"] = float(
                    torch.sqrt(torch.mean(forward.residual(window, u_hat) ** 2))
                )
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


def _model(weight: float) -> tuple[str, dict | None]:
    """The model of a consistency weight and its arguments beyond the registry's: lambda = 0 is RF
    (no surrogate to attach), lambda = 1 the registry's RF-FWD."""
    return ("rf" if weight == 0 else "rf-fwd"), (None if weight in (0.0, 1.0) else dict(consistency=weight))


def models(cell: dict, profile_name: str) -> dict:
    name, kwargs = _model(cell["consistency"])
    profile = get_profile(profile_name)
    return {
        **training_spec(name, profile, kwargs, cell["seed"]),
        **training_spec("forward", profile, seed=cell["seed"]),
    }
