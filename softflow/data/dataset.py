"""The polynomial-excitation dataset and its content-hash cache.

The paper trains on 3000 episodes of random polynomial actuation, 5 s each at 0.01 s.
Episodes are stored whole (u and the tip states); training tuples are views on
them, and the context windows of sequence models are gathered per batch, never copied
whole. The cache file is named by a content key of everything that made it (the
profile's data fields, the simulator's numbers and DATA_VERSION), so a change of any
rebuilds it, a comment edit rebuilds nothing, and a corrupt or partial file is detected
and rebuilt, never used.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from softflow.data.excitation import polynomial_excitation
from softflow.models.common import Dims
from softflow.profiles import Profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT, U_MAX, Robot
from softflow.store import DATA_DIR, cache_file, read_npz, write_npz

DATA_VERSION = 1  # bump when the excitation, the split or the stored arrays change
BLOCK_EPISODES = 500  # episodes simulated and saved together: the unit of resumption


# ---------------------------------------------------------------------------- the dataset
@dataclass(frozen=True)
class Dataset:
    """Whole episodes: u (E, T, m), states (E, T+1, d) (tip positions, then their velocities), an
    episode split, the sample period ``dt`` (s), and the rod and gravity that made them
    (RF-Physical's prior is that rod's statics; None for data no simulator made). Models take
    their sizes from it (``dims``): m = 2 and d = 6 for the paper's rods."""

    u: np.ndarray
    states: np.ndarray
    train: np.ndarray  # episode indices
    val: np.ndarray
    test: np.ndarray
    key: str = ""  # cache file stem: names the exact data a model was trained on
    robot: Robot | None = SIM_ROBOT
    gravity: str | None = "vertical"
    dt: float = DT

    def __post_init__(self):
        if self.u.ndim != 3 or self.states.ndim != 3 or self.states.shape[:2] != (len(self.u), self.u.shape[1] + 1):
            raise ValueError(f"need u (E, T, m) and states (E, T+1, d); got {self.u.shape} and {self.states.shape}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive sample period in s; got {self.dt!r}")

    @property
    def dims(self) -> Dims:
        """What a model trained on these episodes reads and writes."""
        return Dims.of(self.u, self.states)

    @property
    def n_transitions(self) -> int:
        return self.u.shape[0] * self.u.shape[1]

    def transitions(self, episodes):
        """(x_t, x_{t+1}, u_t) of the given episodes, each (E', T, .); views when episodes is a slice."""
        X = self.states[episodes]
        return X[:, :-1], X[:, 1:], self.u[episodes]


def subset(dataset: Dataset, n_episodes: int) -> Dataset:
    """The dataset as if it had ``n_episodes`` episodes: the first 80 % of them train (from its
    own train split), validation and test unchanged, so models of every size are judged on the
    same held-out episodes. Its key names the size (a model's identity records it)."""
    n_train = int(0.8 * n_episodes)
    if not (isinstance(n_episodes, int) and 2 <= n_train <= len(dataset.train)):
        raise ValueError(
            f"n_episodes must be an integer with 2 <= 0.8 n_episodes <= {len(dataset.train)} "
            f"(the training episodes there are); got {n_episodes!r}"
        )
    return replace(dataset, train=dataset.train[:n_train], key=f"{dataset.key}-train{n_train}")


def split_episodes(n_episodes: int, seed: int, fractions=(0.8, 0.1)):
    """Shuffled episode indices split train / validation / test (never by sample)."""
    order = np.random.default_rng(seed).permutation(n_episodes)
    n_train, n_val = int(fractions[0] * n_episodes), int(fractions[1] * n_episodes)
    return np.sort(order[:n_train]), np.sort(order[n_train : n_train + n_val]), np.sort(order[n_train + n_val :])


def _dataset_from(arrays: dict | None, key: str, robot: Robot, gravity: str, u_max: float = U_MAX) -> Dataset | None:
    """A Dataset from cached arrays, or None when any is missing or inconsistent."""
    try:
        data = Dataset(
            **{k: arrays[k] for k in ("u", "states", "train", "val", "test")}, key=key, robot=robot, gravity=gravity
        )
    except (KeyError, TypeError, ValueError):
        return None
    E, T, _ = data.u.shape
    consistent = (
        data.states.shape[-1] % 2 == 0
        and np.isfinite(data.states).all()
        and np.abs(data.u).max() <= u_max
        and len(data.train) + len(data.val) + len(data.test) == E
    )
    return data if consistent else None


def dataset_path(
    profile: Profile, robot: Robot = SIM_ROBOT, gravity: str = "vertical", data_dir: Path = DATA_DIR
) -> Path:
    """Where the profile's dataset is cached; the name changes with any number that made it
    (the rod's parameters, not its name)."""
    spec = dict(**profile.data_spec, simulator=Simulator(robot, gravity=gravity).spec(), version=DATA_VERSION)
    return cache_file(data_dir, f"dataset-{profile.name}", spec)


def load_dataset(
    profile: Profile,
    robot: Robot = SIM_ROBOT,
    gravity: str = "vertical",
    *,
    progress: bool = True,
    data_dir: Path = DATA_DIR,
) -> Dataset:
    """The profile's polynomial-excitation dataset, generated on first use and cached."""
    path = dataset_path(profile, robot, gravity, data_dir)
    n_steps = int(round(profile.episode_seconds / DT))
    return simulated_dataset(
        path,
        lambda: polynomial_excitation(profile.n_episodes, n_steps, np.random.default_rng(profile.seed)),
        Simulator(robot, gravity=gravity),
        profile.seed,
        progress=progress,
    )


class DatasetOnDemand:
    """The profile's dataset, made (or read from its cache) only when its episodes are first
    used: its key, rod and gravity are known before, which is all a shipped model needs to be
    found current, so scoring a shipped model never simulates 3000 episodes first."""

    def __init__(self, profile: Profile, robot: Robot = SIM_ROBOT, gravity: str = "vertical", **options):
        self.key, self.robot, self.gravity = dataset_path(profile, robot, gravity).stem, robot, gravity
        self._make = lambda: load_dataset(profile, robot, gravity, **options)
        self._dataset = None

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        if self._dataset is None:
            self._dataset = self._make()
        return getattr(self._dataset, name)


def simulated_dataset(
    path: Path, excitation, simulator: Simulator, seed: int, *, u_max: float = U_MAX, progress: bool = True
) -> Dataset:
    """The Dataset cached at ``path``, or the episodes of ``excitation()`` (E, T, 2) run through
    ``simulator`` and split by ``seed``, saved there. Generation runs in blocks saved as they
    finish, so an interrupted run resumes where it stopped; the final file appears atomically."""
    robot, gravity = simulator.robot, simulator.gravity
    cached = _dataset_from(read_npz(path), path.stem, robot, gravity, u_max)
    if cached is not None:
        return cached
    u = excitation()
    n_episodes, n_steps, _ = u.shape
    blocks_dir = path.with_suffix(".blocks")
    blocks_dir.mkdir(parents=True, exist_ok=True)
    states = []
    for start in range(0, n_episodes, BLOCK_EPISODES):
        stop = min(start + BLOCK_EPISODES, n_episodes)
        block_path = blocks_dir / f"{start:06d}.npz"
        done = (read_npz(block_path) or {}).get("states")
        if done is None or done.shape[:2] != (stop - start, n_steps + 1):
            done = simulator.rollout(u[start:stop], progress=progress)
            write_npz(block_path, states=done)
        states.append(done)
    train, val, test = split_episodes(n_episodes, seed)
    write_npz(path, u=u, states=np.concatenate(states), train=train, val=val, test=test)
    shutil.rmtree(blocks_dir, ignore_errors=True)  # another process making the same data may clean up first
    return _dataset_from(read_npz(path), path.stem, robot, gravity, u_max)


def gather_windows(states: np.ndarray, episodes, steps, context: int) -> np.ndarray:
    """States x_{t-context+1} .. x_{t+1} for each (episode, t): (B, context+1, d). Before the
    first sample the window repeats x_0, the rest pose the robot held before it moved."""
    index = np.clip(np.asarray(steps)[:, None] + np.arange(-context + 1, 2), 0, None)
    return states[np.asarray(episodes)[:, None], index]


def coverage(
    training_states, query_states, held_out_states, quantile: float = 0.99, max_points: int = 200_000, seed: int = 0
) -> float:
    """Fraction of query states (M, d) inside the region the training states (N, d) cover.

    "Inside" means: nearer (in units of the training standard deviation per coordinate)
    to a training state than ``quantile`` of held-out training-distribution states
    (e.g. validation episodes) are. So 0.99 is what in-distribution data scores."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    d = np.shape(training_states)[-1]
    train = np.asarray(training_states).reshape(-1, d)
    if len(train) > max_points:
        train = train[rng.choice(len(train), max_points, replace=False)]
    scale = train.std(0)
    tree = cKDTree(train / scale)
    held_out = np.asarray(held_out_states).reshape(-1, d)
    held_out = held_out[rng.choice(len(held_out), min(len(held_out), 20_000), replace=False)]
    radius = np.quantile(tree.query(held_out / scale)[0], quantile)
    distance = tree.query(np.asarray(query_states).reshape(-1, d) / scale)[0]
    return float(np.mean(distance <= radius))
