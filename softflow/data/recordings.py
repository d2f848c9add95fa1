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
hold). A run of lost frames up to ``max_gap`` s, or up to BRIDGED_FRAMES frames of a slower
camera, is bridged by the smoother; a longer one is refused, naming its rows and the frames judged
lost there, never filled: cut the file there, or let ``load_dataset`` cut it (``split_at_gaps``).
Frames a tracker held (a point exactly repeating its last frame while it moves) or that jumped
for one frame are lost frames too (``lost_frames``). Each recording carries its
input-to-motion delay (``estimate_delay``); the Dataset pairs each step with the input sent that
many periods before it.
"""

from __future__ import annotations

import hashlib
import io
import math
import re
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from softflow.data.dataset import Dataset, split_episodes
from softflow.data.smoothing import check_levels, smooth
from softflow.store import DATA_DIR, cache_file, cached_arrays, content_key

# bump when what the twin's recordings load as changes (the recorded study's rows key on it)
RECORDINGS_VERSION = 1
# bump when any recording's arrays may change: it keys the cached datasets and the rows of the
# studies of real runs. 2: held and jumped frames are lost frames, and the pairs carry the
# input-to-motion delay (the twin's runs have neither: their arrays at delay=0 are those of
# revision 1). 3: a repeat that the camera's resolution explains is no held frame, and a slow
# camera's run of BRIDGED_FRAMES lost frames is bridged (every shipped recording loses the same
# frames as in revision 2, so the rows keyed on 2 were carried over)
LOADER_REVISION = 3
TIME = "time_s"
TIP = ("x_m", "y_m", "z_m")
SUFFIXES = (".csv", ".csv.gz", ".parquet")
MAX_GAP = 0.2  # s: the longest run of lost frames the smoother bridges, at least (6 frames at 30 fps)
# A frame departing from the chord between its neighbouring frames by more than a constant
# acceleration of JUMP_ACCELERATION would (a h1 h2 / 2: 2.5 mm at 100 Hz, 28 mm at 30 fps) while
# the neighbours lie nearer each other than that departure is a jump (a missed frame). The ASL
# trunk's disks reach 6-12 m/s^2 (99.9th percentile over 50 ms; 13-22 at most) and its frames
# have 0.003-0.008 mm of noise; the twin's camera noise alone makes at most 13 m/s^2 at 30 fps.
JUMP_ACCELERATION = 50.0  # m/s^2
JUMP_NOISE = 10.0  # and by more than this many times the point's median departure (noisy cameras)
HELD, JUMPED = 1, 2  # why a frame was lost (lost_frames)
BRIDGED_FRAMES = 5  # a slow camera's run of this many lost frames is bridged whatever max_gap says
STILL_QUANTA = 3  # a point moving by at most this many steps of its resolution is still (_held)
MAX_DELAY = 0.5  # s: the longest input-to-motion delay estimated (at most a quarter of the run)
DELAY_FOLDS = 5  # contiguous blocks of the run, each held out once when scoring a delay
DELAY_SPREAD = 2  # periods: estimates whose quartiles lie further apart are warned about
DELAY_TOLERANCE = 0.05  # a local best within 5 % of the best unexplained variance is as good
SLOWEST_STEP = 1.0  # s: a median time step this long or longer is milliseconds written as seconds
WIDEST_SPAN = 10.0  # m: a tip column spanning more is millimetres written as metres


@dataclass(frozen=True)
class Recording:
    """One recorded run on a regular grid: times (T+1,) s, inputs (T, m) (the mean command over
    each step, in the file's units), states (T+1, d) (tip positions in m, then their velocities in
    m/s, both smoothed), the period ``dt`` (s), the columns they came from, the smoother's levels
    per tip column (frame noise in m, jerk density in m/s^3/sqrt(Hz)), the frames lost per tip
    column, and the input-to-motion delay. The arrays are as recorded (input t is the one sent
    at the start of step t); ``pairs()`` pairs them across the delay."""

    source: str
    times: np.ndarray
    inputs: np.ndarray
    states: np.ndarray
    dt: float
    input_columns: tuple[str, ...]
    tip_columns: tuple[str, ...]
    noise: np.ndarray
    jerk: np.ndarray
    frozen: np.ndarray  # (k,) frames of each tip column's point that repeated the one before (lost)
    jumps: np.ndarray  # (k,) frames of each tip column's point that jumped for one frame (lost)
    delay: float = 0.0  # s: input-to-motion delay, estimated or given (NaN: too short to estimate)
    delay_steps: int = 0  # the delay in whole periods: what pairs() shifts by (0 where NaN)

    def __post_init__(self):
        T, m, k = len(self.inputs), len(self.input_columns), len(self.tip_columns)
        if self.inputs.shape != (T, m) or self.times.shape != (T + 1,) or self.states.shape != (T + 1, 2 * k):
            raise ValueError(
                f"need times (T+1,), inputs (T, m) and states (T+1, 2k) for m = {m} input and k = {k} tip columns; got "
                f"{self.times.shape}, {self.inputs.shape} and {self.states.shape}"
            )

    def pairs(self, steps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Inputs (T-d, m) and states (T-d+1, 2k) with step t of the states (x_t to x_{t+1}) paired
        with the input sent d periods before it (d: ``steps``, default ``delay_steps``): the
        first d states and the last d inputs are dropped."""
        d = self.delay_steps if steps is None else steps
        if not (isinstance(d, (int, np.integer)) and 0 <= d < len(self.inputs)):
            raise ValueError(
                f"{self.source}: a delay of {d!r} periods leaves no pair; expected 0 to {len(self.inputs) - 1} "
                f"(the run has {len(self.inputs)} steps)"
            )
        return self.inputs[: len(self.inputs) - d], self.states[d:]


@dataclass(frozen=True)
class _Table:
    """The checked columns of one file: times (R,), inputs (R, m) with NaN rows where no command
    was given, tip (R, k) with NaN where no frame was taken or it was lost (``lost``, (R, k): HELD
    or JUMPED frames, counted per column in ``frozen`` and ``jumps``), the commands' period (s)
    and each tip column's camera's (k,) (s: the median interval between its frames as written)."""

    source: str
    times: np.ndarray
    inputs: np.ndarray
    tip: np.ndarray
    input_columns: tuple[str, ...]
    tip_columns: tuple[str, ...]
    command_period: float
    frame_period: np.ndarray
    lost: np.ndarray
    frozen: np.ndarray
    jumps: np.ndarray

    def bridged(self, max_gap: float) -> np.ndarray:
        """The longest run without a frame the smoother bridges, per tip column (k,) s: max_gap,
        or BRIDGED_FRAMES lost frames in a row of that column's camera where it is slower."""
        return np.maximum(max_gap, (BRIDGED_FRAMES + 1) * np.nan_to_num(self.frame_period))

    def rows(self, keep: np.ndarray, source: str) -> _Table:
        """The table of the rows ``keep`` (R,) bool, named ``source``."""
        return replace(
            self,
            source=source,
            times=self.times[keep],
            inputs=self.inputs[keep],
            tip=self.tip[keep],
            lost=self.lost[keep],
        )

    @property
    def commands(self) -> np.ndarray:
        """Rows that give a command (every input set)."""
        return np.flatnonzero(np.isfinite(self.inputs).all(1))


# ---------------------------------------------------------------------------- one file
def _suffix(path) -> str:
    """The recording's kind by name: ".csv", ".csv.gz" (gzip-compressed CSV), ".parquet", or another."""
    name = Path(path).name.lower()
    return ".csv.gz" if name.endswith(".csv.gz") else Path(name).suffix


def _frame(source: str, content: bytes) -> pd.DataFrame:
    """The file's table, read by pandas (no pickles)."""
    suffix = _suffix(source)
    if suffix not in SUFFIXES:
        raise ValueError(f"{source}: a recording is a {', '.join(SUFFIXES)} file; got {suffix or 'no suffix'!r}")
    try:
        if suffix == ".parquet":
            return pd.read_parquet(io.BytesIO(content))
        return pd.read_csv(io.BytesIO(content), compression="gzip" if suffix == ".csv.gz" else None)
    except ImportError as error:
        raise ValueError(
            f"{source}: reading Parquet needs pyarrow or fastparquet, which this environment lacks; "
            f"write the recording as CSV instead ({error})"
        ) from error
    except (ValueError, OSError, EOFError) as error:  # parser errors, undecodable bytes, broken gzip among them
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


def _table(
    source: str, content: bytes, inputs=None, tip=None, dropouts: bool = True, max_acceleration=JUMP_ACCELERATION
) -> _Table:
    """The file's time, input and tip columns, checked, with held and jumped frames lost (unless
    not ``dropouts``; ``lost_frames``); every error names the file, and the row and the column
    where there is one (rows count from 0 below the header, as pandas does)."""
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
    _check_time_unit(times, source)
    p = np.stack([_numbers(frame, name, source) for name in tip_columns], -1)  # (R, k)
    _check_tip_unit(p, tip_columns, source)
    frame_period = np.array([_median_step(times[np.isfinite(column)]) for column in p.T])  # (k,) s
    if dropouts:
        lost, frozen, jumps = _judged(times, p, tip_columns, max_acceleration)
    else:
        lost, frozen, jumps = np.zeros(p.shape, np.int8), 0, 0
    p = np.where(lost > 0, np.nan, p)
    for i, name in enumerate(tip_columns):
        frames = np.flatnonzero(np.isfinite(p[:, i]))
        if len(frames) == 0:
            raise ValueError(
                f"{source}: column {name!r}: no tip position at all (every row empty; name the measured with tip=)"
            )
        if len(frames) == 1:
            held = int(frozen[i]) if np.ndim(frozen) else 0
            why = (
                f"; the other {held} repeat the one before exactly and count as held frames (a constant column: "
                "leave it out of the tip columns)"
                if held
                else ""
            )
            raise ValueError(f"{source}: column {name!r}: fewer than two frames (only row {frames[0]}){why}")
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
    k = len(tip_columns)
    return _Table(
        source,
        times,
        u,
        p,
        input_columns,
        tip_columns,
        period,
        frame_period,
        lost,
        np.zeros(k, int) + frozen,
        np.zeros(k, int) + jumps,
    )


def _median_step(times: np.ndarray) -> float:
    """The median interval (s) between the times (N,) given, NaN for fewer than two."""
    return float(np.median(np.diff(times))) if len(times) > 1 else math.nan


def _check_time_unit(times: np.ndarray, source: str) -> None:
    """Refuse times whose steps are implausible in seconds (a log in ms or us)."""
    steps = np.diff(np.unique(times))
    if len(steps) and np.median(steps) >= SLOWEST_STEP:
        unit = "microseconds" if np.median(steps) >= 1000 * SLOWEST_STEP else "milliseconds"
        raise ValueError(
            f"{source}: column {TIME!r}: the median step between times is {np.median(steps):g}; "
            f"{TIME} looks like {unit} (expected seconds: a rig logging once a second or slower is unlikely)"
        )


def _check_tip_unit(tip: np.ndarray, tip_columns, source: str) -> None:
    """Refuse a tip column in metres (``_m``) that spans more than WIDEST_SPAN (a log in mm); warn
    where a tip column's name says another unit (its numbers are read as metres all the same)."""
    for i, name in enumerate(tip_columns):
        if unit := next((unit for suffix, unit in SUSPECT_UNITS.items() if name.endswith(suffix)), None):
            warnings.warn(
                f"{source}: column {name!r} is read as metres, though its name says {unit}: convert it to "
                "metres (or rename it if it holds metres)",
                stacklevel=4,
            )
        measured = tip[np.isfinite(tip[:, i]), i]
        if name.endswith("_m") and len(measured) and np.ptp(measured) > WIDEST_SPAN:
            raise ValueError(
                f"{source}: column {name!r}: positions span {np.ptp(measured):g} (more than {WIDEST_SPAN:g} m); "
                "it looks like millimetres: write metres, or name the tip columns meant with tip=[...]"
            )


# ---------------------------------------------------------------------------- lost frames
def tip_points(tip_columns) -> list[list[int]]:
    """The tip columns grouped into measured points by name: x1_m, y1_m, z1_m are one point (the
    first disk), x_m, y_m, z_m another; a column named otherwise is a point of its own. Indices
    into ``tip_columns``, points in order of their first column."""
    points = {}
    for i, name in enumerate(tip_columns):
        axis = re.fullmatch(r"[xyz](.*)_m", name)
        points.setdefault(("point", axis.group(1)) if axis else ("column", name), []).append(i)
    return list(points.values())


def lost_frames(
    times, tip, tip_columns, max_acceleration: float = JUMP_ACCELERATION
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames a tracker lost without saying so, per point (``tip_points``): (lost (R, k) bool,
    frozen (k,), jumps (k,)), the counts per tip column (its point's).

    Frozen: a point whose coordinates all exactly repeat its previous frame's (motion capture
    holding its last value; real noise never repeats all of them), unless the camera's
    resolution explains it (``_held``). Jump: among the frames left,
    one departing from the chord between its neighbouring frames by more than both a constant
    acceleration of ``max_acceleration`` (m/s^2: the robot's largest, JUMP_ACCELERATION by
    default) would (a h1 h2 / 2 for steps h1, h2) and JUMP_NOISE times the point's median
    departure, while the neighbours lie nearer each other than that departure (out and back)."""
    why, frozen, jumps = _judged(times, tip, tip_columns, max_acceleration)
    return why > 0, frozen, jumps


def _judged(times, tip, tip_columns, max_acceleration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``lost_frames`` with why each frame was lost: (R, k) HELD, JUMPED or 0 (kept, or no frame)."""
    times, tip = np.asarray(times, float), np.asarray(tip, float)
    lost = np.zeros(tip.shape, np.int8)  # (R, k): 0 kept (or no frame), HELD or JUMPED
    frozen, jumps = np.zeros(tip.shape[1], int), np.zeros(tip.shape[1], int)
    for columns in tip_points(tip_columns):
        point = tip[:, columns]  # (R, c)
        rows = np.flatnonzero(np.isfinite(point).all(1))  # the point's frames
        held = _held(point[rows])
        kept = rows[~held]
        jumped = kept[1:-1][_jumped(times[kept], point[kept], max_acceleration)]
        lost[np.ix_(rows[held], columns)] = HELD
        lost[np.ix_(jumped, columns)] = JUMPED
        frozen[columns], jumps[columns] = held.sum(), len(jumped)
    return lost, frozen, jumps


def _held(point: np.ndarray) -> np.ndarray:
    """Which of a point's frames (F, c) a tracker held: (F,) bool. A frame repeating the one
    before exactly is held unless the camera's resolution explains it: where the point moves by
    at most STILL_QUANTA of its coordinates' resolution (the smallest step each ever makes) into
    the repeats and out of them, a still point seen by a coarse camera (pixels, a logger's few
    digits) repeats for real. A point that never moves holds every frame after its first."""
    steps = np.abs(np.diff(point, axis=0))  # (F-1, c)
    repeat = np.concatenate([np.zeros(min(len(point), 1), bool), (steps == 0).all(1)])  # (F,)
    moved = steps > 0
    if not repeat.any() or not moved.any():
        return repeat
    quantum = np.array([s[m].min() if m.any() else np.inf for s, m in zip(steps.T, moved.T)])  # (c,)
    still = np.concatenate([[True], (steps <= STILL_QUANTA * quantum).all(1), [True]])  # (F+1,): step into frame i
    starts = np.flatnonzero(repeat & ~np.concatenate([[False], repeat[:-1]]))  # first frame of each run of repeats
    ends = np.flatnonzero(repeat & ~np.concatenate([repeat[1:], [False]]))  # its last
    held = repeat.copy()
    for start, end in zip(starts, ends):
        if still[start - 1] and still[end + 1]:  # the step into the frame repeated and the step out of the run
            held[start : end + 1] = False
    return held


def _jumped(t: np.ndarray, point: np.ndarray, max_acceleration: float) -> np.ndarray:
    """Which inner frames of a point's frames (F, c) at times t (F,) jumped: (F-2,) bool."""
    if len(t) < 3:
        return np.zeros(max(len(t) - 2, 0), bool)
    before, after = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    share = np.divide(before, before + after, out=np.full(len(before), 0.5), where=before + after > 0)
    chord = point[:-2] + share[:, None] * (point[2:] - point[:-2])  # (F-2, c)
    departure = np.linalg.norm(point[1:-1] - chord, axis=1)
    apart = np.linalg.norm(point[2:] - point[:-2], axis=1)
    threshold = np.maximum(max_acceleration * before * after / 2, JUMP_NOISE * np.median(departure))
    return (departure > threshold) & (apart < departure)


def _held_means(table: _Table, grid: np.ndarray) -> np.ndarray:
    """The mean over each step of the grid (T+1,) of the commands, each held until the next and
    the last for one command period: (T, m), exact for a piecewise-constant input."""
    rows = table.commands
    knots = np.append(table.times[rows], table.times[rows[-1]] + table.command_period)  # (K+1,)
    held = table.inputs[rows] * np.diff(knots)[:, None]  # (K, m)
    integral = np.concatenate([np.zeros((1, held.shape[1])), np.cumsum(held, 0)])  # (K+1, m)
    at_grid = np.stack([np.interp(grid, knots, channel) for channel in integral.T], -1)  # (T+1, m)
    return np.diff(at_grid, axis=0) / np.diff(grid)[:, None]


def _grid(table: _Table, dt: float) -> np.ndarray | None:
    """The regular grid (T+1,) of period dt from the first command once every tip column has a
    frame to where the frames or the commands end; None where that is less than one step."""
    times, commands = table.times, table.times[table.commands]
    frames = [np.flatnonzero(np.isfinite(column)) for column in table.tip.T]  # rows with a frame, per column
    if len(commands) == 0 or any(len(rows) == 0 for rows in frames):
        return None
    start = max(times[rows[0]] for rows in frames)
    end = min(min(times[rows[-1]] for rows in frames), commands[-1] + table.command_period)
    first = np.searchsorted(commands, start)
    n_steps = math.floor((end - commands[first]) / dt + 1e-9) if first < len(commands) else 0
    return commands[first] + dt * np.arange(n_steps + 1) if n_steps >= 1 else None


def _long_gaps(table: _Table, max_gap: float, within=(-np.inf, np.inf)) -> list[tuple[int, int, int]]:
    """(column, row before, row after) of every run of lost frames longer than the smoother
    bridges (``_Table.bridged``) that reaches into the interval ``within``, in column order."""
    gaps = []
    for i, (column, bridged) in enumerate(zip(table.tip.T, table.bridged(max_gap))):
        rows = np.flatnonzero(np.isfinite(column))
        t = table.times[rows]
        longer = np.diff(t) > bridged * (1 + 1e-9)  # a gap of max_gap itself is bridged, whatever the rounding
        long = np.flatnonzero(longer & (t[1:] > within[0]) & (t[:-1] < within[1]))
        gaps += [(i, rows[j], rows[j + 1]) for j in long]
    return gaps


def _judged_lost(why: np.ndarray, first_row: int) -> str:
    """The rows among ``why`` (the lost codes of rows from ``first_row`` on) judged lost, and why,
    as the end of a refusal ("" where none was)."""
    parts = [
        f"rows {_spans(first_row + np.flatnonzero(why == code))} {reason}"
        for code, reason in (
            (HELD, "repeat the frame before exactly (held)"),
            (JUMPED, "jumped for one frame (further than max_acceleration explains)"),
        )
        if (why == code).any()
    ]
    return f"; judged lost there: {'; '.join(parts)} (dropouts=False keeps them)" if parts else ""


def _spans(rows: np.ndarray) -> str:
    """Increasing row numbers as runs: [3, 4, 5, 9] is "3-5, 9"."""
    breaks = np.flatnonzero(np.diff(rows) > 1)
    firsts, lasts = rows[np.append(0, breaks + 1)], rows[np.append(breaks, len(rows) - 1)]
    return ", ".join(str(a) if a == b else f"{a}-{b}" for a, b in zip(firsts, lasts))


def _resample(table: _Table, dt: float, max_gap: float, noise, jerk, causal: bool = False) -> Recording:
    """The table on its grid of period dt: held commands averaged, tip smoothed (``causal``:
    filtered), long gaps refused."""
    source, times, tip = table.source, table.times, table.tip
    grid = _grid(table, dt)
    if grid is None:
        raise ValueError(
            f"{source}: the commands and the frames of every tip column overlap for less than one step of {dt} s"
        )
    for i, a, b in _long_gaps(table, max_gap, (grid[0], grid[-1]))[:1]:
        bridged = table.bridged(max_gap)[i]
        limit = f"max_gap = {max_gap} s" if bridged == max_gap else f"{BRIDGED_FRAMES} lost frames of its camera"
        raise ValueError(
            f"{source}: rows {a}-{b}, column {table.tip_columns[i]!r}: {times[b] - times[a]:.3f} s between frames "
            f"({times[a]} to {times[b]} s), longer than the {bridged:.3g} s bridged ({limit}); cut the file "
            f"there, or let load_dataset(..., split_at_gaps=True) cut it{_judged_lost(table.lost[a + 1 : b, i], a + 1)}"
        )
    frames = [np.flatnonzero(np.isfinite(column)) for column in tip.T]
    k = len(frames)
    states, levels = np.empty((len(grid), 2 * k)), []  # (T+1, 2k)
    shown = dict(desc=f"smoothing {Path(source).name}", unit="column", disable=None, leave=False)  # a terminal only
    for i, rows in enumerate(tqdm(frames, **shown)):
        try:
            states[:, i], states[:, k + i], *level = smooth(
                times[rows], tip[rows, i], grid, noise=noise, jerk=jerk, causal=causal
            )
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
        table.frozen,
        table.jumps,
    )


def _pieces(table: _Table, dt: float, max_gap: float) -> list[_Table]:
    """The table cut at every run of lost frames longer than bridged (in any tip column): the
    stretches between them that make at least one step of dt, each named by its time span."""
    gaps = sorted((table.times[a], table.times[b]) for _, a, b in _long_gaps(table, max_gap))
    merged = []  # overlapping gaps of several columns make one
    for a, b in gaps:
        if merged and a <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], b))
        else:
            merged.append((a, b))
    starts = [table.times[0]] + [b for _, b in merged]
    ends = [a for a, _ in merged] + [table.times[-1]]
    pieces = []
    for start, end in zip(starts, ends):
        piece = table.rows((table.times >= start) & (table.times <= end), f"{table.source} ({start:g}-{end:g} s)")
        framed = all(np.isfinite(column).sum() >= 2 for column in piece.tip.T)
        if framed and len(piece.commands) >= 1 and _grid(piece, dt) is not None:
            pieces.append(piece)
    return pieces


# ---------------------------------------------------------------------------- the delay
def estimate_delay(recording: Recording, *, max_delay: float = MAX_DELAY) -> float:
    """The recording's input-to-motion delay in s, or NaN where the run cannot tell: too short
    (fewer than ten rows per feature), no input varies, or the best delay is the longest tried.

    For each candidate d of 0 to ``max_delay`` s (at most a quarter of the run) in periods, a
    linear ridge regression predicts the input sent d periods before each step from the step's
    states (x_t, x_{t+1}: positions and velocities), on the same rows for every d, scored by its
    unexplained share of the inputs' variance on DELAY_FOLDS contiguous blocks of the run, each
    held out once. The delay is the first local best within DELAY_TOLERANCE of the best score (a
    flat curve is no evidence of a longer delay), in s: a whole number of periods.

    It needs inputs richer than the robot's own lag and tip columns that show the robot's state:
    the ASL trunk's runs give 22-23 periods from its three disks, 21 from the tip alone; the
    smoother's use of later frames makes it a period short for step inputs; a linear map cannot undo
    a partly observed robot's lag under smooth inputs (a point mass with 3 inputs and a 2-D tip
    under sines, with no delay: 0 for 4 of 10 runs, 17-39 periods for the others), so compare
    the estimates of several runs (``load_dataset`` warns where they disagree)."""
    if not (isinstance(max_delay, (int, float)) and math.isfinite(max_delay) and max_delay >= 0):
        raise ValueError(f"max_delay must be a duration >= 0 in s; got {max_delay!r}")
    u, X, dt = recording.inputs, recording.states, recording.dt
    T = len(u)
    longest = min(int(round(max_delay / dt)), T // 4)
    rows = np.arange(longest, T)
    features = np.concatenate([X[rows], X[rows + 1]], 1)  # (N, 4k)
    varying = np.ptp(u, axis=0) > 0
    if longest < 2 or len(rows) < 10 * (features.shape[1] + 1) or not varying.any():
        return math.nan
    targets = np.concatenate([_standard(u[rows - d][:, varying]) for d in range(longest + 1)], 1)  # (N, m' (D+1))
    unexplained = 1 - _held_out_r2(features, targets).reshape(longest + 1, -1).mean(1)  # (D+1,)
    lower = np.concatenate([[True], unexplained[1:] < unexplained[:-1]])  # below the shorter neighbour
    minima = lower & np.concatenate([unexplained[:-1] <= unexplained[1:], [True]])  # and not above the longer
    best = int(np.flatnonzero(minima & (unexplained <= (1 + DELAY_TOLERANCE) * unexplained.min()))[0])
    return math.nan if best == longest else best * dt


def _standard(values: np.ndarray) -> np.ndarray:
    """Columns scaled to zero mean and unit variance (constant ones left at zero)."""
    spread = values.std(0)
    return (values - values.mean(0)) / np.where(spread > 0, spread, 1.0)


def _held_out_r2(features: np.ndarray, targets: np.ndarray, ridge: float = 1e-6) -> np.ndarray:
    """R^2 per target column of a ridge regression (features standardized, an intercept) scored
    on DELAY_FOLDS contiguous blocks, each predicted by the fit on the others: (targets,)."""
    A = np.column_stack([_standard(features), np.ones(len(features))])  # (N, f+1)
    error, total = np.zeros(targets.shape[1]), np.zeros(targets.shape[1])
    for block in np.array_split(np.arange(len(A)), DELAY_FOLDS):
        train = np.ones(len(A), bool)
        train[block] = False
        gram = A[train].T @ A[train] + ridge * train.sum() * np.eye(A.shape[1])
        weights = np.linalg.solve(gram, A[train].T @ targets[train])  # (f+1, targets)
        error += ((targets[block] - A[block] @ weights) ** 2).sum(0)
        total += ((targets[block] - targets[train].mean(0)) ** 2).sum(0)
    return 1 - error / np.where(total > 0, total, 1.0)


def _with_delay(recording: Recording, delay) -> Recording:
    """The recording with its delay: ``delay`` s, or estimated (None)."""
    seconds = estimate_delay(recording) if delay is None else float(delay)
    steps = int(round(seconds / recording.dt)) if math.isfinite(seconds) else 0
    return replace(recording, delay=seconds, delay_steps=steps)


def _check_options(dt, max_gap, noise, jerk, delay=None, max_acceleration=JUMP_ACCELERATION) -> None:
    if dt is not None and not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be None (the commands' period) or a positive period in s; got {dt!r}")
    if not (isinstance(max_gap, (int, float)) and math.isfinite(max_gap) and max_gap > 0):
        raise ValueError(f"max_gap must be a positive duration in s; got {max_gap!r}")
    if delay is not None and not (
        isinstance(delay, (int, float)) and not isinstance(delay, bool) and math.isfinite(delay) and delay >= 0
    ):
        raise ValueError(f"delay must be None (estimated) or an input-to-motion delay >= 0 in s; got {delay!r}")
    if not (isinstance(max_acceleration, (int, float)) and math.isfinite(max_acceleration) and max_acceleration > 0):
        raise ValueError(
            f"max_acceleration must be the robot's largest acceleration, a positive m/s^2; got {max_acceleration!r}"
        )
    check_levels(noise, jerk)


def read(
    path,
    *,
    inputs=None,
    tip=None,
    dt=None,
    max_gap: float = MAX_GAP,
    noise=None,
    jerk=None,
    dropouts: bool = True,
    delay: float | None = None,
    causal: bool = False,
    max_acceleration: float = JUMP_ACCELERATION,
) -> Recording:
    """One recorded run (a CSV, gzip-compressed CSV or Parquet file) on a regular grid of period
    ``dt`` (s; default: the commands' period). ``inputs`` and ``tip`` name the columns (default:
    those starting with ``u``; those of x_m, y_m, z_m present). ``noise`` (m) and ``jerk``
    (m/s^3/sqrt(Hz)) fix the smoother's levels; by default each tip column's are fitted. The
    smoother bridges a run of lost frames up to ``max_gap`` s long, or up to BRIDGED_FRAMES lost
    frames of a camera slower than that. Held and jumped frames are lost frames (``lost_frames``;
    ``dropouts=False`` keeps every frame, e.g. for noise-free simulated data, whose still tip
    repeats exactly); a jump is judged against ``max_acceleration`` (m/s^2), the robot's largest
    acceleration. ``delay`` (s) is the
    input-to-motion delay the recording carries (None: ``estimate_delay``); its arrays are never
    shifted, ``pairs()`` pairs them. ``causal``: the states are the smoother's filter run forward
    (each from the frames up to it: what a control loop knows then) instead of the smoother's. A
    bad file is a ValueError naming it, and the row and column where there is one."""
    _check_options(dt, max_gap, noise, jerk, delay, max_acceleration)
    path = Path(path)
    table = _table(str(path), _content(path, "the recording"), inputs, tip, dropouts, max_acceleration)
    period = table.command_period if dt is None else dt
    return _with_delay(_resample(table, period, max_gap, noise, jerk, causal), delay)


def read_path(path, *, tip, dt: float, noise: float = 1e-6, jerk: float | None = None) -> np.ndarray:
    """A desired path for a model of recorded runs: a CSV or Parquet file of ``time_s`` and the
    observed columns ``tip`` (in m, as in the recordings), as the states the model reads, (T+1, 2k):
    the positions and their velocities on a grid of period ``dt`` (the recordings') from the first
    time to the last, by the recordings' smoother (``noise``: the path's own, 1 um, so the smoother
    follows it; ``jerk`` fitted). So a user gives positions only; velocities are made as for training."""
    _check_options(dt, MAX_GAP, noise, jerk)
    if dt is None:
        raise ValueError("dt must be the recordings' period in s; got None")
    path = Path(path)
    content = _content(path, "the path")
    source = str(path)
    frame = _frame(source, content)
    frame.columns = [str(name) for name in frame.columns]
    if TIME not in frame.columns:
        raise ValueError(f"{source}: no time column {TIME!r} (the columns are {list(frame.columns)})")
    tip_columns = _column_names(tip, (), "tip", source, frame.columns)
    times = _numbers(frame, TIME, source)
    p = np.stack([_numbers(frame, name, source) for name in tip_columns], -1)  # (R, k)
    if not (np.isfinite(times).all() and np.isfinite(p).all()):
        raise ValueError(f"{source}: a desired path needs every time and every {list(tip_columns)} cell set")
    if len(times) < 2 or np.any(np.diff(times) <= 0):
        raise ValueError(f"{source}: column {TIME!r}: need at least two rows at increasing times")
    _check_time_unit(times, source)
    _check_tip_unit(p, tip_columns, source)
    n_steps = math.floor((times[-1] - times[0]) / dt + 1e-9)
    if n_steps < 1:
        raise ValueError(f"{source}: the path lasts {times[-1] - times[0]:g} s, less than one step of {dt:g} s")
    grid = times[0] + dt * np.arange(n_steps + 1)  # (T+1,)
    k = len(tip_columns)
    states = np.empty((n_steps + 1, 2 * k))  # (T+1, 2k)
    for i in range(k):
        states[:, i], states[:, k + i], *_ = smooth(times, p[:, i], grid, noise=noise, jerk=jerk)
    return states


# ---------------------------------------------------------------------------- a folder of runs
def rest_offset(session, reference, *, tip=None) -> np.ndarray:
    """(k,) m to add to every frame of a new session so that its rest pose is the recordings': the
    mean of each tip column over ``reference`` (a rest run of the session the model's recordings
    come from) minus its mean over ``session`` (a rest run of today's: the rig re-assembled, the
    motion capture re-calibrated, the rest pose moved). Both are rest runs: files whose inputs
    never change."""
    means, columns = [], []
    for path in (reference, session):
        table = _table(str(path), _content(path, "the rest run"), None, tip, True)
        if _excited(table):
            raise ValueError(f"{path}: its inputs change; a rest run holds every input constant")
        means.append(np.nanmean(table.tip, 0))
        columns.append(table.tip_columns)
    if columns[0] != columns[1]:
        raise ValueError(f"{session}: tip columns {list(columns[1])} differ from {list(columns[0])} of {reference}")
    return means[0] - means[1]


def _content(path, what: str) -> bytes:
    """The bytes of the file at ``path``, or a ValueError naming it and ``what`` it was to be."""
    try:
        return Path(path).read_bytes()
    except OSError as error:
        raise ValueError(f"{path}: cannot read {what} ({error})") from error


def recording_files(paths_or_folder) -> list[Path]:
    """The recordings a folder holds (its .csv, .csv.gz and .parquet files, by name) or the files listed."""
    if isinstance(paths_or_folder, (str, Path)):
        path = Path(paths_or_folder)
        if path.is_dir():
            files = sorted(p for p in path.iterdir() if _suffix(p) in SUFFIXES and p.is_file())
            if not files:
                raise ValueError(f"{path}: no recording files ({', '.join(SUFFIXES)}) in the folder")
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
    dropouts: bool = True,
    delay: float | None = None,
    causal: bool = False,
    max_acceleration: float = JUMP_ACCELERATION,
    split_at_gaps: bool = False,
    episode_seconds: float | None = None,
    fractions=None,
    seed: int = 0,
    data_dir: Path | None = DATA_DIR,
) -> Dataset:
    """The Dataset of a folder (or list) of recordings, as training uses it (no rod: robot=None).

    Every recording is read as by ``read`` (``dt``: default the median of the files' command
    periods) with the same columns. ``split_at_gaps``: a file with runs of lost frames longer
    than ``max_gap`` is cut there into recordings of its own instead of refused; stretches
    shorter than an episode are left out (default episode: the shortest of the files' longest
    stretches). Each step is paired with the input sent ``delay`` s before
    (in whole periods: ``Dataset.delay_steps``); None: the median of the recordings' estimates
    (``estimate_delay``, kept in ``Dataset.delays``). ``causal``: states as ``read`` makes them
    with it, what the loop of a model trained on them sees (``control.loop``); ``max_acceleration``
    as ``read`` takes it. Then the
    recordings are cut into episodes of
    ``episode_seconds`` (default: the shortest recording; see ``episodes``). The split is by file,
    shuffled by ``seed``: every episode of a run lands in the same split (``Dataset.split_files``
    names them). ``fractions``: the (train, validation) shares of the files (``split_episodes``);
    None: one file in ten validates and one in ten tests, at least one each, so three runs
    already train. A recording whose inputs never change (a rest run: the measurement noise)
    trains nothing: it is left out of every split, with a warning. The result is cached under
    ``data_dir`` (None: not cached) by the files' contents and these options, written atomically
    after every file was read, so a bad file leaves no cache."""
    _check_options(dt, max_gap, noise, jerk, delay, max_acceleration)
    if episode_seconds is not None and not (
        isinstance(episode_seconds, (int, float)) and math.isfinite(episode_seconds) and episode_seconds > 0
    ):
        raise ValueError(f"episode_seconds must be None (the shortest recording) or positive; got {episode_seconds!r}")
    if fractions is not None and not (len(fractions) == 2 and all(0 < f < 1 for f in fractions) and sum(fractions) < 1):
        raise ValueError(
            f"fractions must be None or (train, validation) shares in (0, 1) summing below 1; got {fractions!r}"
        )
    files = recording_files(paths_or_folder)
    contents = [_content(path, "the recording") for path in files]
    spec = dict(
        files=[hashlib.sha256(content).hexdigest() for content in contents],
        inputs=inputs,
        tip=tip,
        dt=dt,
        max_gap=max_gap,
        noise=noise,
        jerk=jerk,
        dropouts=dropouts,
        delay=delay,
        split_at_gaps=split_at_gaps,
        episode_seconds=episode_seconds,
        fractions=None if fractions is None else list(fractions),
        seed=seed,
        version=RECORDINGS_VERSION,
        revision=LOADER_REVISION,
        **({"causal": True} if causal else {}),  # the smoother's states keep the keys they always had
        **({"max_acceleration": max_acceleration} if max_acceleration != JUMP_ACCELERATION else {}),  # and so
    )

    def compute() -> dict:
        shown = dict(unit="file", disable=None, leave=False)  # on a terminal only: minutes for a few long runs
        tables = [
            _table(str(path), content, inputs, tip, dropouts, max_acceleration)
            for path, content in tqdm(list(zip(files, contents)), desc="reading recordings", **shown)
        ]
        for table in tables[1:]:
            for what in ("input_columns", "tip_columns"):
                if getattr(table, what) != getattr(tables[0], what):
                    raise ValueError(
                        f"{table.source}: {what.replace('_', ' ')} {list(getattr(table, what))} differ from "
                        f"{list(getattr(tables[0], what))} of {tables[0].source}; name them with inputs= and tip="
                    )
        resting = [table.source for table in tables if not _excited(table)]
        tables = [table for table in tables if _excited(table)]
        splits = _file_splits(len(tables), fractions, seed)
        for name, chosen in zip(("train", "validation", "test"), splits):
            if len(chosen) == 0:
                raise ValueError(
                    f"{len(tables)} recordings with moving inputs split by {tuple(fractions)} leave the {name} "
                    "split empty; record more runs or pass other fractions (e.g. (1/3, 1/3) for three)"
                )
        period = float(np.median([table.command_period for table in tables])) if dt is None else dt
        owners, runs = range(len(tables)), tables
        if split_at_gaps:
            pieces = [(i, piece) for i, table in enumerate(tables) for piece in _pieces(table, period, max_gap)]
            if not pieces:
                raise ValueError(f"{tables[0].source}: no stretch between long gaps makes a step, in any file")
            owners, runs = zip(*pieces)
        runs = [
            _with_delay(_resample(run, period, max_gap, noise, jerk, causal), delay)
            for run in tqdm(runs, desc="smoothing recordings", **(shown | dict(unit="run")))
        ]
        if delay is None:
            estimates = [run.delay for run in runs if math.isfinite(run.delay)]
            if not estimates:
                raise ValueError(
                    f"{runs[0].source}: too short to estimate an input-to-motion delay, as is every recording; "
                    "pass delay= (s; 0 when the inputs act at once)"
                )
            steps = int(round(float(np.median(estimates)) / period))
        else:
            steps = int(round(delay / period))
        if split_at_gaps:  # stretches no longer than the delay make no pair
            owners, runs = zip(*[(i, run) for i, run in zip(owners, runs) if len(run.inputs) > steps])
        for run in runs:
            if len(run.inputs) <= steps:
                raise ValueError(f"{run.source}: {len(run.inputs)} steps, no more than the delay ({steps} steps)")
        paired = [run.pairs(steps) for run in runs]
        lengths = [len(u) for u, _ in paired]
        if episode_seconds is not None:
            n_steps = int(round(episode_seconds / period))
        elif split_at_gaps:  # each file's longest stretch stays whole; shorter ones are left out
            n_steps = min(max(n for i, n in zip(owners, lengths) if i == file) for file in sorted(set(owners)))
        else:
            n_steps = min(lengths)
        if n_steps < 1:
            raise ValueError(f"episode_seconds = {episode_seconds} is shorter than one step of {period} s")
        short = [run.source for run, length in zip(runs, lengths) if length < n_steps]
        if short and not split_at_gaps:
            raise ValueError(
                f"{short[0]}: shorter than one episode ({episode_seconds} s = {n_steps} steps of {period} s); "
                "pass a shorter episode_seconds"
            )
        long_enough = [i for i, length in enumerate(lengths) if length >= n_steps]  # with split_at_gaps: pieces
        cuts = [(long_enough[i], start) for i, start in episodes([lengths[i] for i in long_enough], n_steps)]
        owner = np.array([owners[i] for i, _ in cuts])
        train, val, test = (np.flatnonzero(np.isin(owner, chosen)) for chosen in splits)
        for name, chosen in zip(("train", "validation", "test"), (train, val, test)):
            if len(chosen) == 0:
                raise ValueError(
                    f"no stretch between long gaps of the {name} split's files is one episode long "
                    f"({n_steps} steps of {period} s); pass a shorter episode_seconds or a longer max_gap"
                )
        return dict(
            u=np.stack([paired[i][0][s : s + n_steps] for i, s in cuts]),  # (E, T, m)
            states=np.stack([paired[i][1][s : s + n_steps + 1] for i, s in cuts]),  # (E, T+1, d)
            train=train,
            val=val,
            test=test,
            dt=np.float64(period),
            delay_steps=np.int64(steps),
            delays=np.array([run.delay for run in runs] if delay is None else [], float),
            input_columns=np.array(tables[0].input_columns),
            tip_columns=np.array(tables[0].tip_columns),
            **{f"{name}_files": _names([tables[i].source for i in chosen]) for name, chosen in zip(SPLITS, splits)},
            resting_files=_names(resting),
            noise=np.median([run.noise for run in runs], 0),  # (k,) the smoother's levels, for the loop's filter
            jerk=np.median([run.jerk for run in runs], 0),
            causal=np.bool_(causal),
        )

    if data_dir is None:
        data = _dataset(compute(), f"recordings-{content_key(spec)}")
    else:
        path = cache_file(data_dir, "recordings", spec)
        arrays = cached_arrays(
            data_dir, "recordings", spec, compute, valid=lambda cached: _dataset(cached, path.stem) is not None
        )
        data = _dataset(arrays, path.stem)
    for source in data.resting_files:
        warnings.warn(
            f"{source}: every input is constant (a rest run: the measurement noise); it trains nothing and is left "
            "out of the splits",
            stacklevel=2,
        )
    estimates = np.array([seconds for seconds in data.delays if math.isfinite(seconds)])
    if len(estimates) > 1 and np.subtract(*np.percentile(estimates, [75, 25])) > DELAY_SPREAD * data.dt:
        warnings.warn(
            f"the recordings' delay estimates disagree ({1e3 * estimates.min():.0f} to {1e3 * estimates.max():.0f} ms, "
            f"quartiles {np.round(1e3 * np.percentile(estimates, [25, 75])).tolist()} ms): the delay is poorly "
            f"identified from these runs and their median ({data.delay_steps} periods) may be wrong; pass delay= "
            "(s) if you know it (Dataset.delays has the estimates)",
            DelayWarning,
            stacklevel=2,
        )
    return data


SPLITS = ("train", "val", "test")
SUSPECT_UNITS = {"_mm": "millimetres", "_cm": "centimetres", "_in": "inches"}  # column suffixes the loader never reads
UNIT_SUFFIXES = (
    "mm",
    "cm",
    "m",
    "N",
    "Nm",
    "deg",
    "rad",
    "V",
    "A",
    "Pa",
    "kPa",
    "bar",
)  # an input column's name_<unit>


def column_unit(name: str) -> str | None:
    """The unit an input column's name declares (``l1_mm``: "mm", ``u1_N``: "N"), or None."""
    *_, suffix = name.rpartition("_")
    return suffix if "_" in name and suffix in UNIT_SUFFIXES else None


def describe(
    paths_or_folder,
    *,
    inputs=None,
    tip=None,
    max_gap: float = MAX_GAP,
    dropouts: bool = True,
    max_acceleration: float = JUMP_ACCELERATION,
    fractions=None,
    seed: int = 0,
    delays: bool = True,
    progress: bool = True,
) -> pd.DataFrame:
    """What the loader finds in each recording before anything trains on it, one row per file:
    rows and seconds, the commands' and the frames' rates (Hz), the frames lost per point
    (``tip_points``: held and one-frame jumps, ``lost_frames``), runs of lost frames longer than
    ``max_gap`` (which ``read`` refuses), the estimated input-to-motion delay (ms; ``delays=False``
    skips it: it smooths the run), columns in units the loader does not read, the split
    ``load_dataset`` puts it in with the same ``fractions`` and ``seed`` (a rest run in none), and
    why a file would be refused. A bad file is a row saying so, not an error: the report covers
    every file."""
    _check_options(None, max_gap, None, None, max_acceleration=max_acceleration)
    files = recording_files(paths_or_folder)
    rows, excited = [], []
    for path in tqdm(files, desc="recordings", unit="file", disable=not progress):
        row = dict(file=path.name)
        try:
            content = path.read_bytes()
            columns = [str(name) for name in _frame(str(path), content).columns]
            row["other_units"] = _other_units(columns, inputs or ())
            table = _table(str(path), content, inputs, tip, dropouts, max_acceleration)
            row["other_units"] = _other_units(columns, table.input_columns)
        except (OSError, ValueError) as error:
            rows.append(row | dict(split="refused", problem=str(error)))
            continue
        points = tip_points(table.tip_columns)
        point_of = {i: _point_name(table.tip_columns, point) for point in points for i in point}
        gaps = list(  # per point, not per column: a point's columns are lost together
            dict.fromkeys(
                f"{point_of[i]}: {table.times[before]:.2f}-{table.times[after]:.2f} s"
                for i, before, after in _long_gaps(table, max_gap)
            )
        )
        row |= dict(
            rows=len(table.times),
            seconds=float(table.times[-1] - table.times[0]),
            command_hz=1 / table.command_period,
            frame_hz=1 / float(table.frame_period[0]),  # the camera's, its lost frames included
            points=", ".join(dict.fromkeys(point_of.values())),
            held=", ".join(str(int(table.frozen[point[0]])) for point in points),
            jumps=", ".join(str(int(table.jumps[point[0]])) for point in points),
            long_gaps="; ".join(gaps),
        )
        if gaps:
            row["problem"] = "lost frames for longer than the smoother bridges: read refuses it (split it at gaps)"
        elif delays:
            run = _resample(table, table.command_period, max_gap, None, None)
            row["delay_ms"] = 1e3 * estimate_delay(run)
        if _excited(table):
            excited.append(len(rows))
        else:
            row["split"] = "none (rest run)"
        rows.append(row)
    try:
        splits = _file_splits(len(excited), fractions, seed)
    except ValueError as error:
        for i in excited:
            rows[i]["split"] = f"none ({error})"
    else:
        for name, chosen in zip(SPLITS, splits):
            for i in chosen:
                rows[excited[i]]["split"] = name
    order = ["file", "rows", "seconds", "command_hz", "frame_hz", "points", "held", "jumps", "long_gaps", "delay_ms"]
    table = pd.DataFrame(rows)
    return table.reindex(columns=[*order, "other_units", "split", "problem"])


def _other_units(columns, input_columns) -> str:
    """Columns other than the inputs (which may be in any units) whose names say a unit the
    loader does not read positions in: a tip in millimetres beside the metre columns, say."""
    return ", ".join(
        f"{name} ({unit}?)"
        for name in columns
        if name not in input_columns
        for suffix, unit in SUSPECT_UNITS.items()
        if name.endswith(suffix)
    )


def _point_name(tip_columns, point: list[int]) -> str:
    """A point's name in reports: its columns' shared part (``3`` of x3_m, y3_m, z3_m; ``tip`` of
    x_m, y_m, z_m), or its column."""
    axis = re.fullmatch(r"[xyz](.*)_m", tip_columns[point[0]])
    return (axis.group(1) or "tip") if axis else tip_columns[point[0]]


def _excited(table: _Table) -> bool:
    """Whether any input takes more than one value: a run that moves the rig, not a rest run."""
    sent = table.inputs[~np.isnan(table.inputs).any(-1)]
    return bool(len(sent)) and bool((sent != sent[0]).any())


def _file_splits(n: int, fractions, seed: int):
    """File indices of the train, validation and test splits, shuffled by ``seed``: by
    ``fractions`` (``split_episodes``), or for None one file in ten validating and one in ten
    testing, at least one each."""
    if fractions is not None:
        return split_episodes(n, seed, fractions)
    order, held = np.random.default_rng(seed).permutation(n), max(1, round(0.1 * n))
    if n < 3:
        raise ValueError(
            f"{n} recordings with moving inputs cannot be split into training, validation and test runs; "
            "record at least three"
        )
    return np.sort(order[: n - 2 * held]), np.sort(order[n - 2 * held : n - held]), np.sort(order[n - held :])


def _names(sources: list[str]) -> np.ndarray:
    """File names as a string array (an empty list too), as the cache keeps them."""
    return np.array([Path(source).name for source in sources], dtype=str)


class DelayWarning(UserWarning):
    """The recordings' input-to-motion delay estimates disagree (see ``load_dataset``)."""


def _dataset(arrays: dict, key: str) -> Dataset | None:
    """The Dataset of the arrays (cached or just made), or None when they do not make one."""
    try:
        data = Dataset(
            **{k: arrays[k] for k in ("u", "states", "train", "val", "test")},
            key=key,
            robot=None,
            gravity=None,
            dt=float(arrays["dt"]),
            delay_steps=int(arrays["delay_steps"]),
            delays=tuple(float(seconds) for seconds in arrays["delays"]),
            input_columns=tuple(str(name) for name in arrays["input_columns"]),
            tip_columns=tuple(str(name) for name in arrays["tip_columns"]),
            split_files={name: tuple(str(f) for f in arrays[f"{name}_files"]) for name in SPLITS},
            resting_files=tuple(str(f) for f in arrays["resting_files"]),
            levels=(np.asarray(arrays["noise"], float), np.asarray(arrays["jerk"], float)),
            causal=bool(arrays["causal"]),
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
