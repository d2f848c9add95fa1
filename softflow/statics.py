"""Tabulated statics: the equilibrium tip as a smooth function of u, for inverse statics on
millions of points (the prior of RF-Physical) in seconds instead of hours.

The simulator's equilibrium tip is solved once on a grid of u and interpolated with
bicubic splines (value and gradient); ``inverse`` is then Gauss-Newton on the spline.
"""
from __future__ import annotations

import sys
from dataclasses import asdict

import numpy as np
from scipy.interpolate import RectBivariateSpline
from tqdm import tqdm

from . import data as data_module
from . import sim as sim_module
from .checks import as_real_array
from .data import cache_path, read_npz, write_npz_atomic
from .sim import Simulator


class StaticTable:
    """Equilibrium tip p(u) on [-u_range, u_range]^2, sampled every ``step`` N, as splines."""

    def __init__(self, sim: Simulator, u_range: float = 6.0, step: float = 0.2, progress: bool = False):
        self.sim, self.u_range = sim, u_range
        grid = np.linspace(-u_range, u_range, int(round(2 * u_range / step)) + 1)
        spec = dict(robot=asdict(sim.robot), gravity=sim.gravity, order=sim.order, n_segments=sim.n_segments,
                    u_range=u_range, step=step)
        path = cache_path("static-table", spec, (sim_module, data_module, sys.modules[__name__]))
        tips = (read_npz(path) or {}).get("tips")
        if tips is None or tips.shape != (len(grid), len(grid), 3):
            u = np.stack(np.meshgrid(grid, grid, indexing="ij"), -1).reshape(-1, 2)
            chunks = [sim.static_tip(u[i:i + 256]) for i in tqdm(range(0, len(u), 256), disable=not progress,
                                                                  desc="static table")]
            tips = np.concatenate(chunks).reshape(len(grid), len(grid), 3)
            write_npz_atomic(path, tips=tips)
        self.splines = [RectBivariateSpline(grid, grid, tips[..., i], kx=3, ky=3) for i in range(3)]

    def tip(self, u):
        """Tip (B, 3) and its Jacobian d p / d u (B, 3, 2) from the splines."""
        u1, u2 = u[:, 0], u[:, 1]
        p = np.stack([s.ev(u1, u2) for s in self.splines], -1)
        J = np.stack([np.stack([s.ev(u1, u2, dx=1), s.ev(u1, u2, dy=1)], -1) for s in self.splines], 1)
        return p, J

    def inverse(self, p, iterations: int = 12) -> np.ndarray:
        """Least-squares actuation for tip positions p (..., 3) -> (..., 2), clipped to the table.

        Same answer as ``Simulator.inverse_static`` inside the table (to the spline
        accuracy), for any number of points at once."""
        batch_shape = np.shape(p)[:-1]
        if np.shape(p)[-1:] != (3,):
            raise ValueError(f"p must have shape (..., 3); got {np.shape(p)}")
        p, _ = as_real_array(np.reshape(p, (-1, 3)), "p", (None, 3))
        r = self.sim.robot
        lateral = np.hypot(p[:, 1], p[:, 2])
        bend = 2 * np.arctan2(lateral, p[:, 0])  # gravity-free arc through p: the start
        heading = np.arctan2(p[:, 2], p[:, 1])
        u = (bend / r.length * r.bending_stiffness / r.cable_radius)[:, None] * np.stack([np.cos(heading), np.sin(heading)], -1)
        u = np.clip(u, -self.u_range, self.u_range)
        for _ in range(iterations):
            tip, J = self.tip(u)
            JT = J.transpose(0, 2, 1)
            du = np.linalg.solve(JT @ J + 1e-12 * np.eye(2), JT @ (p - tip)[..., None])[..., 0]
            u = np.clip(u + du, -self.u_range, self.u_range)
        return u.reshape(batch_shape + (2,))
