"""Calibration: plan for the rod on the bench rather than the rod the inverse model was
trained on, without retraining. ``identification.identify`` fits the rod's E, eta, rho and
its motors' lag; a ``Calibration`` then corrects what the model plans in three places:

1. statics: each planned u becomes the u that holds the identified rod's tip where the
   model rod's tip would be (the sag and stiffness errors, most of the twin's horizontal
   error). The correction fades in over the first ``RAMP_SECONDS``: a reference starts at
   the model rod's rest, not the real one's, and a step there rings the first bending mode;
2. cables: u becomes motor positions through the identified rod's shape, not the model's;
3. motors: the commands lead by the identified lag (the inverse of a first-order lag).

The rest of the gap (inertia, damping, slack) is left to feedback. The rest pose alone
(``calibrate_sag``, below) is not enough here: it fixes rho / E, but the actuated statics
also depend on u / E.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq

from softflow.checks import as_real_array
from softflow.hardware.commands import StepCommands, cable_commands
from softflow.hardware.identification import Identified
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, Robot

RAMP_SECONDS = 1.0


@dataclass(frozen=True)
class Calibration:
    model: Simulator  # the rod the inverse model was trained on
    rod: Simulator  # the identified rod
    motor_lag: float = 0.0  # s, the identified motor lag

    def __post_init__(self):
        if self.model.gravity != self.rod.gravity:
            raise ValueError(
                f"model and rod must share a configuration; got {self.model.gravity!r} and {self.rod.gravity!r}"
            )
        if not (np.isfinite(self.motor_lag) and self.motor_lag >= 0):
            raise ValueError(f"motor_lag must be a finite time >= 0 s; got {self.motor_lag!r}")

    @classmethod
    def identified(cls, model: Simulator, fit: Identified) -> Calibration:
        """The calibration an identification run gives (``fit`` relative to ``model``'s rod)."""
        return cls(model, Simulator(fit.gap.plant_robot(model.robot), model.gravity), fit.gap.motor_lag)

    def actuation(self, u, first_step: int = 0) -> np.ndarray:
        """Planned u (..., T, 2), for control steps first_step .. first_step + T - 1 -> the u
        that puts the identified rod's static tip where the model rod's would be."""
        u = np.asarray(u, float)
        if u.ndim < 2 or u.shape[-1] != 2:
            raise ValueError(f"u must have shape (..., T, 2); got {u.shape}")
        tip, _ = self.model.static_table().tip(u.reshape(-1, 2))
        moved = self.rod.static_table().inverse(tip).reshape(u.shape) - u
        seconds = (first_step + np.arange(u.shape[-2])) * DT
        fade = np.where(seconds < RAMP_SECONDS, 0.5 - 0.5 * np.cos(np.pi * seconds / RAMP_SECONDS), 1.0)
        return u + fade[:, None] * moved

    def commands(self, u) -> np.ndarray:
        """A whole calibrated plan (B, T, 2) -> motor commands (B, T, C)."""
        return cable_commands(u, self.rod, lead=self.motor_lag)

    def step_commands(self) -> StepCommands:
        """Motor commands one step at a time, for a loop's rig."""
        return StepCommands(self.rod, lead=self.motor_lag)


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
