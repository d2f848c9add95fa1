"""Reference trajectories: structured y-z shapes lifted to 6D, and actuation-driven families.

A structured path is drawn in the tip's y-z plane, timed at a constant nominal speed
with smooth ramps, and lifted to a full state: p_x from the rod's static workspace at
(y, z), velocities by the chain rule through the static map (exact, not differenced).
Every reference starts at rest with an approach segment to the path's start point,
which its ``mask`` excludes from the metrics (the paper's Initial-to-Start transient).
Random and complex-3D references are made by running held-out actuation families
through the simulator, so their true u is known.

A rod with more inputs than tip coordinates (``TWO_SEGMENT_ROD``: four) holds a tip point
with a curve of u, so its y-z lift takes the least-norm equilibrium (``least_norm_lift``),
and it can follow paths whose depth leaves that lift (``depth_circle_reference``), which a
rod of one segment cannot. Its references can also carry the path of its middle disk
(``observation="tip+disk"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline

from softflow.checks import check_choice
from softflow.data.dataset import disk_rollout, observe_disks
from softflow.data.excitation import mixed_excitation, sum_of_sines_excitation
from softflow.rod import statics
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, U_MAX
from softflow.store import DATA_DIR, cached_arrays

REFERENCE_VERSION = 1  # bump when a reference changes (it keys the reference caches)
NOMINAL_SPEED = 0.15  # m/s, mean tip speed along a structured path
APPROACH_SECONDS = 1.5  # s, rest pose -> path start
RAMP_SECONDS = 0.5  # s, speed ramps at the start and the end of a path
SIZE = 0.12  # m, half-extent of a structured shape in y-z
HARDWARE_SHAPES = ("star", "spiral", "circle", "heart")  # Table III
HARDWARE_SIZE = 0.05  # m: the stiffer hardware rod reaches about 0.08 m from its rest tip at 4 N
HARDWARE_BURST_RADIUS = 0.05  # m
# 3-D paths of a redundant rod: a y-z circle about the rest tip whose depth falls below the
# least-norm lift's twice per revolution (docs/assumptions.md, two_segment)
DEPTH_RADIUS = 0.05  # m
DEPTH_SWING = 0.006  # m: the largest fall below the least-norm depth
PATH3D_STARTS = (0, 120, 240)  # degrees: where on its circle each path starts (and its depth wave with it)
REACH_TOLERANCE = 1e-6  # m: every sample of a 3-D path is an equilibrium tip to within this
_STATIC_CHUNK = 128  # points fitted together (each Newton step perturbs every coordinate of each)


@dataclass(frozen=True)
class Reference:
    """A reference trajectory at DT: states (T+1, d) (6 for the tip, 12 for the tip and the middle
    disk), metric mask (T+1,), true u (T, m) or None."""

    name: str
    family: str  # "shape", "random", "burst" or "complex3d"
    states: np.ndarray
    mask: np.ndarray
    u_true: np.ndarray | None = None

    @property
    def n_steps(self) -> int:
        return len(self.states) - 1


# ---------------------------------------------------------------------------- y-z paths
def _unit(points):
    """Scale a (K, 2) point set to half-extent 1 about its box centre."""
    points = np.asarray(points, float)
    centre = (points.max(0) + points.min(0)) / 2
    return (points - centre) / np.abs(points - centre).max()


def _polar(radius, turns=1.0, k=2000):
    angle = np.linspace(0, 2 * np.pi * turns, k)
    r = radius(angle)
    return np.stack([r * np.cos(angle), r * np.sin(angle)], -1)


def _heart(k=2000, rounding=0.03):
    """The classic parametric heart with its two cusps rounded: resampled by arc length and
    smoothed by a circular Gaussian of ``rounding`` x the perimeter, so the tip never stops."""
    t = np.linspace(0, 2 * np.pi, 20 * k)
    points = np.stack([16 * np.sin(t) ** 3, 13 * np.cos(t) - 5 * np.cos(2 * t) - 2 * np.cos(3 * t) - np.cos(4 * t)], -1)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    uniform = np.linspace(0, s[-1], k, endpoint=False)
    points = np.stack([np.interp(uniform, s, points[:, i]) for i in range(2)], -1)
    offsets = np.fft.fftfreq(k) * k  # circular distance in samples
    kernel = np.exp(-0.5 * (offsets / (rounding * k)) ** 2)
    smoothed = np.fft.ifft(np.fft.fft(points, axis=0) * np.fft.fft(kernel / kernel.sum())[:, None], axis=0).real
    return np.concatenate([smoothed, smoothed[:1]])


# Characters as stroke control points (y right, z up); a cubic spline through them is the path.
_CHARACTERS = {
    "S": [(1, 0.8), (0.3, 1), (-0.7, 0.8), (-0.8, 0.2), (0, 0), (0.8, -0.2), (0.7, -0.8), (-0.3, -1), (-1, -0.8)],
    "C": [(0.9, 0.6), (0.3, 1), (-0.5, 0.8), (-1, 0), (-0.5, -0.8), (0.3, -1), (0.9, -0.6)],
    "M": [(-1, -1), (-0.9, 0.2), (-0.75, 1), (-0.4, 0.3), (0, -0.3), (0.4, 0.3), (0.75, 1), (0.9, 0.2), (1, -1)],
    "W": [(-1, 1), (-0.8, -0.2), (-0.6, -1), (-0.3, -0.3), (0, 0.4), (0.3, -0.3), (0.6, -1), (0.8, -0.2), (1, 1)],
}

SHAPES = {
    "circle": lambda: _polar(lambda a: np.ones_like(a)),
    "heart": _heart,
    "star": lambda: _polar(lambda a: 1 + 0.35 * np.cos(5 * a)),  # a rounded five-pointed star
    "spiral": lambda: _polar(lambda a: 0.25 + 0.75 * a / a[-1], turns=2.5),
    **{f"char_{c}": (lambda pts=pts: np.asarray(pts, float)) for c, pts in _CHARACTERS.items()},
}


def shape_points(name: str) -> np.ndarray:
    """The named shape as dense (K, 2) y-z points with half-extent 1."""
    check_choice(name, "shape", SHAPES)
    return _unit(SHAPES[name]())


def _path_spline(points):
    """Cubic spline through the points, parametrised by arc length (m): (spline, length)."""
    keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-12])
    points = points[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    closed = np.allclose(points[0], points[-1])
    spline = make_interp_spline(s, points, k=3, bc_type="periodic" if closed else "not-a-knot")
    return spline, s[-1]


def _ramped_progress(t, duration, ramp):
    """Arc-length fraction along a path and its rate: constant speed with smoothstep ramps
    of ``ramp`` s at both ends (C1 speed, so C2 positions)."""
    ramp = min(ramp, duration / 2)
    cruise = 1.0 / (duration - ramp)  # speed (fraction/s) so that the total is 1

    def ramp_up(x):  # integral of the smoothstep 3x^2 - 2x^3 on [0, x], times ramp
        return ramp * (x**3 - x**4 / 2)

    x_in = np.clip(t / ramp, 0, 1)
    x_out = np.clip((duration - t) / ramp, 0, 1)
    middle = np.clip(t, ramp, duration - ramp) - ramp
    progress = cruise * (ramp_up(x_in) + middle + (ramp / 2 - ramp_up(x_out)))  # last term is 0 before the end ramp
    speed = cruise * np.minimum(3 * x_in**2 - 2 * x_in**3, 3 * x_out**2 - 2 * x_out**3)
    return progress, speed


def _minimum_jerk(t, duration):
    """Fraction and its rate of a rest-to-rest minimum-jerk move."""
    x = np.clip(t / duration, 0, 1)
    return 10 * x**3 - 15 * x**4 + 6 * x**5, (30 * x**2 - 60 * x**3 + 30 * x**4) / duration


@dataclass(frozen=True)
class StaticPath:
    """Least-norm equilibria at a path's points: actuation u (K, m), the position (K, S, 3) of every
    disk (base outwards, the tip last), and its rate along the fitted target coordinates,
    d position / d target (K, S, 3, r)."""

    u: np.ndarray
    positions: np.ndarray
    rates: np.ndarray

    def velocities(self, target_rate) -> np.ndarray:
        """Disk velocities (K, S, 3) of a path whose target moves at ``target_rate`` (K, r)."""
        return np.einsum("ksir,kr->ksi", self.rates, target_rate)


def least_norm_statics(sim: Simulator, target, rows, start) -> StaticPath:
    """The least-norm u whose equilibrium tip has ``target`` (K, 3) in coordinates ``rows``
    (``statics.fit_static`` from ``start`` (K, m)), its disks and their rates along the target.
    ValueError where no equilibrium reaches a point."""
    parts = []
    for begin in range(0, len(target), _STATIC_CHUNK):
        chunk = slice(begin, begin + _STATIC_CHUNK)
        try:
            u, _, _ = statics.fit_static(sim, target[chunk], rows, start[chunk], u_limit=sim.u_bound)
        except (RuntimeError, np.linalg.LinAlgError) as error:
            raise ValueError(
                f"the path leaves the static workspace of {sim.robot.name!r} near samples {begin}.."
                f"{min(begin + _STATIC_CHUNK, len(target)) - 1} (no equilibrium found)"
            ) from error
        parts.append((u, *statics.least_norm_rates(sim, u, rows)))
    return StaticPath(*(np.concatenate(part) for part in zip(*parts)))


def least_norm_lift(sim: Simulator, yz, u_max: float = U_MAX) -> StaticPath:
    """The least-norm equilibrium whose tip has lateral position yz (K, 2), over every input: the
    y-z lift of a rod with more inputs than two, whose depth x is where the gentlest actuation puts
    the tip (``Simulator.static_lift`` for two inputs). Rates are d position / d(y, z).
    ValueError where it needs |u_i| > u_max."""
    yz = np.asarray(yz, float)
    arc_towards = np.column_stack([np.full(len(yz), sim.robot.length), yz])  # the tip cables' arc, to start from
    path = least_norm_statics(
        sim, np.column_stack([np.zeros(len(yz)), yz]), [1, 2], statics.arc_actuation(sim.robot, arc_towards)
    )
    worst = np.abs(path.u).max()
    if worst > u_max:
        raise ValueError(f"y-z path leaves the reachable static workspace: needs |u| = {worst:.2f} N > {u_max} N")
    return path


def _lift(sim: Simulator, yz, yz_rate, observation: str = "tip"):
    """Full states of a y-z path: p from the static workspace (for a rod with more than two inputs
    the least-norm equilibrium), v = dp/d(yz) yz_rate; the tip's 6, or with ``observation``
    "tip+disk" the tip's and the middle disk's 12."""
    if sim.n_inputs == 2 and observation == "tip":
        p, _, dp_dyz = sim.static_lift(yz)
        return np.concatenate([p, np.einsum("tij,tj->ti", dp_dyz, yz_rate)], -1)
    path = least_norm_lift(sim, yz)
    return observe_disks(path.positions, path.velocities(yz_rate), observation)


def _check_reach(sim: Simulator, yz):
    """Refuse a y-z path (K, 2) that no tip can follow: one farther from the rod's axis than the
    rod is long (a size in millimetres, say). The message gives the rod's static reach, which
    costs a few static solves, so it is computed only then."""
    farthest = np.linalg.norm(yz, axis=-1).max()
    if farthest < sim.robot.length:
        return
    rest = sim.tip_positions(sim.rest_q()[None])[0, 1:]
    grid = np.linspace(-U_MAX, U_MAX, 9)
    u = np.stack(np.meshgrid(grid, grid, indexing="ij"), -1).reshape(-1, 2)  # every input pair of the range
    reach = np.linalg.norm(sim.static_tip(np.tile(u, sim.n_inputs // 2))[:, 1:] - rest, axis=1).max()
    raise ValueError(
        f"the path reaches {farthest:.4g} m from the rod's axis, farther than the rod is long "
        f"({sim.robot.length:g} m): size, radius and centre are in metres. At |u| <= {U_MAX:g} N this "
        f"rod's tip reaches at most {reach:.3f} m from its rest position (y, z) = ({rest[0]:.3f}, "
        f"{rest[1]:.3f}) m"
    )


def _approach(sim: Simulator, yz_path, yz_rate_path):
    """The y-z path (K, 2) and its rate with a minimum-jerk move from the rest tip to its start
    prepended, and the mask of the path's own samples."""
    rest = sim.tip_positions(sim.rest_q()[None])[0, 1:]
    n_approach = int(round(APPROACH_SECONDS / DT))
    fraction, rate = _minimum_jerk(np.arange(n_approach) * DT, APPROACH_SECONDS)
    yz = np.concatenate([rest + fraction[:, None] * (yz_path[0] - rest), yz_path])
    yz_rate = np.concatenate([rate[:, None] * (yz_path[0] - rest), yz_rate_path])
    return yz, yz_rate, np.arange(len(yz)) >= n_approach


def _with_approach(sim: Simulator, yz_path, yz_rate_path, observation: str = "tip"):
    """Prepend a minimum-jerk move from the rest tip to the path start; mask the path only."""
    yz, yz_rate, mask = _approach(sim, yz_path, yz_rate_path)
    return _lift(sim, yz, yz_rate, observation), mask


def shape_reference(
    sim: Simulator,
    name: str,
    size: float = SIZE,
    centre=(0.0, 0.0),
    speed: float = NOMINAL_SPEED,
    observation: str = "tip",
) -> Reference:
    """A structured shape of half-extent ``size`` (m) about ``centre`` (y, z in m) traversed once at
    mean speed ``speed`` (m/s); ``observation`` "tip+disk" adds the middle disk of a two-segment rod."""
    if not (size > 0 and speed > 0):
        raise ValueError(f"size and speed must be positive; got {size!r}, {speed!r}")
    points = shape_points(name) * size + np.asarray(centre, float)
    _check_reach(sim, points)
    spline, length = _path_spline(points)
    duration = length / speed
    t = np.arange(int(round(duration / DT)) + 1) * DT
    progress, rate = _ramped_progress(t, t[-1], RAMP_SECONDS)
    s = progress * length
    states, mask = _with_approach(sim, spline(s), spline(s, 1) * (rate * length)[:, None], observation)
    return Reference(name, "shape", states, mask)


def depth_circle_reference(
    sim: Simulator,
    start: float = 0.0,
    radius: float = DEPTH_RADIUS,
    swing: float = DEPTH_SWING,
    speed: float = NOMINAL_SPEED,
    observation: str = "tip",
) -> Reference:
    """A 3-D path for a rod with more inputs than tip coordinates: a y-z circle of ``radius`` (m)
    about the rest tip, from the angle ``start`` (degrees, from +y towards +z) once round at the
    shapes' speed and ramps, whose depth x falls below the least-norm lift's by
    swing (1 - cos 2(a - start)) / 2 (m): twice per revolution, back on the lift at the start and
    half-way. The approach from rest is lifted as the shapes'. Each sample is the least-norm
    equilibrium at its 3-D point, reached to REACH_TOLERANCE with |u_i| <= U_MAX, else ValueError;
    a rod of one segment reaches none but the lift's depth."""
    if not (radius > 0 and swing >= 0 and speed > 0):
        raise ValueError(f"radius and speed must be > 0 and swing >= 0; got {radius!r}, {swing!r}, {speed!r}")
    rest = sim.tip_positions(sim.rest_q()[None])[0, 1:]
    t = np.arange(int(round(2 * np.pi * radius / speed / DT)) + 1) * DT
    progress, rate = _ramped_progress(t, t[-1], RAMP_SECONDS)
    turned, turn_rate = 2 * np.pi * progress, 2 * np.pi * rate  # angle from the start (rad) and its rate
    angle = np.deg2rad(start) + turned
    circle = rest + radius * np.stack([np.cos(angle), np.sin(angle)], -1)
    _check_reach(sim, circle)
    yz, yz_rate, mask = _approach(
        sim, circle, radius * turn_rate[:, None] * np.stack([-np.sin(angle), np.cos(angle)], -1)
    )
    lift = least_norm_lift(sim, yz)
    depth = np.concatenate([np.zeros(np.sum(~mask)), -swing * (1 - np.cos(2 * turned)) / 2])
    depth_rate = np.concatenate([np.zeros(np.sum(~mask)), -swing * np.sin(2 * turned) * turn_rate])
    tip = lift.positions[:, -1]
    target = np.column_stack([tip[:, 0] + depth, yz])
    target_rate = np.column_stack([np.einsum("kr,kr->k", lift.rates[:, -1, 0], yz_rate) + depth_rate, yz_rate])
    path = least_norm_statics(sim, target[mask], [0, 1, 2], lift.u[mask])
    miss = np.linalg.norm(path.positions[:, -1] - target[mask], axis=-1).max()
    worst = np.abs(path.u).max()
    if not (miss <= REACH_TOLERANCE and worst <= U_MAX):
        raise ValueError(
            f"the 3-D path leaves the static workspace of {sim.robot.name!r}: its nearest equilibria miss by "
            f"{1e3 * miss:.3g} mm and need |u| up to {worst:.2f} N (at most {1e3 * REACH_TOLERANCE:g} mm and {U_MAX} N)"
        )
    positions, velocities = lift.positions.copy(), lift.velocities(yz_rate)
    positions[mask], velocities[mask] = path.positions, path.velocities(target_rate[mask])
    return Reference(f"path3d-{start:g}", "path3d", observe_disks(positions, velocities, observation), mask)


def burst_circle_reference(
    sim: Simulator,
    radius: float = 0.15,
    periods=(5.0, 1.2),
    duration: float = 12.0,
    centre=(0.0, 0.0),
    name: str = "burst_circle",
) -> Reference:
    """A circle whose period falls linearly from periods[0] to periods[1] s over ``duration``."""
    if not (radius > 0 and duration > 0 and min(periods) > 0):
        raise ValueError(f"radius, duration and periods must be positive; got {radius!r}, {duration!r}, {periods!r}")
    t = np.arange(int(round(duration / DT)) + 1) * DT
    period = periods[0] + (periods[1] - periods[0]) * t / duration
    slope = (periods[1] - periods[0]) / duration
    angle = 2 * np.pi * np.log(period / periods[0]) / slope  # integral of 2 pi / P(t)
    angle_rate = 2 * np.pi / period
    yz = np.asarray(centre) + radius * np.stack([np.cos(angle), np.sin(angle)], -1)
    _check_reach(sim, yz)
    rate = radius * angle_rate[:, None] * np.stack([-np.sin(angle), np.cos(angle)], -1)
    states, mask = _with_approach(sim, yz, rate)
    return Reference(name, "burst", states, mask)


def actuated_references(sim: Simulator, u, names, family: str, observation: str = "tip"):
    """References made by running actuation (B, T, m) through the simulator; the true u is kept.
    ``observation`` "tip+disk": the middle disk of a two-segment rod too."""
    states = sim.rollout(u) if observation == "tip" else observe_disks(*disk_rollout(sim, u), observation)
    return [Reference(name, family, X, np.ones(len(X), bool), np.asarray(uu)) for name, X, uu in zip(names, states, u)]


def random_references(
    sim: Simulator, n: int = 4, seconds: float = 5.0, seed: int = 1000, u_max: float = 3.0, observation: str = "tip"
):
    """Rand1..Randn: held-out sum-of-sines actuation below 1 Hz on each of the rod's inputs (not the
    polynomial training family)."""
    u = sum_of_sines_excitation(
        n, int(round(seconds / DT)), seed, u_max=u_max, frequencies=(0.1, 1.0), n_inputs=sim.n_inputs
    )
    return actuated_references(sim, u, [f"Rand{k + 1}" for k in range(n)], "random", observation)


def complex3d_references(sim: Simulator, n: int = 3, seconds: float = 8.0, seed: int = 2000):
    """Forward-then-inverse test: sine + sigmoid + ramp actuation, run through the simulator."""
    u = mixed_excitation(n, int(round(seconds / DT)), seed)
    return actuated_references(sim, u, [f"Complex{seed}-{k + 1}" for k in range(n)], "complex3d")


STRUCTURED = ("circle", "heart", "star", "spiral", "char_S", "char_C", "char_M", "char_W")


def _pack(references) -> dict:
    arrays = {"names": np.array([r.name for r in references]), "families": np.array([r.family for r in references])}
    for i, r in enumerate(references):
        arrays[f"states_{i}"], arrays[f"mask_{i}"] = r.states, r.mask
        if r.u_true is not None:
            arrays[f"u_{i}"] = r.u_true
    return arrays


def _unpack(arrays: dict) -> list[Reference]:
    return [
        Reference(str(name), str(family), arrays[f"states_{i}"], arrays[f"mask_{i}"], arrays.get(f"u_{i}"))
        for i, (name, family) in enumerate(zip(arrays["names"], arrays["families"]))
    ]


def references_spec(sim: Simulator, kind: str, build: str) -> dict:
    """What a cached reference set is keyed by: the simulator's numbers, the set's kind, the name
    of the function that builds it and REFERENCE_VERSION."""
    return dict(simulator=sim.spec(), kind=kind, build=build, version=REFERENCE_VERSION)


def cached_references(sim: Simulator, kind: str, build) -> list[Reference]:
    """build(sim) -> references, cached under data/ by ``references_spec``."""
    arrays = cached_arrays(
        DATA_DIR,
        f"references-{kind}",
        references_spec(sim, kind, build.__name__),
        lambda: _pack(build(sim)),
        valid=lambda arrays: "names" in arrays,
    )
    return _unpack(arrays)


def _evaluation_set(sim: Simulator) -> list[Reference]:
    return [shape_reference(sim, name) for name in STRUCTURED] + random_references(sim)


def _burst_set(sim: Simulator) -> list[Reference]:
    paper = burst_circle_reference(sim)
    # the same falling-period law continued until tracking must break: 5.0 -> 0.2 s at the paper's slope
    beyond = burst_circle_reference(sim, periods=(5.0, 0.2), duration=12.0 * 4.8 / 3.8, name="burst_to_0.2s")
    return [paper, beyond]


def burst_references(sim: Simulator) -> list[Reference]:
    """The paper's burst circle (period 5.0 -> 1.2 s over 12 s) and its continuation to 0.2 s, cached."""
    return cached_references(sim, "burst", _burst_set)


def _hardware_set(sim: Simulator) -> list[Reference]:
    centre = sim.tip_positions(sim.rest_q()[None])[0, 1:]  # shapes drawn about the rest tip
    shapes = [shape_reference(sim, name, size=HARDWARE_SIZE, centre=centre) for name in HARDWARE_SHAPES]
    return shapes + [burst_circle_reference(sim, radius=HARDWARE_BURST_RADIUS, centre=centre)]


def hardware_burst_reference(sim: Simulator, periods=(5.0, 0.2), duration: float = 12.0 * 4.8 / 3.8) -> Reference:
    """Table III's burst circle continued at the paper's slope until tracking must break (period
    5.0 -> 0.2 s), about the hardware rod's rest tip: where the twin's loops break."""
    centre = sim.tip_positions(sim.rest_q()[None])[0, 1:]
    return burst_circle_reference(
        sim,
        radius=HARDWARE_BURST_RADIUS,
        periods=periods,
        duration=duration,
        centre=centre,
        name=f"burst_to_{periods[1]:g}s",
    )


def hardware_references(sim: Simulator) -> list[Reference]:
    """Table III's shapes and the burst circle, sized for the hardware rod and centred on its
    rest tip (which sags in the horizontal configuration), cached."""
    return cached_references(sim, "hardware", _hardware_set)


def evaluation_references(sim: Simulator) -> list[Reference]:
    """The Table I/II evaluation set, cached: the structured shapes and Rand1..Rand4."""
    return cached_references(sim, "evaluation", _evaluation_set)
