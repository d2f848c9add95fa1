"""Recorded runs, one table per episode, made into the Dataset training uses: model-free inverse
dynamics for any robot whose inputs and tip were logged.

The format (docs/recordings.md): a ``time_s`` column (s, never decreasing); the inputs, any
number of columns in any units (by default every column whose name starts with ``u``); the tip
position in m (``x_m``, ``y_m`` and ``z_m`` where measured). A row carries a command (every
input set), a camera frame (the tip set), both, or neither; a lost frame is a row whose tip
cells are empty, so commands and frames at different rates share one table.

What is estimated, on a regular grid of period ``dt`` (the commands' period by default) that
starts at the first command once every tip column has a frame and ends where the frames or the
commands end: the tip position and velocity per axis, by the smoother of ``smoothing``, and the
input of each step, the mean over it of the commands, each held until the next (zero-order
hold). A run of lost frames up to ``max_gap`` s is bridged by the smoother; a longer one is
refused, naming its rows, never filled: cut the file there.
"""

from __future__ import annotations

import hashlib
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from softflow.data.dataset import Dataset, split_episodes
from softflow.data.smoothing import check_levels, smooth
from softflow.store import DATA_DIR, cache_file, cached_arrays, content_key

RECORDINGS_VERSION = 1  # bump when the resampling, the smoother, the episodes or the split change
TIME = "time_s"
TIP = ("x_m", "y_m", "z_m")
SUFFIXES = (".csv", ".parquet")
MAX_GAP = 0.2  # s: the longest run of lost frames the smoother bridges (6 frames at 30 fps)


@dataclass(frozen=True)
class Recording:
    """One recorded run on a regular grid: times (T+1,) s, inputs (T, m) (the mean command over
    each step, in the file's units), states (T+1, d) (tip positions in m, then their velocities in
    m/s, both smoothed), the period ``dt`` (s), the columns they came from, and the smoother's
    levels per tip column (frame noise in m, jerk density in m/s^3/sqrt(Hz))."""

    source: str
    times: np.ndarray
    inputs: np.ndarray
    states: np.ndarray
    dt: float
    input_columns: tuple[str, ...]
    tip_columns: tuple[str, ...]
    noise: np.ndarray
    jerk: np.ndarray

    def __post_init__(self):
        T, m, k = len(self.inputs), len(self.input_columns), len(self.tip_columns)
        if self.inputs.shape != (T, m) or self.times.shape != (T + 1,) or self.states.shape != (T + 1, 2 * k):
            raise ValueError(
                f"need times (T+1,), inputs (T, m) and states (T+1, 2k) for m = {m} input and k = {k} tip columns; got "
                f"{self.times.shape}, {self.inputs.shape} and {self.states.shape}"
            )


@dataclass(frozen=True)
class _Table:
    """The checked columns of one file: times (R,), inputs (R, m) with NaN rows where no command
    was given, tip (R, k) with NaN where no frame was taken, and the commands' period (s)."""

    source: str
    times: np.ndarray
    inputs: np.ndarray
    tip: np.ndarray
    input_columns: tuple[str, ...]
    tip_columns: tuple[str, ...]
    command_period: float

    @property
    def commands(self) -> np.ndarray:
        """Rows that give a command (every input set)."""
        return np.flatnonzero(np.isfinite(self.inputs).all(1))


# ---------------------------------------------------------------------------- one file
def _frame(source: str, content: bytes) -> pd.DataFrame:
    """The file's table, read by pandas (no pickles)."""
    suffix = Path(source).suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{source}: a recording is a {' or '.join(SUFFIXES)} file; got {suffix or 'no suffix'!r}")
    try:
        if suffix == ".parquet":
            return pd.read_parquet(io.BytesIO(content))
        return pd.read_csv(io.BytesIO(content))
    except ImportError as error:
        raise ValueError(
            f"{source}: reading Parquet needs pyarrow or fastparquet, which this environment lacks; "
            f"write the recording as CSV instead ({error})"
        ) from error
    except (ValueError, OSError) as error:  # pandas' parser errors and undecodable bytes among them
        raise ValueError(f"{source}: not a readable {suffix[1:]} table ({error})") from error


def _numbers(frame: pd.DataFrame, column: str, source: str) -> np.ndarray:
    """A column as floats (R,), empty cells NaN; text or infinity is an error naming its row."""
    cells = frame[column]
    values = pd.to_numeric(cells, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
    bad = np.flatnonzero((np.isnan(values) & cells.notna().to_numpy()) | np.isinf(values))
    if len(bad):
        raise ValueError(f"{source}: row {bad[0]}, column {column!r}: {cells.iloc[bad[0]]!r} is not a finite number")
    return values


def _column_names(given, default, what: str, source: str, columns) -> tuple[str, ...]:
    """The columns the user named (each must be there) or the default ones."""
    if given is None:
        names = tuple(default)
        if not names:
            raise ValueError(f"{source}: no {what} columns found among {list(columns)}; name them with {what}=[...]")
        return names
    if isinstance(given, str) or not given or not all(isinstance(name, str) for name in given):
        raise ValueError(f"{what} must be None or a non-empty list of column names; got {given!r}")
    if len(set(given)) != len(given):
        raise ValueError(f"{what} must name each column once; got {list(given)}")
    missing = [name for name in given if name not in columns]
    if missing:
        raise ValueError(f"{source}: no {what} column {missing[0]!r} (the columns are {list(columns)})")
    return tuple(given)


def _table(source: str, content: bytes, inputs=None, tip=None) -> _Table:
    """The file's time, input and tip columns, checked; every error names the file, and the row
    and the column where there is one (rows count from 0 below the header, as pandas does)."""
    frame = _frame(source, content)
    columns = [str(name) for name in frame.columns]
    frame.columns = columns
    if TIME not in columns:
        raise ValueError(f"{source}: no time column {TIME!r} (the columns are {columns})")
    input_columns = _column_names(inputs, [name for name in columns if name.startswith("u")], "inputs", source, columns)
    tip_columns = _column_names(tip, [name for name in TIP if name in columns], "tip", source, columns)
    if tip is None and len(tip_columns) < 2:
        raise ValueError(
            f"{source}: found tip columns {list(tip_columns)}; expected at least two of {list(TIP)} "
            "(or name them with tip=)"
        )
    clash = set(input_columns) & ({TIME} | set(tip_columns))
    if clash:
        raise ValueError(f"{source}: column {sorted(clash)[0]!r} cannot be an input and the time or the tip")

    times = _numbers(frame, TIME, source)
    if np.isnan(times).any():
        raise ValueError(f"{source}: row {np.flatnonzero(np.isnan(times))[0]}, column {TIME!r}: no time")
    backwards = np.flatnonzero(np.diff(times) < 0)
    if len(backwards):
        row = backwards[0] + 1
        raise ValueError(
            f"{source}: row {row}, column {TIME!r}: time runs backwards ({times[row]} s after {times[row - 1]} s)"
        )
    p = np.stack([_numbers(frame, name, source) for name in tip_columns], -1)  # (R, k)
    for i, name in enumerate(tip_columns):
        frames = np.flatnonzero(np.isfinite(p[:, i]))
        if len(frames) == 0:
            raise ValueError(
                f"{source}: column {name!r}: no tip position at all (every row empty; name the measured with tip=)"
            )
        if len(frames) == 1:
            raise ValueError(f"{source}: column {name!r}: fewer than two frames (only row {frames[0]})")
    u = np.stack([_numbers(frame, name, source) for name in input_columns], -1)  # (R, m)
    given = np.isfinite(u)
    partial = np.flatnonzero(given.any(1) & ~given.all(1))
    if len(partial):
        row = partial[0]
        empty = input_columns[int(np.flatnonzero(~given[row])[0])]
        raise ValueError(
            f"{source}: row {row}, column {empty!r}: empty while other inputs are set (a command sets all)"
        )
    commands = times[given.all(1)]
    if len(commands) < 2:
        raise ValueError(f"{source}: fewer than two commands (rows with every one of {list(input_columns)} set)")
    median = float(np.median(np.diff(commands)))
    if not median > 0:
        raise ValueError(f"{source}: column {TIME!r}: the commands' median interval is 0 s (most share a time)")
    span = commands[-1] - commands[0]
    period = span / round(span / median)  # the median (robust to jitter and lost commands), refined over the span
    return _Table(source, times, u, p, input_columns, tip_columns, period)


def _held_means(table: _Table, grid: np.ndarray) -> np.ndarray:
    """The mean over each step of the grid (T+1,) of the commands, each held until the next and
    the last for one command period: (T, m), exact for a piecewise-constant input."""
    rows = table.commands
    knots = np.append(table.times[rows], table.times[rows[-1]] + table.command_period)  # (K+1,)
    held = table.inputs[rows] * np.diff(knots)[:, None]  # (K, m)
    integral = np.concatenate([np.zeros((1, held.shape[1])), np.cumsum(held, 0)])  # (K+1, m)
    at_grid = np.stack([np.interp(grid, knots, channel) for channel in integral.T], -1)  # (T+1, m)
    return np.diff(at_grid, axis=0) / np.diff(grid)[:, None]


def _resample(table: _Table, dt: float, max_gap: float, noise, jerk) -> Recording:
    """The table on its grid of period dt: held commands averaged, tip smoothed, long gaps refused."""
    source, times, tip = table.source, table.times, table.tip
    commands = times[table.commands]
    frames = [np.flatnonzero(np.isfinite(column)) for column in tip.T]  # rows with a frame, per column
    start = max(times[rows[0]] for rows in frames)
    end = min(min(times[rows[-1]] for rows in frames), commands[-1] + table.command_period)
    first = np.searchsorted(commands, start)
    n_steps = math.floor((end - commands[first]) / dt + 1e-9) if first < len(commands) else 0
    if n_steps < 1:
        raise ValueError(
            f"{source}: the commands and the frames of every tip column overlap for less than one step of {dt} s"
        )
    grid = commands[first] + dt * np.arange(n_steps + 1)  # (T+1,)
    for rows, name in zip(frames, table.tip_columns):
        t = times[rows]
        long = np.flatnonzero((np.diff(t) > max_gap) & (t[1:] > grid[0]) & (t[:-1] < grid[-1]))
        if len(long):
            a, b = rows[long[0]], rows[long[0] + 1]
            raise ValueError(
                f"{source}: rows {a}-{b}, column {name!r}: {times[b] - times[a]:.3f} s between frames "
                f"({times[a]} to {times[b]} s), longer than max_gap = {max_gap} s; cut the file there"
            )
    k = len(frames)
    states, levels = np.empty((n_steps + 1, 2 * k)), []  # (T+1, 2k)
    for i, rows in enumerate(frames):
        try:
            states[:, i], states[:, k + i], *level = smooth(times[rows], tip[rows, i], grid, noise=noise, jerk=jerk)
        except ValueError as error:
            raise ValueError(f"{source}: column {table.tip_columns[i]!r}: {error}") from error
        levels.append(level)
    noise_used, jerk_used = np.array(levels).T  # (k,) each
    return Recording(
        source,
        grid,
        _held_means(table, grid),
        states,
        float(dt),
        table.input_columns,
        table.tip_columns,
        noise_used,
        jerk_used,
    )


def _check_options(dt, max_gap, noise, jerk) -> None:
    if dt is not None and not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be None (the commands' period) or a positive period in s; got {dt!r}")
    if not (isinstance(max_gap, (int, float)) and math.isfinite(max_gap) and max_gap > 0):
        raise ValueError(f"max_gap must be a positive duration in s; got {max_gap!r}")
    check_levels(noise, jerk)


def read(path, *, inputs=None, tip=None, dt=None, max_gap: float = MAX_GAP, noise=None, jerk=None) -> Recording:
    """One recorded run (a CSV or Parquet file) on a regular grid of period ``dt`` (s; default:
    the commands' period). ``inputs`` and ``tip`` name the columns (default: those
    starting with ``u``; those of x_m, y_m, z_m present). ``noise`` (m) and ``jerk``
    (m/s^3/sqrt(Hz)) fix the smoother's levels; by default each tip column's are fitted. A bad
    file is a ValueError naming it, and the row and column where there is one."""
    _check_options(dt, max_gap, noise, jerk)
    path = Path(path)
    try:
        content = path.read_bytes()
    except OSError as error:
        raise ValueError(f"{path}: cannot read the recording ({error})") from error
    table = _table(str(path), content, inputs, tip)
    return _resample(table, table.command_period if dt is None else dt, max_gap, noise, jerk)


# ---------------------------------------------------------------------------- a folder of runs
def recording_files(paths_or_folder) -> list[Path]:
    """The recordings a folder holds (its .csv and .parquet files, by name) or the files listed."""
    if isinstance(paths_or_folder, (str, Path)):
        path = Path(paths_or_folder)
        if path.is_dir():
            files = sorted(p for p in path.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file())
            if not files:
                raise ValueError(f"{path}: no recording files ({' or '.join(SUFFIXES)}) in the folder")
            return files
        paths_or_folder = [path]
    files = [Path(p) for p in paths_or_folder]
    if not files:
        raise ValueError("need a folder of recordings or a non-empty list of recording files; got an empty list")
    return files


def episodes(lengths, n_steps: int) -> list[tuple[int, int]]:
    """(recording, first step) of each episode of ``n_steps`` cut from recordings of ``lengths``
    steps: consecutive, and where a remainder is left one more that ends with the recording
    (overlapping the one before), so every recorded step is used and none is made up."""
    if not (isinstance(n_steps, int) and 1 <= n_steps <= min(lengths, default=0)):
        raise ValueError(
            f"n_steps must be an integer from 1 to the shortest length {min(lengths, default=0)}; got {n_steps!r}"
        )
    cuts = []
    for index, length in enumerate(lengths):
        starts = list(range(0, length - n_steps + 1, n_steps))
        if starts[-1] + n_steps < length:
            starts.append(length - n_steps)
        cuts += [(index, start) for start in starts]
    return cuts


def load_dataset(
    paths_or_folder,
    *,
    inputs=None,
    tip=None,
    dt=None,
    max_gap: float = MAX_GAP,
    noise=None,
    jerk=None,
    episode_seconds: float | None = None,
    fractions=(0.8, 0.1),
    seed: int = 0,
    data_dir: Path | None = DATA_DIR,
) -> Dataset:
    """The Dataset of a folder (or list) of recordings, as training uses it (no rod: robot=None).

    Every recording is read as by ``read`` (``dt``: default the median of the files' command
    periods) with the same columns, then cut into episodes of ``episode_seconds`` (default: the
    shortest recording; see ``episodes``). The split is by recording (``split_episodes`` over the
    recordings, with ``fractions`` and ``seed``): every episode of a run lands in the same split.
    The result is cached under ``data_dir`` (None: not cached) by the files' contents and these
    options, written atomically after every file was read, so a bad file leaves no cache."""
    _check_options(dt, max_gap, noise, jerk)
    if episode_seconds is not None and not (
        isinstance(episode_seconds, (int, float)) and math.isfinite(episode_seconds) and episode_seconds > 0
    ):
        raise ValueError(f"episode_seconds must be None (the shortest recording) or positive; got {episode_seconds!r}")
    if not (len(fractions) == 2 and all(0 < f < 1 for f in fractions) and sum(fractions) < 1):
        raise ValueError(f"fractions must be (train, validation) shares in (0, 1) summing below 1; got {fractions!r}")
    files = recording_files(paths_or_folder)
    splits = split_episodes(len(files), seed, fractions)
    for name, chosen in zip(("train", "validation", "test"), splits):
        if len(chosen) == 0:
            raise ValueError(
                f"{len(files)} recordings split by {tuple(fractions)} leave the {name} split empty; "
                "record more runs or pass other fractions (e.g. (1/3, 1/3) for three)"
            )
    contents = []
    for path in files:
        try:
            contents.append(path.read_bytes())
        except OSError as error:
            raise ValueError(f"{path}: cannot read the recording ({error})") from error
    spec = dict(
        files=[hashlib.sha256(content).hexdigest() for content in contents],
        inputs=inputs,
        tip=tip,
        dt=dt,
        max_gap=max_gap,
        noise=noise,
        jerk=jerk,
        episode_seconds=episode_seconds,
        fractions=list(fractions),
        seed=seed,
        version=RECORDINGS_VERSION,
    )

    def compute() -> dict:
        tables = [_table(str(path), content, inputs, tip) for path, content in zip(files, contents)]
        for table in tables[1:]:
            for what in ("input_columns", "tip_columns"):
                if getattr(table, what) != getattr(tables[0], what):
                    raise ValueError(
                        f"{table.source}: {what.replace('_', ' ')} {list(getattr(table, what))} differ from "
                        f"{list(getattr(tables[0], what))} of {tables[0].source}; name them with inputs= and tip="
                    )
        period = float(np.median([table.command_period for table in tables])) if dt is None else dt
        runs = [_resample(table, period, max_gap, noise, jerk) for table in tables]
        lengths = [len(run.inputs) for run in runs]
        n_steps = min(lengths) if episode_seconds is None else int(round(episode_seconds / period))
        if n_steps < 1:
            raise ValueError(f"episode_seconds = {episode_seconds} is shorter than one step of {period} s")
        short = [run.source for run, length in zip(runs, lengths) if length < n_steps]
        if short:
            raise ValueError(
                f"{short[0]}: shorter than one episode ({episode_seconds} s = {n_steps} steps of {period} s); "
                "pass a shorter episode_seconds"
            )
        cuts = episodes(lengths, n_steps)
        owner = np.array([index for index, _ in cuts])
        train, val, test = (np.flatnonzero(np.isin(owner, chosen)) for chosen in splits)
        return dict(
            u=np.stack([runs[i].inputs[s : s + n_steps] for i, s in cuts]),  # (E, T, m)
            states=np.stack([runs[i].states[s : s + n_steps + 1] for i, s in cuts]),  # (E, T+1, d)
            train=train,
            val=val,
            test=test,
            dt=np.float64(period),
        )

    if data_dir is None:
        return _dataset(compute(), f"recordings-{content_key(spec)}")
    path = cache_file(data_dir, "recordings", spec)
    return _dataset(
        cached_arrays(path, compute, valid=lambda arrays: _dataset(arrays, path.stem) is not None), path.stem
    )


def _dataset(arrays: dict, key: str) -> Dataset | None:
    """The Dataset of the arrays (cached or just made), or None when they do not make one."""
    try:
        data = Dataset(
            **{k: arrays[k] for k in ("u", "states", "train", "val", "test")},
            key=key,
            robot=None,
            gravity=None,
            dt=float(arrays["dt"]),
        )
    except (KeyError, TypeError, ValueError):
        return None
    splits = np.concatenate([data.train, data.val, data.test])
    consistent = (
        np.isfinite(data.u).all()
        and np.isfinite(data.states).all()
        and data.states.shape[-1] % 2 == 0
        and np.array_equal(np.sort(splits), np.arange(len(data.u)))
        and min(len(data.train), len(data.val), len(data.test)) > 0
    )
    return data if consistent else None
