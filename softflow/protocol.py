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

import numpy as np

from .checks import check_choice
from .data import DT, Dataset
from .data import coverage as data_coverage
from .sim import Simulator
from .trajectories import NOMINAL_SPEED, Reference, cached_references, shape_reference

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
