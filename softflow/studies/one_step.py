"""one_step: do the one-step flows keep, in one network call, what the 4-step flows give?

Fixed before any row ran (docs/assumptions.md, "The one-step study"):
- models: the MLP; RF and RF-FWD, each trained once and planned with 4 Euler steps (as shipped)
  and with 1; RF-1 and RF-FWD-1 (``MeanFlow``), planned with 1 step and with 2; 3 seeds; one
  fixed budget of optimiser steps for all (``FIXED_BUDGET``: 20 000, no early stop; RF-FWD's
  surrogate the same).
- rods: the paper rod, trained on the paper dataset and scored on Table I's references (8 shapes,
  Rand1..Rand24); the two-segment rod seen at its tip alone, trained on the two-segment study's
  tip dataset and scored on its shapes and 24 random references (its three 3-D paths are one
  path in three rotations: left out).
- every plan from z = 0, as Table I plans, run open loop from rest; Table I's tracking RMSE.
- the rules (``summarise``), per rod and reference family:
  1. parity: a one-step flow at 1 step against its parent at 4 steps, the ratio of their mean
     RMSEs with its paired two-way bootstrap interval: "within" 10 % where the interval lies
     inside [0.9, 1.1], "outside" where it lies wholly beyond, else "undecided";
  2. the tip-alone win, on the two-segment rod: a one-step flow at 1 step against the MLP, a
     ranking only where the bootstrap and the paired t-interval of the difference both exclude
     zero, Holm over this family;
  3. the collapse: RF and RF-FWD at 1 Euler step against the MLP, the ratio as in 1: "within"
     10 % of the MLP is the collapse the theory predicts (one Euler step from z = 0 gives the
     conditional mean).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from softflow import data, training
from softflow.control.planning import Controller, evaluate
from softflow.profiles import FIXED_BUDGET, get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT, TWO_SEGMENT_ROD
from softflow.studies import stats, two_segment
from softflow.studies.study import Grid, training_spec, unnamed
from softflow.studies.table1 import table1_references

PAPER_ROD, TWO_SEGMENT_TIP = "paper", "two-segment-tip"
PLANS = {"mlp": (None,), "rf": (4, 1), "rf-fwd": (4, 1), "rf-1": (1, 2), "rf-fwd-1": (1, 2)}  # steps per plan
PARENTS = {"rf-1": "rf", "rf-fwd-1": "rf-fwd"}
BAND = (0.9, 1.1)  # "within 10 %": the ratio's interval inside it


@dataclass(frozen=True, kw_only=True)
class OneStepGrid(Grid):
    rods: tuple[str, ...]  # PAPER_ROD, TWO_SEGMENT_TIP


ONE_STEP = {
    "ci": OneStepGrid(rods=(PAPER_ROD,), models=("mlp", "rf", "rf-1"), seeds=(0,), train=FIXED_BUDGET["ci"]),
    "paper": OneStepGrid(
        rods=(PAPER_ROD, TWO_SEGMENT_TIP),
        models=("mlp", "rf", "rf-fwd", "rf-1", "rf-fwd-1"),
        seeds=(0, 1, 2),
        train=FIXED_BUDGET["paper"],  # 20 000 steps, no early stop
    ),
}


def cells(profile_name: str) -> list[dict]:
    grid = ONE_STEP[profile_name]
    return [
        dict(study="one_step", rod=rod, model=model, seed=seed)
        for rod in grid.rods
        for model in grid.models
        for seed in grid.seeds
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One model and seed trained with the study's budget on the cell's rod and scored on its
    references with each of its plans' step counts: one row per reference and step count."""
    name, seed = cell["model"], cell["seed"]
    if cell["rod"] == PAPER_ROD:
        sim = Simulator(SIM_ROBOT)
        references = table1_references(sim, profile_name)
        model, checkpoint = training.ensure_trained(
            name,
            ONE_STEP[profile_name].budget(profile_name),
            data.DatasetOnDemand(get_profile(profile_name), progress=False),  # simulated only if a model must train
            seed=seed,
            root=Path(workdir) / "models" / profile_name / PAPER_ROD,
            device=device,
        )
        controller = Controller(model, name)
    else:
        sim = Simulator(TWO_SEGMENT_ROD, two_segment.GRAVITY)
        grid = two_segment.TWO_SEGMENT[profile_name]
        names = [*grid.shapes, *(f"Rand{i + 1}" for i in range(grid.n_random))]
        references = two_segment.references(sim, profile_name, "tip", names=names)
        model, checkpoint = two_segment.trained_model(name, profile_name, "tip", seed, workdir, device)
        controller = Controller(model, name, robot=TWO_SEGMENT_ROD, gravity=two_segment.GRAVITY)
    controller.workspace_margin = None  # extrapolation is measured, not refused (as Table I)
    training_facts = dict(best_val=float(checkpoint["best_val"]), train_minutes=float(checkpoint["wall_seconds"]) / 60)
    rows = []
    for steps in PLANS[name]:
        results, _ = evaluate(controller, references, sim, **({} if steps is None else {"steps": steps}))
        rows += [unnamed(row, plan_steps=steps or 0, **training_facts) for row in results.to_dict("records")]
    return rows


def summarise(rows: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The study's tables from its rows (columns rod, model, seed, plan_steps, reference, family,
    rmse_mm): "rmse", each plan's mean tracking RMSE (``model@steps``; the MLP's @0) with its
    bootstrap interval over seeds and references; "parity" (rule 1) and "collapse" (rule 3), one row per ratio
    with its interval and whether it lies within the band; "tip_win" (rule 2), a verdict table
    (``stats.judged``, one Holm family)."""
    plans = rows.assign(model=rows["model"] + "@" + rows["plan_steps"].astype(str))
    parity, win, collapse = [], [], []
    for (rod, family), part in plans.groupby(["rod", "family"], sort=False):
        present = set(part["model"])

        def grids(a, b, part=part):
            order = list(dict.fromkeys(part.loc[part["model"] == a, "reference"]))
            return [stats.seed_reference_grid(part[part["model"] == m], "rmse_mm", order) for m in (a, b)]

        for one_step, parent in PARENTS.items():
            if {f"{one_step}@1", f"{parent}@4"} <= present:
                interval = stats.ratio(*grids(f"{one_step}@1", f"{parent}@4"))
                parity.append(_ratio_row(rod, family, f"{one_step}@1", f"{parent}@4", interval))
        for flow in ("rf", "rf-fwd"):
            if {f"{flow}@1", "mlp@0"} <= present:
                interval = stats.ratio(*grids(f"{flow}@1", "mlp@0"))
                collapse.append(_ratio_row(rod, family, f"{flow}@1", "mlp@0", interval))
        if rod == TWO_SEGMENT_TIP:
            for one_step in PARENTS:
                if {f"{one_step}@1", "mlp@0"} <= present:
                    win.append(dict(rod=rod, **stats.compared(part, f"{one_step}@1", "mlp@0", family)))
    win = stats.judged(win, ("rod",))
    rmse = stats.summarise(plans, "rmse_mm", by=("rod", "family", "model"))
    return dict(rmse=rmse, parity=pd.DataFrame(parity), tip_win=win, collapse=pd.DataFrame(collapse))


def _ratio_row(rod: str, family: str, a: str, b: str, interval: stats.Interval) -> dict:
    """mean(a) / mean(b) with its interval, in the comparison schema's names (``stats.COMPARED``)."""
    return dict(
        rod=rod,
        family=family,
        a=a,
        b=b,
        ratio=interval.estimate,
        low=interval.low,
        high=interval.high,
        within_10_percent=stats.within(interval, BAND),
    )


def models(cell: dict, profile_name: str) -> dict:
    return training_spec(cell["model"], ONE_STEP[profile_name].budget(profile_name), seed=cell["seed"])
