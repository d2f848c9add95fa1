"""The evaluation protocol's open choices. The paper does not say how its tracking errors were
scored, so each choice it leaves open is a setting here, and Table I is recomputed under
each (notebook 08) with the same trained models:

- approach: the segment from rest to the path's start is excluded from the score (our
  default), scored, or replaced by starting the rod at rest on the path's first point;
- lift: how a y-z path becomes a 6D reference: p_x and velocities through the statics
  (default), p_x held at its rest value, zero velocities, or finite-difference velocities;
- noise: where a flow starts, z = 0 (default), one seeded z per reference, a fresh z each step;
- speed: the shapes' mean tip speed, 0.15 m/s by default.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from softflow import data, training
from softflow.checks import check_choice
from softflow.control.planning import Controller, evaluate
from softflow.data.dataset import Dataset
from softflow.data.dataset import coverage as data_coverage
from softflow.data.references import (
    NOMINAL_SPEED,
    Reference,
    cached_references,
    evaluation_references,
    shape_reference,
)
from softflow.profiles import get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT
from softflow.studies.study import FLOOR, Grid, floor_rows, training_spec, unnamed
from softflow.studies.table1 import TABLE1

APPROACHES = ("excluded", "scored", "on-path")
LIFTS = ("statics", "px-constant", "zero-velocity", "finite-difference")
NOISES = ("zero", "seeded", "fresh")


@dataclass(frozen=True)
class Protocol:
    """One way to score tracking; the defaults are Table I's."""

    approach: str = "excluded"
    lift: str = "statics"
    noise: str = "zero"
    speed: float = NOMINAL_SPEED  # m/s, the shapes' mean tip speed

    def __post_init__(self):
        check_choice(self.approach, "approach", APPROACHES)
        check_choice(self.lift, "lift", LIFTS)
        check_choice(self.noise, "noise", NOISES)
        if not self.speed > 0:
            raise ValueError(f"speed must be positive (m/s); got {self.speed!r}")


def shapes_at(sim: Simulator, names, speed: float) -> list[Reference]:
    """The named shapes at mean tip speed ``speed``, cached (the default speed: Table I's)."""

    def shapes(sim):
        return [shape_reference(sim, name, speed=speed) for name in names]

    return cached_references(sim, f"shapes-{'-'.join(names)}-{speed:g}", shapes)


def apply(sim: Simulator, references, protocol: Protocol):
    """The references as ``protocol`` scores them, and the pose each run starts from: None
    (rest) or one equilibrium pose per reference (approach "on-path"). Actuation-made
    references (random, complex 3D) are dynamically exact already: only the approach and
    the lift of structured paths change."""
    changed = [_lifted(sim, r, protocol.lift) if r.u_true is None else r for r in references]
    if protocol.approach == "scored":
        changed = [replace(r, mask=np.ones_like(r.mask)) for r in changed]
    if protocol.approach != "on-path":
        return changed, None
    if any(r.u_true is not None for r in references):
        raise ValueError("approach 'on-path' applies to structured paths only (actuation-made references have none)")
    on_path = [replace(r, states=r.states[r.mask], mask=np.ones(int(r.mask.sum()), bool)) for r in changed]
    start_u = sim.static_table().inverse(np.stack([r.states[0, :3] for r in on_path]))
    return on_path, sim.static_q(start_u)


def _lifted(sim: Simulator, reference: Reference, lift: str) -> Reference:
    states = reference.states.copy()
    if lift == "px-constant":
        states[:, 0], states[:, 3] = sim.tip_positions(sim.rest_q()[None])[0, 0], 0.0
    elif lift == "zero-velocity":
        states[:, 3:] = 0.0
    elif lift == "finite-difference":
        states[:, 3:] = np.gradient(states[:, :3], DT, axis=0)
    return replace(reference, states=states)


def coverage(references, dataset: Dataset) -> np.ndarray:
    """Per reference, the share of its scored states (position and velocity) that the training
    states cover, as ``data.coverage`` measures it (as close as held-out validation states are)."""
    train, val = dataset.states[dataset.train], dataset.states[dataset.val]
    return np.array([data_coverage(train, r.states[r.mask], val) for r in references])


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


@dataclass(frozen=True, kw_only=True)
class ProtocolGrid(Grid):
    conditions: tuple[str, ...]  # of PROTOCOLS, each scoring Table I's seed-0 models
    ilc_iterations: int  # the floor's trials


PROTOCOL_GRID = {
    "ci": ProtocolGrid(conditions=("table1", "zero-velocity", "z-fresh", "speed-0.5"), ilc_iterations=2),
    "paper": ProtocolGrid(conditions=tuple(PROTOCOLS), ilc_iterations=15),  # shapes settle within 10 trials
}
WITH_RANDOM = ("table1", "z-seeded", "z-fresh")  # conditions that change something on Rand1..Rand4


def cells(profile_name: str) -> list[dict]:
    models = (*TABLE1[profile_name].models, FLOOR)
    return [
        dict(study="protocol", model=model, seed=0, condition=condition)
        for condition in PROTOCOL_GRID[profile_name].conditions
        for model in models
        if not (model == FLOOR and PROTOCOLS[condition].noise != "zero")
    ]  # the floor draws no noise


def protocol_references(sim: Simulator, profile_name: str, condition: str):
    """The references a condition scores, before the protocol is applied: the profile's shapes
    at the condition's speed, and Rand1..Rand4 where the condition changes them."""
    protocol = PROTOCOLS[condition]
    shapes = shapes_at(sim, TABLE1[profile_name].shapes, protocol.speed)
    random = [r for r in evaluation_references(sim) if r.family == "random"] if condition in WITH_RANDOM else []
    return shapes + random


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """A seed-0 model (or the floor) scored under one protocol; each row carries the
    reference's coverage by the training states."""
    profile, sim, protocol = get_profile(profile_name), Simulator(SIM_ROBOT), PROTOCOLS[cell["condition"]]
    references, start_q = apply(sim, protocol_references(sim, profile_name, cell["condition"]), protocol)
    dataset = data.load_dataset(profile, progress=False)
    covered = dict(zip((r.name for r in references), coverage(references, dataset)))
    if cell["model"] == FLOOR:
        rows, _ = floor_rows(sim, references, PROTOCOL_GRID[profile_name].ilc_iterations, start_q)
    else:
        model, _ = training.ensure_trained(cell["model"], profile, dataset, device=device)
        controller = Controller(model, cell["model"])
        options = dict(noise=protocol.noise) if controller.generative else {}
        rows = evaluate(controller, references, sim, start_q=start_q, **options)[0].to_dict("records")
    return [unnamed(row, coverage=covered[row["reference"]], speed=protocol.speed) for row in rows]


def models(cell: dict, profile_name: str) -> dict:
    return {} if cell["model"] == FLOOR else training_spec(cell["model"], get_profile(profile_name))
