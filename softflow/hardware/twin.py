"""Hardware replay (Sec. V): planned actuation becomes per-cable motor commands, replayed on a
twin plant across a stated reality gap and watched by a camera.

The model is driven by differential tensions u, the robot by motors that hold cable
positions, so commands are made *through the model*: the tension-driven twin's rod shape
gives each cable's path-length change Delta_c(q) (``cables.cable_displacements``), and a
cable of stiffness k carries k (l_c + Delta_c(q)) when its motor has pulled in l_c. To
produce the planned tensions T_c(u) (u split over the three cables above a pretension,
``cables.cable_tensions``) the motor pulls in l_c = T_c / k - Delta_c(q), with Delta_c
averaged over the control step.

The plant is the same rod with every term of ``RealityGap``: its E, eta, rho are off,
motors follow their commands with a first-order lag, each cable has its own slack
(tension k max(0, stretch - slack)), the cables rub in the spacer disks (capstan friction
with a Dahl state, ``capstan_tensions``), and the camera adds its noise. Cable tension is
re-evaluated every quarter step, as the physical cable would.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.optimize import brentq

from softflow.checks import as_real_array
from softflow.hardware import vision
from softflow.rod.cables import cable_actuation, cable_displacements, cable_tensions
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, HW_ROBOT, U_MAX, Robot

CABLE_STIFFNESS = 1000.0  # N/m, line + guides + motor mount in series (assumed; docs/assumptions.md)
PRETENSION = 1.0  # N, the slackest cable's tension: keeps every cable taut
CAMERA_DISTANCE = 0.4  # m, camera beyond the rest tip, looking back along the rod
SLIDING_LENGTH = 5e-4  # m, the Dahl sliding length of a cable in its holes (assumed; docs/assumptions.md)
ADDED_TERMS = ("cable_friction", "sliding_length")  # out of a gap's key while at their defaults
LOOP_PERIOD = 20.0  # s, the slower of hysteresis_loop's two cycles (10 s rings the rod: docs/assumptions.md)


@dataclass(frozen=True)
class RealityGap:
    """Everything that separates the plant from the model used to plan, in one seeded place."""

    youngs_modulus: float = 0.0  # relative error of the plant's E
    damping: float = 0.0  # relative error of its eta
    density: float = 0.0  # relative error of its rho
    motor_lag: float = 0.0  # s, time constant of each motor's position loop
    slack: float = 0.0  # m, each cable's slack is drawn uniformly from [0, slack]
    depth_noise: float = 0.0  # m at 1 m, the camera's depth noise (grows with Z^2)
    pixel_noise: float = 0.0  # colour noise of the camera, 0-255
    seed: int = 0
    cable_friction: float = 0.0  # mu, Coulomb coefficient of a cable in the spacer disks' holes
    sliding_length: float = SLIDING_LENGTH  # m of sliding over which friction builds up (Dahl: F_c / sigma_0)

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not np.isfinite(value):
                raise ValueError(f"{name} must be finite; got {value!r}")
        for name in ("motor_lag", "slack", "depth_noise", "pixel_noise"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0; got {getattr(self, name)!r}")
        if min(self.youngs_modulus, self.damping, self.density) <= -1:
            raise ValueError("relative parameter errors must be > -1 (a positive parameter stays positive)")
        if self.cable_friction < 0:
            raise ValueError(
                "cable_friction must be a friction coefficient >= 0 (0: frictionless cables); "
                f"got {self.cable_friction!r}"
            )
        if not self.sliding_length > 0:
            raise ValueError(f"sliding_length must be a length > 0 m (Dahl's); got {self.sliding_length!r}")

    def parameters(self) -> dict:
        """The terms that key caches: a term added later counts only when it differs from its
        default, so every gap that existed keeps its key (use this, not ``asdict``, in a key)."""
        defaults = {name: RealityGap.__dataclass_fields__[name].default for name in ADDED_TERMS}
        return {k: v for k, v in asdict(self).items() if not (k in defaults and v == defaults[k])}

    def plant_robot(self, robot: Robot) -> Robot:
        return replace(
            robot,
            youngs_modulus=robot.youngs_modulus * (1 + self.youngs_modulus),
            damping=robot.damping * (1 + self.damping),
            density=robot.density * (1 + self.density),
        )

    def doubled(self, term: str) -> RealityGap:
        """This gap with one term twice as large: the sensitivity study."""
        if term not in GAP_TERMS:
            raise ValueError(f"term must be one of {GAP_TERMS}; got {term!r}")
        return replace(self, **{term: 2 * getattr(self, term)})


GAP_TERMS = ("youngs_modulus", "damping", "density", "motor_lag", "slack", "depth_noise", "pixel_noise")
NO_GAP = RealityGap()
# A bench-top rod: E, eta, rho within 10-20 % of their nominal values, a hobby servo's lag,
# a few tenths of a millimetre of slack, D435-like depth and colour noise.
TYPICAL_GAP = RealityGap(
    youngs_modulus=-0.15, damping=0.20, density=0.10, motor_lag=0.02, slack=3e-4, depth_noise=1e-3, pixel_noise=3.0
)
# The typical gap with cables that rub in their holes: nylon line in printed-plastic disks
# (mu assumed, docs/assumptions.md), a hysteresis loop of a few per cent of the reach.
FRICTION_GAP = replace(TYPICAL_GAP, cable_friction=0.15)


def dahl_state(state, sliding, sliding_length: float):
    """The friction state z (B, C) in [-1, 1] after each cable slid by ``sliding`` (B, C) m
    (positive: towards its motor). Dahl's model dz/dx = (1 - z sgn(dx)) / x_s, solved exactly
    over a step of one sign: z' = s + (z - s) exp(-|dx| / x_s), s = sgn(dx). Sticking (|dx| <<
    x_s) barely moves z; sliding (|dx| >> x_s) takes it to +-1. Rate-independent, smooth, and
    bounded for any step, so it needs no finer time step than the plant's."""
    direction = np.sign(sliding)
    return direction + (state - direction) * np.exp(-np.abs(sliding) / sliding_length)


def capstan_tensions(base, turning, friction: float, state):
    """Tension at the anchored end and mean tension along the cable (B, C) each, for the
    tension ``base`` at the motor end, the cable's total turning ``turning`` (rad) through the
    disks, the friction coefficient and the friction state z (all (B, C) or broadcastable).

    Capstan: where the cable slides towards its motor (z = 1) the tension falls along it as
    exp(-mu phi), phi the turning from the base, so the anchored end carries T_b exp(-mu theta);
    sliding away (z = -1) it rises as exp(+mu phi); in between z scales the exponent,
    a = mu theta z. Turning grows along an arc at a constant rate, so the mean along the cable
    is T_b (1 - exp(-a)) / a (series below |a| = 1e-4, never divided by a small a)."""
    exponent = friction * np.asarray(turning) * state  # (B, C)
    small = np.abs(exponent) < 1e-4
    safe = np.where(small, 1.0, exponent)
    mean_factor = np.where(small, 1 - exponent / 2 + exponent**2 / 6, -np.expm1(-safe) / safe)
    return base * np.exp(-exponent), base * mean_factor


def calibrate_sag(robot: Robot, rest_tip, *, gravity: str) -> Robot:
    """The rod with its Young's modulus rescaled so that its unactuated equilibrium tip sags
    as far as a measured one (``rest_tip`` (3,), m, robot frame, docs/real_robot.md): the first
    thing to do with a real rod, since the sag (rho A g L^3 / 8 EI in small deflection) decides
    where every shape is reached. Statics identify only rho / E, so E carries the whole
    correction. ``gravity`` names the mounting the tip was measured in, and must be
    "horizontal": a hanging rod does not sag sideways, so it says nothing about E."""
    if gravity != "horizontal":
        raise ValueError(
            "calibrate_sag needs the rest tip of a horizontally mounted rod (gravity='horizontal'); "
            f"got gravity={gravity!r}: a rod hanging along gravity, or without it, does not sag sideways, "
            "so its rest tip says nothing about E. Calibrate from a horizontal mounting, or identify "
            "the rod from a filmed excitation (hardware.identification)"
        )
    rest_tip, _ = as_real_array(rest_tip, "rest_tip", (3,))
    if rest_tip[2] > 0:
        raise ValueError(
            f"rest_tip z = {rest_tip[2]:.4g} m is above the rod's axis, but gravity along -z sags the "
            "tip to z < 0: expected a negative z (robot frame: z up, docs/real_robot.md)"
        )
    straight = np.array([robot.length, 0.0, 0.0])
    measured = np.linalg.norm(rest_tip - straight)

    def scaled(log_scale):
        return replace(robot, youngs_modulus=robot.youngs_modulus * np.exp(log_scale))

    def sag(log_scale):
        return np.linalg.norm(Simulator(scaled(log_scale), gravity=gravity).static_tip(np.zeros((1, 2)))[0] - straight)

    low, high = np.log(0.1), np.log(10.0)
    softest, stiffest = sag(low), sag(high)
    if not stiffest <= measured <= softest:
        raise ValueError(
            f"a rest sag of {1e3 * measured:.1f} mm is outside what E x 0.1 .. 10 gives "
            f"({1e3 * stiffest:.1f} .. {1e3 * softest:.1f} mm); check rest_tip is in metres, robot frame"
        )
    return scaled(brentq(lambda x: sag(x) - measured, low, high, xtol=1e-10))


def cable_commands(
    u, sim: Simulator, stiffness: float = CABLE_STIFFNESS, pretension: float = PRETENSION, lead: float = 0.0
):
    """Planned actuation (B, T, 2) -> motor commands (B, T, C) in m, through the tension-driven
    model ``sim`` (the rod shape it predicts for the plan). ``lead`` (s): each command leads
    by that much of its rate of change, undoing a motor lag of that time constant."""
    u, _ = as_real_array(u, "u", (None, None, 2))
    _check_cables(stiffness, lead)
    B, T, _ = u.shape
    q, _ = sim.integrate(u, sim.rest_q(), np.zeros(sim.nq))
    delta = cable_displacements(sim.bend_angles(q.reshape(-1, sim.nq)), sim.robot).reshape(B, T + 1, -1)
    tensions = cable_tensions(u.reshape(-1, 2), sim.robot, pretension).reshape(B, T, -1)
    commands = tensions / stiffness - 0.5 * (delta[:, :-1] + delta[:, 1:])
    rest = np.broadcast_to(rest_command(sim, stiffness, pretension), (B, 1, commands.shape[2]))
    return commands + lead / DT * np.diff(commands, axis=1, prepend=rest)


def rest_command(sim: Simulator, stiffness: float = CABLE_STIFFNESS, pretension: float = PRETENSION) -> np.ndarray:
    """The motor commands (C,) in m that hold ``sim``'s rod at rest with every cable at its pretension."""
    return pretension / stiffness - cable_displacements(sim.bend_angles(sim.rest_q()[None]), sim.robot)[0]


def _check_cables(stiffness: float, lead: float):
    if not stiffness > 0:
        raise ValueError(f"stiffness must be positive; got {stiffness!r}")
    if not (np.isfinite(lead) and lead >= 0):
        raise ValueError(f"lead must be a finite time >= 0 s; got {lead!r}")


class StepCommands:
    """Motor commands one control step at a time, for a loop: ``commands(u)`` (2,) -> (C,) in
    m, through the model rod ``sim`` integrated alongside, exactly as ``cable_commands`` turns
    a whole plan (the cable path change averaged over the step, the same ``lead``)."""

    def __init__(
        self, sim: Simulator, stiffness: float = CABLE_STIFFNESS, pretension: float = PRETENSION, lead: float = 0.0
    ):
        _check_cables(stiffness, lead)
        self.sim, self.stiffness, self.pretension, self.lead = sim, stiffness, pretension, lead
        self.q, self.qd = sim.rest_q()[None], np.zeros((1, sim.nq))
        self.last = rest_command(sim, stiffness, pretension)

    def __call__(self, u) -> np.ndarray:
        u, _ = as_real_array(np.reshape(u, (1, 1, 2)), "u", (1, 1, 2))
        q, qd = self.sim.integrate(u, self.q, self.qd)
        delta = cable_displacements(self.sim.bend_angles(q[0]), self.sim.robot)  # (2, C): the step's ends
        self.q, self.qd = q[:, -1], qd[:, -1]
        command = cable_tensions(u[0], self.sim.robot, self.pretension)[0] / self.stiffness - 0.5 * (
            delta[0] + delta[1]
        )
        led, self.last = command + self.lead / DT * (command - self.last), command
        return led


class CablePlant:
    """The twin robot: motor positions in, rod motion out, across a ``RealityGap``."""

    def __init__(
        self,
        robot: Robot,
        gravity: str,
        gap: RealityGap = NO_GAP,
        *,
        stiffness: float = CABLE_STIFFNESS,
        pretension: float = PRETENSION,
        substeps: int = 4,
        cable_friction=None,
    ):
        """``cable_friction``: one coefficient per rod (B,) in place of the gap's, to replay one
        gap at several frictions in one batch (a batch of B rods then)."""
        self.robot, self.gap, self.stiffness, self.pretension, self.substeps = (
            robot,
            gap,
            stiffness,
            pretension,
            substeps,
        )
        if cable_friction is None:
            self.friction = gap.cable_friction
        else:
            friction, _ = as_real_array(cable_friction, "cable_friction", (None,))
            if (friction < 0).any():
                raise ValueError(f"cable_friction must hold coefficients >= 0; got {friction.tolist()}")
            self.friction = friction[:, None]  # (B, 1): per rod, across its cables
        self.sim = Simulator(gap.plant_robot(robot), gravity, dt=DT / substeps, substeps=1, threads=1)
        self.slack = np.random.default_rng(gap.seed).uniform(0.0, gap.slack, robot.n_cables)
        # the anchor group (an input pair) of each cable: its turning is that group's bend
        self.cable_group = np.zeros(robot.n_cables, int)
        for g, cables in enumerate(robot.cable_groups):
            self.cable_group[list(cables)] = g

    def _cable_stretch(self, motor, q):
        return motor + cable_displacements(self.sim.bend_angles(q), self.robot) - self.slack

    def reset(self, batch: int = 1) -> None:
        """``batch`` rods at rest, every motor holding the command of the rest pose (its
        pretension, less any slack), the cables' friction relaxed: the state ``step`` advances."""
        if np.ndim(self.friction) and len(self.friction) != batch:
            raise ValueError(f"this plant has a friction for each of {len(self.friction)} rods; got {batch} rods")
        sim = self.sim
        self.q, self.qd = np.repeat(sim.rest_q()[None], batch, 0), np.zeros((batch, sim.nq))
        self.motor = np.repeat(rest_command(sim, self.stiffness, self.pretension)[None], batch, 0)
        self.friction_state = np.zeros_like(self.motor)  # (B, C), Dahl's z
        self.sliding = self._sliding(self.motor, self.q)  # (B, C), m

    def _sliding(self, motor, q):
        """How far each cable has slid through the disks towards its motor, up to a constant
        (B, C): the motor's pull-in minus the path-length change (m)."""
        return motor - cable_displacements(self.sim.bend_angles(q), self.robot)

    def _turning(self, bend_angles):
        """Each cable's total turning through the disks (B, C), rad, for bend angles (B, m):
        the norm of its anchor group's pair, exact for an arc, a lower bound for other shapes."""
        return np.hypot(bend_angles[:, 0::2], bend_angles[:, 1::2])[:, self.cable_group]

    def tensions(self) -> dict:
        """Tensions (B, C) now at the motor end (``base``), at the anchor (``anchored``) and
        the mean along each cable (``mean``, what bends the rod). After ``reset``."""
        base = self.stiffness * np.maximum(self._cable_stretch(self.motor, self.q), 0.0)
        turning = self._turning(self.sim.bend_angles(self.q))
        anchored, mean = capstan_tensions(base, turning, self.friction, self.friction_state)
        return dict(base=base, anchored=anchored, mean=mean)

    def _rubbing_tension(self, q):
        """The mean tension along each cable (B, C) at shape q (B, nq), its friction state
        first moved on by the cables' sliding since the last substep."""
        angles = self.sim.bend_angles(q)  # (B, m)
        path = cable_displacements(angles, self.robot)  # (B, C)
        sliding = self.motor - path
        self.friction_state = dahl_state(self.friction_state, sliding - self.sliding, self.gap.sliding_length)
        self.sliding = sliding
        base = self.stiffness * np.maximum(self.motor + path - self.slack, 0.0)  # (B, C), at the motors
        return capstan_tensions(base, self._turning(angles), self.friction, self.friction_state)[1]

    def step(self, command) -> np.ndarray:
        """Hold motor commands (B, C) in m for DT: the rods move; returns the mean cable
        tensions (B, C) over the step (along each cable, as they bend the rod). After ``reset``."""
        sim, h = self.sim, DT / self.substeps
        follow = 1.0 - np.exp(-h / self.gap.motor_lag) if self.gap.motor_lag > 0 else 1.0
        tensions = np.zeros_like(self.motor)
        for _ in range(self.substeps):
            self.motor = self.motor + follow * (command - self.motor)
            if np.any(self.friction > 0):  # every rod rubs; one with mu = 0 gets a mean factor of exactly 1
                tension = self._rubbing_tension(self.q + 0.5 * h * self.qd)
            else:  # frictionless cables: the arithmetic of the plant before friction, bit for bit
                tension = self.stiffness * np.maximum(self._cable_stretch(self.motor, self.q + 0.5 * h * self.qd), 0.0)
            self.q, self.qd = (
                x[:, -1] for x in sim.integrate(cable_actuation(tension, self.robot)[:, None], self.q, self.qd)
            )
            tensions += tension / self.substeps
        return tensions

    def tip_state(self) -> np.ndarray:
        """The rods' tip states (B, 6) now."""
        return self.sim.tip_state(self.q, self.qd)

    def replay(self, commands) -> dict:
        """Motor commands (B, T, C) in m, held for DT each -> dict of tip ``states`` (B, T+1, 6),
        rod ``q`` (B, T+1, nq) and mean cable ``tensions`` (B, T, C) per step."""
        commands, _ = as_real_array(commands, "commands", (None, None, self.robot.n_cables))
        B, T, C = commands.shape
        self.reset(B)
        qs, qds, tensions = [self.q], [self.qd], np.zeros((B, T, C))
        for t in range(T):
            tensions[:, t] = self.step(commands[:, t])
            qs.append(self.q)
            qds.append(self.qd)
        qs, qds = np.stack(qs, 1), np.stack(qds, 1)
        states = self.sim.tip_state(qs.reshape(-1, self.sim.nq), qds.reshape(-1, self.sim.nq)).reshape(B, T + 1, 6)
        return dict(states=states, q=qs, tensions=tensions)


@dataclass(frozen=True)
class HysteresisLoop:
    """The plant's tip against a slowly cycled input (``hysteresis_loop``): what friction leaves
    of the cycle once the effects of its rate are removed."""

    u: np.ndarray  # (K,) N, the inputs where the branches are compared
    gap: np.ndarray  # (K,) down minus up branch, lateral tip, rate effects removed, fraction of the reach
    width: float  # the largest |gap|: the loop's width as a fraction of the reach
    reach: float  # m, half the tip's lateral span over the slower cycle
    down: np.ndarray  # (T, 2): u (N) and lateral tip (m) along the slower cycle's down branch
    up: np.ndarray  # (T, 2): the same along its up branch


def _branch_run(period: float, sign: float, n_steps: int, u_max: float) -> np.ndarray:
    """One input (T,) N: from 0 to sign u_max over period / 2, then to -sign u_max over the next
    half (the branch), each a half cosine (no jump in rate, so the rod is barely set ringing),
    then held."""
    t = np.arange(n_steps) * DT
    half = period / 2
    approach = sign * u_max * (1 - np.cos(np.pi * np.minimum(t, half) / half)) / 2
    branch = sign * u_max * np.cos(np.pi * np.clip(t - half, 0.0, half) / half)
    return np.where(t < half, approach, branch)


@functools.lru_cache(maxsize=4)
def _loop_commands(robot: Robot, gravity: str, period: float, u_max: float):
    """The four runs of ``hysteresis_loop``, u (4, T, 2) and motor commands (4, T, C), kept for
    the next gap (they depend on the model rod only, and cost as much as a replay)."""
    n_steps = int(round(period / DT)) + 1
    u = np.zeros((4, n_steps, 2))  # (4, T, 2): rods (period / 2: down, up; period: down, up)
    for rod, (cycle, sign) in enumerate([(period / 2, 1.0), (period / 2, -1.0), (period, 1.0), (period, -1.0)]):
        u[rod, :, 0] = _branch_run(cycle, sign, n_steps, u_max)
    commands = cable_commands(u, Simulator(robot, gravity))
    u.setflags(write=False)
    commands.setflags(write=False)
    return u, commands


def hysteresis_loop(
    gap: RealityGap,
    *,
    robot: Robot = HW_ROBOT,
    gravity: str = "vertical",
    period: float = LOOP_PERIOD,
    u_max: float = U_MAX,
) -> HysteresisLoop:
    """The loop the plant across ``gap`` draws when u1 is cycled over [-u_max, u_max] (u2 = 0),
    made into motor commands through the model rod (``cable_commands``), the tip's lateral y
    against u1: its width is the largest gap between the down and the up branch at the same u1,
    as a fraction of the reach (half the lateral span).

    Four rods in one batch: a down branch (0 -> u_max -> -u_max) and an up branch (0 -> -u_max
    -> u_max) at cycle periods ``period`` and ``period`` / 2. A lag tau (Kelvin-Voigt creep, motor
    lag) puts the branches tau du/dt apart, which halves when the period doubles, so the
    gap 2 g(period) - g(period / 2) keeps only what does not depend on the rate: the friction's.
    What is left of the rate, the rod's ringing, is 0.1-0.2 % of the reach at 20 s."""
    friction = gap.cable_friction
    return hysteresis_loops(gap, [friction], robot=robot, gravity=gravity, period=period, u_max=u_max)[friction]


def hysteresis_loops(
    gap: RealityGap,
    frictions,
    *,
    robot: Robot = HW_ROBOT,
    gravity: str = "vertical",
    period: float = LOOP_PERIOD,
    u_max: float = U_MAX,
) -> dict[float, HysteresisLoop]:
    """``hysteresis_loop`` of ``gap`` with each cable friction coefficient of ``frictions`` in
    its place: {mu: loop}, every plant in one batch (a replay costs per step, hardly per rod),
    each loop the one ``hysteresis_loop`` draws alone, bit for bit."""
    if robot.n_inputs != 2:
        raise ValueError(f"hysteresis_loop cycles u1 of a two-input rod; {robot.name!r} has {robot.n_inputs} inputs")
    if not (np.isfinite(period) and period >= 4 * DT and np.isfinite(u_max) and u_max > 0):
        raise ValueError(f"need a period of at least {4 * DT} s and u_max > 0 N; got {period!r} s, {u_max!r} N")
    frictions = [float(mu) for mu in frictions]
    if not frictions or len(set(frictions)) < len(frictions):
        raise ValueError(f"frictions must hold at least one coefficient, each once; got {frictions}")
    u, commands = _loop_commands(robot, gravity, float(period), float(u_max))  # (4, T, 2), (4, T, C)
    per_rod = np.repeat(frictions, len(commands))  # (4 F,): the four runs at each friction
    plant = CablePlant(robot, gravity, gap, cable_friction=per_rod)
    lateral = plant.replay(np.tile(commands, (len(frictions), 1, 1)))["states"][:, 1:, 1]  # (4 F, T), after each u_t
    return {mu: _loop(u, runs, period, u_max) for mu, runs in zip(frictions, np.split(lateral, len(frictions)))}


def _loop(u, lateral, period: float, u_max: float) -> HysteresisLoop:
    """The loop of the four runs' lateral tips (4, T) against their u1 (4, T, 2)."""
    grid = np.linspace(-u_max, u_max, 41)[1:-1]  # (K,) inside the turns, where the branches meet
    gaps, branches = [], []
    for first, cycle in ((0, period / 2), (2, period)):
        start, end = int(round(cycle / 2 / DT)), int(round(cycle / DT)) + 1
        down = np.stack([u[first, start:end, 0], lateral[first, start:end]], -1)  # (T', 2), u falling
        up = np.stack([u[first + 1, start:end, 0], lateral[first + 1, start:end]], -1)  # (T', 2), u rising
        gaps.append(np.interp(grid, *down[::-1].T) - np.interp(grid, *up.T))
        branches = [down, up]
    reach = float(np.ptp(lateral[2:])) / 2
    quasi_static = (2 * gaps[1] - gaps[0]) / reach  # (K,)
    return HysteresisLoop(grid, quasi_static, float(np.abs(quasi_static).max()), reach, *branches)


def twin_camera(sim: Simulator, gap: RealityGap = NO_GAP) -> vision.Camera:
    """The camera of the replay: on the rod's axis, CAMERA_DISTANCE beyond its rest tip."""
    rest_tip = sim.tip_positions(sim.rest_q()[None])[0]
    return vision.camera_facing(rest_tip, CAMERA_DISTANCE, depth_noise=gap.depth_noise, pixel_noise=gap.pixel_noise)


def observe_run(sim: Simulator, q, camera: vision.Camera, seed: int = 0):
    """Render a rod motion q (T+1, nq) sampled at DT and track its tip marker: (frame times, (K, 3))."""
    positions, _ = sim.centerline(q)
    times = np.arange(len(q)) * DT
    return vision.observe(
        times,
        positions[:, -1],
        camera,
        np.random.default_rng(seed),
        centerlines=positions,
        rod_diameter=sim.robot.diameter,
    )


def stroboscope_run(sim: Simulator, q, camera: vision.Camera, interval: float = 0.4, seed: int = 0) -> np.ndarray:
    """One multi-exposure picture of a rod motion q (T+1, nq): a frame every ``interval`` s."""
    every = int(round(interval / DT))
    if every < 1:
        raise ValueError(f"interval must be at least one sample ({DT} s); got {interval!r}")
    positions, _ = sim.centerline(q[::every])
    frames = vision.render(positions[:, -1], camera, seed, centerlines=positions, rod_diameter=sim.robot.diameter)
    return vision.stroboscope((color for color, _ in frames), every=1)


def tracked_rmse(frame_times, tracked, reference) -> float:
    """3D RMSE (m) of a camera track against a reference sampled at DT, over the frames inside
    the reference's mask that found the marker."""
    frame_times, tracked = np.asarray(frame_times, float), np.asarray(tracked, float)
    index = np.round(frame_times / DT).astype(int)
    if index.min() < 0 or index.max() >= len(reference.states):
        raise ValueError("frame times must lie within the reference")
    t_ref = np.arange(len(reference.states)) * DT
    expected = np.stack([np.interp(frame_times, t_ref, reference.states[:, k]) for k in range(3)], -1)
    scored = reference.mask[index] & np.isfinite(tracked).all(1)
    if not scored.any():
        raise ValueError("no tracked frame falls inside the reference's mask")
    return float(np.sqrt(np.mean(np.sum((tracked[scored] - expected[scored]) ** 2, axis=1))))


class TwinRig:
    """The twin as a rig for ``loop.run_loop``. ``command(u)`` turns u into motor commands
    (``StepCommands``) and advances the plant across ``gap`` by DT; ``measure()`` returns the camera frames
    that have arrived by then: taken at the camera's frame rate (at the first control sample
    at or after each frame time), rendered and tracked, each ``latency`` s late, a share
    ``dropped`` of them lost (no marker). With a ``calibration``, u becomes motor commands
    through the identified rod (``Calibration.step_commands``)."""

    def __init__(
        self,
        sim: Simulator,
        gap: RealityGap = NO_GAP,
        *,
        latency: float = 0.0,
        dropped: float = 0.0,
        seed: int = 0,
        calibration=None,
    ):
        if not (np.isfinite(latency) and latency >= 0 and 0 <= dropped < 1):
            raise ValueError(f"need latency >= 0 s and 0 <= dropped < 1; got {latency!r}, {dropped!r}")
        self.sim, self.latency, self.dropped = sim, latency, dropped
        self.plant, self.camera = CablePlant(sim.robot, sim.gravity, gap), twin_camera(sim, gap)
        self.plant.reset(1)
        self.to_motors = StepCommands(sim) if calibration is None else calibration.step_commands()
        self.rng = np.random.default_rng(seed)
        self.steps, self.next_frame, self.pending = 0, 0, []
        self.states, self.q = [self.plant.tip_state()[0]], [self.plant.q[0]]
        self.commands, self.frame_times, self.tracked = [], [], []
        self._film()

    def command(self, u) -> None:
        motor = self.to_motors(u)
        self.plant.step(motor[None])
        self.steps += 1
        self.states.append(self.plant.tip_state()[0])
        self.q.append(self.plant.q[0])
        self.commands.append(motor)
        self._film()

    def measure(self) -> list:
        now = self.steps * DT + 1e-9
        arrived = [(taken, position) for arrival, taken, position in self.pending if arrival <= now]
        self.pending = [frame for frame in self.pending if frame[0] > now]
        return arrived

    def _film(self):
        now = self.steps * DT
        while self.next_frame / self.camera.fps <= now + 1e-9:
            if self.rng.random() < self.dropped:
                position = np.full(3, np.nan)
            else:
                positions, _ = self.plant.sim.centerline(self.plant.q)
                frames = vision.render(
                    positions[:, -1], self.camera, self.rng, centerlines=positions, rod_diameter=self.sim.robot.diameter
                )
                position = vision.track(frames, self.camera)[0]
            self.pending.append((now + self.latency, now, position))
            self.frame_times.append(now)
            self.tracked.append(position)
            self.next_frame += 1
