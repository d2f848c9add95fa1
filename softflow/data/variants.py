"""Dataset variants in which the inverse (x_t, x_t+1) -> u may be many-valued: how
the rod is driven (actuation range, damping, excitation) and what a model is shown of its tip
(observed channels, position noise, finite-difference velocities).

The paper's setting is nearly one-to-one (every bending mode above the first relaxes in about
25 ms), so a flow has nothing to gain over a regression there. Each variant breaks that in one
named way; ``ambiguity.conditional_spread`` measures how much it does. A variant's episodes
are simulated once and cached like the paper dataset (variants that drive the rod the same
way share them); the observation is applied on load, so it costs nothing to change.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from softflow.checks import check_choice
from softflow.data.dataset import DATA_VERSION, Dataset, simulated_dataset
from softflow.data.excitation import polynomial_excitation
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT, U_MAX
from softflow.store import DATA_DIR, cache_file

EXCITATIONS = ("polynomial", "piecewise")
HOLD_SECONDS = (0.05, 0.5)  # s: how long a piecewise-constant level is held


@dataclass(frozen=True)
class Variant:
    """One way of making the inverse ambiguous; the defaults are the paper's setting."""

    name: str
    u_max: float = U_MAX  # N: the excitation's peak |u| (norm of both inputs) and the plans' clip
    damping: float = 1.0  # factor on the rod's eta
    excitation: str = "polynomial"  # or "piecewise": random levels held HOLD_SECONDS
    observed: tuple = (0, 1, 2, 3, 4, 5)  # tip-state channels (p, v) a model sees; the others read 0
    noise_mm: float = 0.0  # standard deviation of the noise on observed positions
    finite_difference: bool = False  # velocities by backward differences of the (noisy) positions

    def __post_init__(self):
        check_choice(self.excitation, "excitation", EXCITATIONS)
        if not (self.u_max > 0 and self.damping > 0 and self.noise_mm >= 0):
            raise ValueError(
                f"u_max and damping must be > 0 and noise_mm >= 0; got {self.u_max!r}, "
                f"{self.damping!r}, {self.noise_mm!r}"
            )
        if not set(self.observed) <= set(range(6)) or not self.observed:
            raise ValueError(
                f"observed must name some of the channels 0..5 (p_x, p_y, p_z, v_x, v_y, v_z); got {self.observed!r}"
            )

    @property
    def robot(self):
        return replace(SIM_ROBOT, damping=SIM_ROBOT.damping * self.damping)

    def observe(self, states, rng: np.random.Generator | None = None) -> np.ndarray:
        """What a model is shown of tip states (..., T+1, 6): noise on the positions (only with
        ``rng``: references are noise-free), velocities by finite differences if the variant
        says so, hidden channels zeroed."""
        X = np.array(states, dtype=float)
        if rng is not None and self.noise_mm > 0:
            X[..., :3] += rng.normal(0.0, 1e-3 * self.noise_mm, X[..., :3].shape)
        if self.finite_difference:  # backward: what a real-time estimate has; v_0 = 0 (from rest)
            X[..., 3:] = np.diff(X[..., :3], axis=-2, prepend=X[..., :1, :3]) / DT
        X[..., [c for c in range(6) if c not in self.observed]] = 0.0
        return X


# Fixed before any ran: the paper's setting and one variant per way of ambiguity.
VARIANTS = {
    v.name: v
    for v in (
        Variant("paper"),
        # past a half circle the tip comes back: with x hidden, two bends reach one (y, z)
        Variant("folded", u_max=12.0, observed=(1, 2, 4, 5)),
        # hidden modes ring on after each step of u instead of following recent u
        Variant("weak-damping", damping=0.1, excitation="piecewise"),
        Variant("position-only", observed=(0, 1, 2)),
        Variant("finite-difference", finite_difference=True),
        Variant("noise-0.5mm", noise_mm=0.5, finite_difference=True),
        Variant("noise-2mm", noise_mm=2.0, finite_difference=True),
    )
}


def piecewise_excitation(
    n_episodes: int, n_steps: int, rng: np.random.Generator, u_max: float = U_MAX, hold=HOLD_SECONDS
) -> np.ndarray:
    """Random levels, uniform in [-u_max, u_max] per input, each held uniform(hold) s: (B, T, 2)."""
    most = int(np.ceil(n_steps * DT / hold[0])) + 1  # enough levels to fill the longest episode
    switches = np.cumsum(rng.uniform(*hold, (n_episodes, 2, most)), -1)  # end time of each level
    levels = rng.uniform(-u_max, u_max, (n_episodes, 2, most))
    t = np.arange(n_steps) * DT
    index = np.stack([[np.searchsorted(row, t, side="right") for row in pair] for pair in switches])
    return np.take_along_axis(levels, index, -1).transpose(0, 2, 1)


def _excitation(variant: Variant, n_episodes: int, n_steps: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if variant.excitation == "piecewise":
        return piecewise_excitation(n_episodes, n_steps, rng, variant.u_max)
    u = polynomial_excitation(n_episodes, n_steps, rng, amplitudes=(0.5, variant.u_max))
    norm = np.linalg.norm(u, axis=-1).max(-1)[:, None, None]  # keep |u| within u_max, as on a real rod
    return u * np.minimum(1.0, variant.u_max / norm)


def variant_dataset(
    variant: Variant,
    n_episodes: int,
    *,
    seconds: float = 5.0,
    seed: int = 0,
    progress: bool = False,
    data_dir: Path = DATA_DIR,
) -> Dataset:
    """``n_episodes`` episodes of the variant's excitation on its rod (simulated once, cached),
    with states as the variant observes them (position noise seeded by ``seed``). Its key
    names the variant, so models trained on it are told apart from the paper's."""
    sim = Simulator(variant.robot)
    drive = dict(u_max=variant.u_max, excitation=variant.excitation)
    spec = dict(simulator=sim.spec(), n_episodes=n_episodes, seconds=seconds, seed=seed, version=DATA_VERSION, **drive)
    path = cache_file(data_dir, "variant", spec)
    n_steps = int(round(seconds / DT))
    raw = simulated_dataset(
        path, lambda: _excitation(variant, n_episodes, n_steps, seed), sim, seed, u_max=variant.u_max, progress=progress
    )
    observation = {k: v for k, v in asdict(variant).items() if k not in drive and k not in ("name", "damping")}
    states = variant.observe(raw.states, np.random.default_rng(seed))
    return replace(raw, states=states, key=f"{raw.key}-{cache_file('', 'seen', observation).stem}")
