"""The polynomial-excitation dataset and its content-hash cache.

The paper trains on 3000 episodes of random polynomial actuation, 5 s each at 0.01 s.
Episodes are stored whole (u and the tip states; for a rod of several segments also the
states of the disks between them); training tuples are views on them, and the context
windows of sequence models are gathered per batch, never copied whole. What a model is
shown of a rod with inner disks is its ``observation``: the tip alone, or the tip and the
disks. The cache file is named by a content key of everything that made it (the profile's
data fields, the simulator's numbers and DATA_VERSION), so a change of any rebuilds it, a
comment edit rebuilds nothing, and a corrupt or partial file is detected and rebuilt, never
used.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from softflow.checks import check_choice
from softflow.data.excitation import polynomial_excitation
from softflow.models.common import Dims
from softflow.profiles import Profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT, U_MAX, Robot
from softflow.store import DATA_DIR, cache_file, read_npz, write_npz

DATA_VERSION = 1  # bump when the excitation, the split or the stored arrays change
BLOCK_EPISODES = 500  # episodes simulated and saved together: the unit of resumption
OBSERVATIONS = ("tip", "tip+disk")  # what a model of a rod with inner disks is shown
_STATE_CHUNK = 2048  # samples whose disk states are computed together (position Jacobians of every node)


# ---------------------------------------------------------------------------- the dataset
@dataclass(frozen=True)
class Dataset:
    """Whole episodes: u (E, T, m), states (E, T+1, d) (tip positions, then their velocities), an
    episode split, the sample period ``dt`` (s), and the rod and gravity that made them
    (RF-Physical's prior is that rod's statics; None for data no simulator made). Models take
    their sizes from it (``dims``): m = 2 and d = 6 for the paper's rods. Recorded data pair each
    (x_t, x_{t+1}) with the input sent ``delay_steps`` periods earlier (the rig's input-to-motion
    delay; 0 for simulated data), and keep the per-recording estimates it came from (``delays``, s)
    and the offline smoother's levels (``levels``, the recordings' median), which the loop's filter uses."""

    u: np.ndarray
    states: np.ndarray
    train: np.ndarray  # episode indices
    val: np.ndarray
    test: np.ndarray
    key: str = ""  # cache file stem: names the exact data a model was trained on
    robot: Robot | None = SIM_ROBOT
    gravity: str | None = "vertical"
    dt: float = DT
    delay_steps: int = 0  # periods between an input and the step it is paired with
    delays: tuple[float, ...] = ()  # s: the estimated delay of each recording (NaN: too short), if estimated
    input_columns: tuple[str, ...] = ()  # recorded data: the columns the inputs and the tip came from
    tip_columns: tuple[str, ...] = ()
    split_files: dict | None = None  # recorded data: {"train" | "val" | "test": file names}
    resting_files: tuple[str, ...] = ()  # recorded data: files left out, their inputs never changing
    levels: tuple[np.ndarray, np.ndarray] | None = None  # recorded data: the smoother's (noise, jerk) per tip column
    causal: bool = False  # recorded data: states from the smoother's filter alone (what a loop knows), not the smoother

    def __post_init__(self):
        if self.u.ndim != 3 or self.states.ndim != 3 or self.states.shape[:2] != (len(self.u), self.u.shape[1] + 1):
            raise ValueError(f"need u (E, T, m) and states (E, T+1, d); got {self.u.shape} and {self.states.shape}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive sample period in s; got {self.dt!r}")
        whole = isinstance(self.delay_steps, (int, np.integer)) and not isinstance(self.delay_steps, bool)
        if not (whole and self.delay_steps >= 0):
            raise ValueError(f"delay_steps must be a whole number of periods >= 0; got {self.delay_steps!r}")

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


def observe_disks(positions, velocities, observation: str = "tip") -> np.ndarray:
    """The state a model is shown, from the positions and velocities (..., S, 3) of a rod's disks
    (base outwards, the tip last): "tip", the tip's position and velocity (..., 6); "tip+disk",
    the tip's and then the inner disks' positions, then their velocities in the same order
    (..., 6 S), which a rod of one segment (no inner disk) does not have."""
    check_choice(observation, "observation", OBSERVATIONS)
    n_disks = np.shape(positions)[-2]
    if observation == "tip+disk" and n_disks < 2:
        raise ValueError("observation 'tip+disk' needs a rod of several segments (a disk between them); got one")
    order = [n_disks - 1] + (list(range(n_disks - 1)) if observation == "tip+disk" else [])
    batch = np.shape(positions)[:-2]
    return np.concatenate(
        [
            np.asarray(positions)[..., order, :].reshape(batch + (-1,)),
            np.asarray(velocities)[..., order, :].reshape(batch + (-1,)),
        ],
        -1,
    )


def tip_of(states) -> np.ndarray:
    """The tip's state (..., 6) within "tip+disk" states (..., 6 S): the tip leads both halves."""
    half = np.shape(states)[-1] // 2
    return np.concatenate([states[..., :3], states[..., half : half + 3]], -1)


def disk_states(sim: Simulator, q, qd) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities (..., S, 3) of the rod's disks, base outwards (the tip last), at
    q, qd (..., nq): the tip's as a rollout gives them (``Simulator.tip_state``), the inner
    disks' velocity J(q) qd through their exact position Jacobian (the same kinematics: J qd at
    the tip agrees with the rollout's velocity to about 1e-8 relative)."""
    batch, nq = np.shape(q)[:-1], sim.nq
    q, qd = np.reshape(q, (-1, nq)), np.reshape(qd, (-1, nq))
    inner = sim.kinematics.segment_ends[:-1]
    positions, velocities = [], []
    for start in range(0, len(q), _STATE_CHUNK):
        c = slice(start, start + _STATE_CHUNK)
        frames = sim.kinematics.frames(q[c])
        jacobians = sim.kinematics.position_jacobians(frames)[:, inner]  # (b, S-1, 3, nq)
        tip = sim.tip_state(q[c], qd[c])  # (b, 6)
        positions.append(np.concatenate([frames["positions"][:, inner], tip[:, None, :3]], 1))
        velocities.append(np.concatenate([(jacobians @ qd[c][:, None, :, None])[..., 0], tip[:, None, 3:]], 1))
    shape = batch + (len(inner) + 1, 3)
    return np.concatenate(positions).reshape(shape), np.concatenate(velocities).reshape(shape)


def disk_rollout(sim: Simulator, u, *, progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``Simulator.rollout`` with every disk: positions and velocities (B, T+1, S, 3) of the
    disks (the tip last) for actuation u (B, T, m) from the rest pose."""
    q, qd = sim.integrate(u, sim.rest_q(), np.zeros(sim.nq), progress=progress)
    return disk_states(sim, q, qd)


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


def _dataset_from(
    arrays: dict | None, key: str, robot: Robot, gravity: str, u_max: float = U_MAX, observation: str = "tip"
) -> Dataset | None:
    """A Dataset from cached arrays, as ``observation`` sees them, or None when any is missing or
    inconsistent (a rod of several segments must also have its inner disks' states)."""
    try:
        data = Dataset(
            **{k: arrays[k] for k in ("u", "states", "train", "val", "test")}, key=key, robot=robot, gravity=gravity
        )
        disks = arrays["disks"] if len(robot.segment_lengths) > 1 else np.zeros(data.states.shape[:2] + (0, 6))
    except (KeyError, TypeError, ValueError):
        return None
    E, T, _ = data.u.shape
    consistent = (
        data.states.shape[-1] % 2 == 0
        and np.isfinite(data.states).all()
        and disks.shape == data.states.shape[:2] + (len(robot.segment_lengths) - 1, 6)
        and np.isfinite(disks).all()
        and np.abs(data.u).max() <= u_max
        and len(data.train) + len(data.val) + len(data.test) == E
    )
    if not consistent:
        return None
    if observation == "tip":
        return data
    positions = np.concatenate([disks[..., :3], data.states[..., None, :3]], -2)  # (E, T+1, S, 3)
    velocities = np.concatenate([disks[..., 3:], data.states[..., None, 3:]], -2)
    return replace(data, states=observe_disks(positions, velocities, observation), key=f"{key}-{observation}")


def dataset_path(
    profile: Profile, robot: Robot = SIM_ROBOT, gravity: str = "vertical", data_dir: Path | None = None
) -> Path:
    """Where the profile's dataset is cached (in ``data_dir``, default the cache root); the name
    changes with any number that made it (the rod's parameters, not its name)."""
    spec = dict(**profile.data_spec, simulator=Simulator(robot, gravity=gravity).spec(), version=DATA_VERSION)
    return cache_file(DATA_DIR if data_dir is None else data_dir, f"dataset-{profile.name}", spec)


def load_dataset(
    profile: Profile,
    robot: Robot = SIM_ROBOT,
    gravity: str = "vertical",
    *,
    observation: str = "tip",
    progress: bool = True,
    data_dir: Path | None = None,
) -> Dataset:
    """The profile's polynomial-excitation dataset (one polynomial per input of the rod), generated
    on first use and cached; its states as ``observation`` sees them ("tip", or "tip+disk" for a
    rod of several segments, whose key then says so)."""
    check_choice(observation, "observation", OBSERVATIONS)
    path = dataset_path(profile, robot, gravity, data_dir)
    n_steps = int(round(profile.episode_seconds / DT))
    return simulated_dataset(
        path,
        lambda: polynomial_excitation(
            profile.n_episodes, n_steps, np.random.default_rng(profile.seed), n_inputs=robot.n_inputs
        ),
        Simulator(robot, gravity=gravity),
        profile.seed,
        progress=progress,
        observation=observation,
    )


class DatasetOnDemand:
    """The profile's dataset, made (or read from its cache) only when its episodes are first
    used: its key, rod and gravity are known before, which is all a shipped model needs to be
    found current, so scoring a shipped model never simulates 3000 episodes first."""

    def __init__(self, profile: Profile, robot: Robot = SIM_ROBOT, gravity: str = "vertical", **options):
        observation = options.get("observation", "tip")
        stem = dataset_path(profile, robot, gravity).stem
        self.key, self.robot, self.gravity = stem if observation == "tip" else f"{stem}-{observation}", robot, gravity
        self._make = lambda: load_dataset(profile, robot, gravity, **options)
        self._dataset = None

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        if self._dataset is None:
            self._dataset = self._make()
        return getattr(self._dataset, name)


def simulated_dataset(
    path: Path,
    excitation,
    simulator: Simulator,
    seed: int,
    *,
    u_max: float = U_MAX,
    progress: bool = True,
    observation: str = "tip",
) -> Dataset:
    """The Dataset cached at ``path``, or the episodes of ``excitation()`` (E, T, m) run through
    ``simulator`` and split by ``seed``, saved there; its states as ``observation`` sees them.
    A rod of several segments also saves its inner disks' states (``disks``, (E, T+1, S-1, 6):
    position, velocity). Generation runs in blocks saved as they finish, so an interrupted run
    resumes where it stopped; the final file appears atomically."""
    robot, gravity = simulator.robot, simulator.gravity
    cached = _dataset_from(read_npz(path), path.stem, robot, gravity, u_max, observation)
    if cached is not None:
        return cached
    u = excitation()
    n_episodes, n_steps, _ = u.shape
    inner = len(robot.segment_lengths) > 1
    blocks_dir = path.with_suffix(".blocks")
    blocks_dir.mkdir(parents=True, exist_ok=True)
    blocks = []
    for start in range(0, n_episodes, BLOCK_EPISODES):
        stop = min(start + BLOCK_EPISODES, n_episodes)
        block_path = blocks_dir / f"{start:06d}.npz"
        done = read_npz(block_path) or {}
        if (
            done.get("states") is None
            or done["states"].shape[:2] != (stop - start, n_steps + 1)
            or (inner and "disks" not in done)
        ):
            done = _simulate(simulator, u[start:stop], inner, progress)
            write_npz(block_path, **done)
        blocks.append(done)
    train, val, test = split_episodes(n_episodes, seed)
    arrays = {name: np.concatenate([block[name] for block in blocks]) for name in blocks[0]}
    write_npz(path, u=u, **arrays, train=train, val=val, test=test)
    shutil.rmtree(blocks_dir, ignore_errors=True)  # another process making the same data may clean up first
    return _dataset_from(read_npz(path), path.stem, robot, gravity, u_max, observation)


def _simulate(simulator: Simulator, u, inner: bool, progress: bool) -> dict:
    """A block's arrays: the tip states (B, T+1, 6), and with ``inner`` the inner disks' (B, T+1, S-1, 6)."""
    if not inner:
        return dict(states=simulator.rollout(u, progress=progress))
    positions, velocities = disk_rollout(simulator, u, progress=progress)
    both = np.concatenate([positions, velocities], -1)  # (B, T+1, S, 6)
    return dict(states=both[..., -1, :], disks=both[..., :-1, :])


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
