"""System identification of a rod: excite it, film the tip, and fit the parameters that the
reality gap gets wrong, E, eta, rho and the motor lag, by least squares through the plant's
replay of the same commands.

The statics alone identify only rho / E (``hardware.calibrate_sag``); a moving tip adds its
bending frequency (sqrt(E / rho)), its decay (eta) and its delay behind the motors (the
lag), so all four separate. The fit runs on what a real rig records: the motor commands
sent and the camera's tip positions at the frame times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from softflow.checks import as_real_array
from softflow.data.excitation import sum_of_sines_excitation
from softflow.hardware.commands import cable_commands
from softflow.hardware.gap import RealityGap
from softflow.hardware.plant import CablePlant
from softflow.hardware.twin import observe_run, twin_camera
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT

EXCITATION_SECONDS = 3.0
FITTED = ("youngs_modulus", "damping", "density", "motor_lag")  # the RealityGap terms identify fits


def excitation_commands(sim: Simulator, seconds: float = EXCITATION_SECONDS, seed: int = 0, u_max: float = 2.0):
    """Motor commands (T, C) of an identification run: sums of sines up to 3 Hz (through the
    first bending mode) on both bending inputs, made through the model rod ``sim``."""
    u = sum_of_sines_excitation(1, int(round(seconds / DT)), seed, u_max=u_max, frequencies=(0.2, 3.0))
    return cable_commands(u, sim)[0]


@dataclass(frozen=True)
class Identified:
    gap: RealityGap  # the fitted relative errors of E, eta, rho and the motor lag (s) against the model rod
    rmse_mm: float  # of the fitted replay against the recording
    evaluations: int


def identify(sim: Simulator, commands, frame_times, tracked) -> Identified:
    """Fit E, eta, rho (relative to ``sim``'s rod) and the motor lag so that the plant's replay
    of ``commands`` (T, C) matches the recorded tip ``tracked`` (K, 3) at ``frame_times`` (K,)
    (rows with NaN, frames without the marker, are left out)."""
    commands, _ = as_real_array(commands, "commands", (None, sim.robot.n_cables))
    frame_times, _ = as_real_array(frame_times, "frame_times", (None,))
    tracked = np.asarray(tracked, float)
    if tracked.shape != (len(frame_times), 3):
        raise ValueError(f"tracked must have shape ({len(frame_times)}, 3); got {tracked.shape}")
    seen = np.isfinite(tracked).all(1) & (frame_times <= len(commands) * DT)
    if seen.sum() < 10:
        raise ValueError(f"need at least 10 frames with the marker inside the run; got {int(seen.sum())}")
    t = np.arange(len(commands) + 1) * DT

    def gap_of(x):
        return RealityGap(youngs_modulus=np.expm1(x[0]), damping=np.expm1(x[1]), density=np.expm1(x[2]), motor_lag=x[3])

    def residual(x):
        states = CablePlant(sim.robot, sim.gravity, gap_of(x)).replay(commands[None])["states"][0]
        predicted = np.stack([np.interp(frame_times[seen], t, states[:, k]) for k in range(3)], -1)
        return 1e3 * (predicted - tracked[seen]).ravel()  # mm: residuals of order one

    fit = least_squares(
        residual,
        x0=[0.0, 0.0, 0.0, 0.01],
        bounds=([-1.5, -1.5, -1.5, 0.0], [1.5, 1.5, 1.5, 0.2]),
        diff_step=1e-3,
        x_scale=[0.1, 0.1, 0.1, 0.01],
    )
    return Identified(gap_of(fit.x), float(np.sqrt(np.mean(fit.fun**2) * 3)), int(fit.nfev))


def identify_twin(sim: Simulator, gap: RealityGap, seconds: float = EXCITATION_SECONDS, seed: int = 0) -> Identified:
    """The identification run on the hardware twin: ``excitation_commands`` replayed on the
    plant across ``gap``, filmed by its camera, fitted (as a real rig would be)."""
    commands = excitation_commands(sim, seconds, seed)
    plant = CablePlant(sim.robot, sim.gravity, gap)
    times, tracked = observe_run(plant.sim, plant.replay(commands[None])["q"][0], twin_camera(sim, gap), seed)
    return identify(sim, commands, times, tracked)
