"""The hardware twin as a rig (Sec. V): the plant across a reality gap, watched by a camera on
the rod's axis, driven one control step at a time (``TwinRig``, for ``control.closed_loop``),
and the camera's helpers for a replayed run (``twin_camera``, ``observe_run``,
``stroboscope_run``, ``tracked_rmse``)."""

from __future__ import annotations

import numpy as np

from softflow.hardware import vision
from softflow.hardware.commands import StepCommands
from softflow.hardware.gap import NO_GAP, RealityGap
from softflow.hardware.plant import CablePlant
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT

CAMERA_DISTANCE = 0.4  # m, camera beyond the rest tip, looking back along the rod


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
