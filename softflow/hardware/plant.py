"""The twin's plant (Sec. V): motor positions in, rod motion out, across a ``RealityGap``.

The plant is the same rod with every term of the gap: its E, eta, rho are off, motors follow
their commands with a first-order lag, each cable has its own slack (tension k max(0, stretch
- slack)), the cables rub in the spacer disks (capstan friction with a Dahl state,
``friction.capstan_tensions``), and the camera adds its noise. Cable tension is re-evaluated
every quarter step, as the physical cable would.
"""

from __future__ import annotations

import numpy as np

from softflow.checks import as_real_array
from softflow.hardware.commands import CABLE_STIFFNESS, PRETENSION, rest_command
from softflow.hardware.friction import capstan_tensions, dahl_state
from softflow.hardware.gap import NO_GAP, RealityGap
from softflow.rod.cables import cable_actuation, cable_displacements
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, Robot


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
            tension = self._rubbing_tension(self.q + 0.5 * h * self.qd)  # mu = 0: a mean factor of exactly 1
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
