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
(``hardware.calibrate_sag``) is not enough here: it fixes rho / E, but the actuated statics
also depend on u / E.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softflow.hardware.identification import Identified
from softflow.hardware.twin import StepCommands, cable_commands
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT

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
