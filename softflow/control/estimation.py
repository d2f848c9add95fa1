"""State estimation for the closed loop: a camera's tip positions (30 fps, late, sometimes
missing) become the tip position and velocity the inverse model needs every 10 ms.

A constant-acceleration Kalman filter per axis (state p, v, a; white jerk as process noise):
each frame updates it at the time the frame was *taken*, and the control loop asks for the
state *now*, which the filter predicts forward over the camera's latency. A lost frame (no
marker, NaN) is no update: the prediction bridges it, and its uncertainty grows meanwhile.
"""

from __future__ import annotations

import math

import numpy as np

from softflow.checks import as_real_array

FRAME_NOISE = 1e-3  # m, standard deviation of a tracked marker position (the twin's camera: ~1 mm)
JERK = 1.0  # m/s^3 / sqrt(Hz): white-jerk density, about the jerk of the hardware shapes (v^3 / r^2 = 1.35 m/s^3)


class TipEstimator:
    """Tip position and velocity from late, noisy, sometimes missing camera positions.

    ``update(t, position)`` with the time the frame was taken (s) and its (3,) position (NaN:
    the marker was lost); ``state(t)`` the estimated (6,) [p, v] at time t, predicted from the
    last frame. Frames must arrive in the order they were taken."""

    def __init__(self, initial_position, *, frame_noise: float = FRAME_NOISE, jerk: float = JERK):
        position, _ = as_real_array(initial_position, "initial_position", (3,))
        for name, value in (("frame_noise", frame_noise), ("jerk", jerk)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number; got {value!r}")
        self.frame_noise, self.jerk = float(frame_noise), float(jerk)
        self.x = np.zeros((3, 3))  # per axis (rows): p, v, a
        self.x[:, 0] = position
        self.P = np.diag([frame_noise**2, 1e-2, 1.0])  # the same for every axis; starts at rest, roughly
        self.t = None  # time of the last frame taken
        self.frames = self.lost = 0

    def _transition(self, h: float):
        F = np.array([[1, h, h * h / 2], [0, 1, h], [0, 0, 1]])
        Q = self.jerk**2 * np.array(
            [[h**5 / 20, h**4 / 8, h**3 / 6], [h**4 / 8, h**3 / 3, h**2 / 2], [h**3 / 6, h**2 / 2, h]]
        )
        return F, Q

    def update(self, t: float, position) -> None:
        """Fold in the frame taken at time ``t`` (s); a NaN position counts it as lost."""
        if not math.isfinite(t) or (self.t is not None and t <= self.t):
            raise ValueError(
                f"frames must come in the order they were taken, at finite times; got t = {t!r} after {self.t!r}"
            )
        position = np.asarray(position, float)
        if position.shape != (3,):
            raise ValueError(f"position must have shape (3,); got {position.shape}")
        if self.t is not None:
            F, Q = self._transition(t - self.t)
            self.x, self.P = self.x @ F.T, F @ self.P @ F.T + Q
        self.t = t
        self.frames += 1
        if not np.all(np.isfinite(position)):
            self.lost += 1
            return
        gain = self.P[:, 0] / (self.P[0, 0] + self.frame_noise**2)  # H = [1, 0, 0]
        self.x = self.x + np.outer(position - self.x[:, 0], gain)
        self.P = self.P - np.outer(gain, self.P[0])

    def state(self, t: float) -> np.ndarray:
        """The (6,) tip state [p, v] at time ``t`` >= the last frame's, predicted from it."""
        if self.t is None:
            return np.concatenate([self.x[:, 0], self.x[:, 1]])
        if not t >= self.t:
            raise ValueError(f"t = {t!r} is before the last frame ({self.t}): the estimator only predicts forward")
        F, _ = self._transition(t - self.t)
        x = self.x @ F.T
        return np.concatenate([x[:, 0], x[:, 1]])
