"""design: the RF design choices behind the defaults (notebook 04), the consistency weight and
the tau sampling, every variant at the profile's short budget (the sequence models')."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from softflow import data, training
from softflow.control.planning import Controller, evaluate
from softflow.data.references import evaluation_references
from softflow.profiles import get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT
from softflow.studies.study import Grid, training_spec, unnamed

# variant -> (model, its arguments beyond the registry's); one seed each: a screen, which the
# fwd_lambda study (notebook 11) repeats with three seeds at the full budget.
VARIANTS = {
    **{f"rf-fwd, λ = {weight:g}": ("rf-fwd", {"consistency": weight}) for weight in (0.1, 0.3, 1.0, 3.0)},
    "rf (λ = 0)": ("rf", {}),
    "rf, uniform τ": ("rf", {"tau_sampling": "uniform"}),
}


@dataclass(frozen=True, kw_only=True)
class DesignGrid(Grid):
    # the Table I references a variant is scored on (None: all twelve); the ci run's cost is its
    # rollouts, whose length the longest reference sets
    references: tuple[str, ...] | None


DESIGN = {"ci": DesignGrid(references=("circle", "char_S", "Rand1", "Rand2")), "paper": DesignGrid(references=None)}


def cells(profile_name: str) -> list[dict]:
    return [dict(study="design", variant=variant, model=VARIANTS[variant][0], seed=0) for variant in VARIANTS]


def _short_budget(profile_name: str):
    """The profile with its short budget (``train``, the sequence models') for every model."""
    return replace(get_profile(profile_name), per_step_train=None)


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One variant trained at the short budget (RF-FWD's surrogate too, shared by the variants'
    cells) and scored open loop on the profile's Table I references; one row per reference."""
    profile, sim = _short_budget(profile_name), Simulator(SIM_ROBOT)
    name, kwargs = VARIANTS[cell["variant"]]
    dataset = data.load_dataset(profile, progress=False)
    model, checkpoint = training.ensure_trained(
        name, profile, dataset, model_kwargs=kwargs, root=workdir / "models" / profile_name, device=device
    )
    names = DESIGN[profile_name].references
    references = [r for r in evaluation_references(sim) if names is None or r.name in names]
    results, _ = evaluate(Controller(model, name), references, sim)
    fitted = dict(best_val=float(checkpoint["best_val"]), epochs_run=int(checkpoint["epochs_run"]))
    return [unnamed(row, **fitted) for row in results.to_dict("records")]


def models(cell: dict, profile_name: str) -> dict:
    name, kwargs = VARIANTS[cell["variant"]]
    return training_spec(name, _short_budget(profile_name), kwargs)
