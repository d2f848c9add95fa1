"""Dynamics of the geometric-variable-strain (GVS) rod: a cable-driven Cosserat rod, batched
in numpy. Kinematics (strain basis, frames, Jacobians) live in ``kinematics``, equilibria
and inverse statics in ``statics``; equation numbers refer to docs/simulator.md.

Dynamics (Lagrange in the strain coordinates q, D1):

    M(q) qdd + c(q, qd) + K q + D qd = B u + G(q)

with K = int Phi^T EI Phi ds (diagonal for Legendre), D = (eta/E) K (Kelvin-Voigt),
B the cable map (a constant body moment u r from the base to where the cables end), G gravity and
c = sum_n m_n Jp_n^T (d/dt Jp_n) qd the convective term (D2). Mass is lumped at the
segment ends (trapezoid weights); rotary inertia of the cross-section, (D/L)^2 ~ 1e-4 of
the translational one, is neglected. Time stepping (D3) is linearly implicit
trapezoidal: K and D (stiff, constant) implicit, M, G and c at an explicit half step, so
the stiff overdamped high modes stay stable at the 0.01 s sampling with a few substeps.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from tqdm import tqdm

from softflow.checks import as_real_array, check_choice
from softflow.rod import statics
from softflow.rod.kinematics import RodKinematics, rowwise
from softflow.rod.robots import DT, U_MAX, Robot

SIMULATOR_VERSION = 1  # bump when a number the simulator produces changes (it keys every cache)
GRAVITY = 9.81  # m/s^2
GRAVITY_DIRECTIONS = {
    "vertical": np.array([GRAVITY, 0.0, 0.0]),  # along +x: the rod hangs
    "horizontal": np.array([0.0, 0.0, -GRAVITY]),  # across the rod, along -z
    "none": np.zeros(3),
}
# Step of the central differences along qd (velocities, convective term): the largest
# curvature coefficient moves by 1e-3 1/m, i.e. the rod turns by about 4e-4 rad. Measured
# on a random episode against the exact Jacobian and a Richardson estimate (docs/simulator.md,
# D2): tip velocity 1.4e-8 relative error; convective force 4e-7, where round-off of the
# second difference dominates (truncation ~eps^2 takes over above 3e-3; 1e-2 gives 6e-7).
_CONVECTIVE_STEP = 1e-3  # 1/m
# Episodes a rollout thread gets at least: below this a step is numpy call overhead under the
# GIL, and splitting the batch doubles the overhead instead of sharing the work.
MIN_THREAD_CHUNK = 64
# Rows of one tip_state call when a rollout reads its states: enough to spread the per-call cost
# of the frames, few enough that their (rows, N, 3, 3) rotations stay in cache.
_TIP_STATE_ROWS = 2048
_REACH = 1e-9  # m: fit_holding's tip must be this close to p (an exact fit, 3 equations in m - 1 >= 3 unknowns)


def _default_threads() -> int:
    """Up to 2 rollout threads, fewer where the machine or $OMP_NUM_THREADS allows fewer."""
    budget = os.environ.get("OMP_NUM_THREADS", "")
    cap = int(budget) if budget.isdigit() and int(budget) > 0 else 2
    return max(1, min(2, os.cpu_count() or 1, cap))


class Simulator:
    """Batched GVS rod: rollouts, statics and inverse statics.

    Parameters
    ----------
    robot: physical parameters (``SIM_ROBOT``, ``HW_ROBOT`` or ``TWO_SEGMENT_ROD``); u has
        ``robot.n_inputs`` entries.
    gravity: "vertical" (along +x), "horizontal" (along -z) or "none".
    order: highest Legendre degree of each curvature in each of the rod's segments (q has
        2 (order+1) entries per segment); default 3 for a one-segment rod, 2 for more (two
        segments then carry 6 coefficients per curvature against 4, see docs/assumptions.md).
    n_segments: segments of the spatial integration, over the whole rod (shared among the
        rod's segments by length).
    substeps: time steps per ``dt`` sample.
    damping: False switches the Kelvin-Voigt damping off (for validation).
    threads, chunk_size: rollouts run in chunks of ``chunk_size`` episodes on
        ``threads`` threads (default: up to 2, at most $OMP_NUM_THREADS where set: a caller
        that budgets one thread per process means it); results do not depend on either.
    """

    def __init__(
        self,
        robot: Robot,
        gravity: str = "vertical",
        *,
        order: int | None = None,
        n_segments: int = 32,
        substeps: int = 4,
        dt: float = DT,
        damping: bool = True,
        threads: int | None = None,
        chunk_size: int = 256,
    ):
        if not isinstance(robot, Robot):
            raise ValueError(f"robot must be a softflow.rod.Robot (e.g. SIM_ROBOT); got {type(robot).__name__}")
        check_choice(gravity, "gravity", GRAVITY_DIRECTIONS)
        if order is None:
            order = 3 if len(robot.segment_lengths) == 1 else 2
        for name, value, low in (
            ("order", order, 0),
            ("n_segments", n_segments, 1),
            ("substeps", substeps, 1),
            ("chunk_size", chunk_size, 1),
            ("threads", 1 if threads is None else threads, 1),
        ):
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}; got {value!r}")
        if not (
            isinstance(dt, (int, float, np.floating, np.integer))
            and not isinstance(dt, bool)
            and math.isfinite(dt)
            and dt > 0
        ):
            raise ValueError(f"dt must be a positive number of seconds; got {dt!r}")
        self.robot, self.gravity, self.order, self.damping = robot, gravity, order, damping
        self.n_segments, self.substeps, self.dt = n_segments, substeps, dt
        self.threads, self.chunk_size = threads or _default_threads(), chunk_size
        self.g = GRAVITY_DIRECTIONS[gravity]
        self.kinematics = RodKinematics(robot.segment_lengths, order, n_segments)
        self.n_modes, self.nq, self.n_inputs = self.kinematics.n_modes, self.kinematics.nq, robot.n_inputs
        per_segment = self.kinematics.modes_per_segment

        # K = int Phi^T EI Phi ds = EI L_j / (2m + 1) per mode of segment j (Legendre orthogonality);
        # D = (eta/E) K (D1).
        modal = np.concatenate(
            [robot.bending_stiffness * part / (2 * np.arange(per_segment) + 1) for part in robot.segment_lengths]
        )
        self.stiffness = np.diag(np.concatenate([modal, modal]))  # (nq, nq)
        self.damping_matrix = (
            (robot.damping / robot.youngs_modulus) * self.stiffness if damping else np.zeros_like(self.stiffness)
        )
        # int_0^{s_g} Phi ds in the bending components up to the disk s_g where cable group g ends:
        # L_j on the m = 0 modes of the segments j before it (K5).
        self.anchor_integrals = np.zeros((self.nq, self.n_inputs))  # (nq, m)
        for g, anchor in enumerate(sorted(set(robot.anchors))):
            for j in range(robot.segment_ends.index(anchor) + 1):
                kappa_1 = j * per_segment
                self.anchor_integrals[kappa_1, 2 * g] = robot.segment_lengths[j]
                self.anchor_integrals[self.n_modes + kappa_1, 2 * g + 1] = robot.segment_lengths[j]
        # Cable map (D1, D4): group g applies the constant body moment u_g r over [0, s_g] -> r int_0^{s_g} Phi ds.
        self.cable_map = robot.cable_radius * self.anchor_integrals  # (nq, m)
        # Lumped masses at segment ends 1..N (trapezoid weights; node 0 is clamped).
        ds = self.kinematics.ds
        self.node_mass = robot.mass_per_length * 0.5 * (ds + np.append(ds[1:], 0.0))  # (N,)
        self._rest_q = self._static_table = None

    @property
    def u_bound(self) -> float:
        """|u| (N) of the tip cables that curls the rod into a full circle without gravity
        (2 pi EI / (r L)): beyond it the model (no self-contact) means nothing."""
        r = self.robot
        return 2 * math.pi * r.bending_stiffness / (r.cable_radius * r.length)

    def free_turning(self, u) -> np.ndarray:
        """Angle (rad) through which u (..., m) turns the rod without gravity (...,): the sum
        over segments j of L_j |kappa_j|, each bent by the cable groups that pass it (D4)."""
        pairs = np.reshape(u, np.shape(u)[:-1] + (-1, 2))  # (..., G, 2)
        per_segment = self.kinematics.modes_per_segment
        passing = self.anchor_integrals[: self.n_modes : per_segment, 0::2]  # (S, G): L_j where group g passes j
        r = self.robot
        return np.linalg.norm(passing @ pairs, axis=-1).sum(-1) * r.cable_radius / r.bending_stiffness

    def spec(self) -> dict:
        """Every number that decides what this simulator computes: the key of its caches
        (the robot's parameters, not its name; not threads or chunk_size)."""
        return dict(
            robot=self.robot.parameters(),
            gravity=self.gravity,
            order=self.order,
            n_segments=self.n_segments,
            substeps=self.substeps,
            dt=self.dt,
            damping=self.damping,
            version=SIMULATOR_VERSION,
        )

    def _actuation(self, u, shape):
        """u as a finite array of ``shape`` within the bound: unit mistakes fail loudly."""
        u, _ = as_real_array(u, "u", shape)
        if u.shape[0] == 0:
            raise ValueError("u must hold at least one episode (its batch axis is empty)")
        turning = self.free_turning(u).ravel()
        if u.size and turning.max() > 2 * math.pi:
            worst = turning.argmax()
            magnitude = np.linalg.norm(u.reshape(-1, u.shape[-1])[worst])
            raise ValueError(
                f"|u| = {magnitude:.3g} N exceeds {magnitude * 2 * math.pi / turning[worst]:.1f} N, the actuation "
                f"along it that curls {self.robot.name!r} into a full circle (u in newtons?)"
            )
        return u

    # ------------------------------------------------------------------ kinematics
    def centerline(self, q):
        """Rod shape: node positions (B, N+1, 3) and rotations (B, N+1, 3, 3), base first."""
        q, _ = as_real_array(q, "q", (None, self.nq))
        return self.kinematics.centerline(q)

    def tip_positions(self, q):
        """Tip position for generalized coordinates q (B, nq) -> (B, 3)."""
        return self.kinematics.tip_positions(q)

    def tip_state(self, q, qd):
        """Tip position and velocity (B, 6); velocity by a central difference along qd (D2)."""
        f, plus, minus, eps = self.kinematics.frames_along(q, qd, _CONVECTIVE_STEP)
        return np.concatenate([f["positions"][:, -1], (plus[:, -1] - minus[:, -1]) / (2 * eps)], -1)

    def disk_positions(self, q):
        """Position of each segment's end disk, base outwards, the tip last: q (..., nq) -> (..., S, 3)
        (e.g. the middle disk and the tip of ``TWO_SEGMENT_ROD`` from ``static_q`` or ``integrate``)."""
        q, _ = as_real_array(q, "q", (None,) * (np.ndim(q) - 1) + (self.nq,))
        ends = self.kinematics.disk_positions(q.reshape(-1, self.nq))
        return ends.reshape(q.shape[:-1] + ends.shape[1:])

    def bend_angles(self, q):
        """Bend angle of each curvature from the base to where each cable group ends,
        int_0^{s_g} kappa_i ds (B, m): what the cables of group g feel."""
        q, _ = as_real_array(q, "q", (None, self.nq))
        return q @ self.anchor_integrals

    # ------------------------------------------------------------------ dynamics
    def _convective_force(self, Jp, positions, along):
        """c = sum_n m_n Jp_n^T (d Jp_n/dt) qd (D2): the node accelerations along qd by a
        second central difference of the exact positions (``along``: positions_along's)."""
        plus, minus, eps = along
        acceleration = (plus - 2 * positions + minus) / (eps**2)[..., None]
        weighted = (acceleration * self.node_mass[:, None]).reshape(len(Jp), 1, -1)  # (B, 1, 3N)
        return (weighted @ Jp.reshape(len(Jp), -1, self.nq))[:, 0]

    def _dynamics_terms(self, q, f=None):
        """Frames (``frames(q)`` unless given), Jp, M(q) = sum_n m_n Jp_n^T Jp_n and the gravity force G(q) (D1)."""
        f = self.kinematics.frames(q) if f is None else f
        Jp = self.kinematics.position_jacobians(f)  # (B, N, 3, nq)
        flat = (Jp * np.sqrt(self.node_mass)[None, :, None, None]).reshape(Jp.shape[0], -1, self.nq)
        M = flat.transpose(0, 2, 1) @ flat
        G = np.einsum("bnik,i,n->bk", Jp, self.g, self.node_mass)
        return f, Jp, M, G

    def mass_matrix(self, q):
        """M(q) for q (B, nq) -> (B, nq, nq)."""
        q, _ = as_real_array(q, "q", (None, self.nq))
        return self._dynamics_terms(q)[2]

    def energy(self, q, qd):
        """Kinetic + elastic + gravitational energy (J) of each rod, (B,)."""
        _, _, M, _ = self._dynamics_terms(q)
        kinetic = 0.5 * np.einsum("bi,bij,bj->b", qd, M, qd)
        elastic = 0.5 * np.einsum("bi,ij,bj->b", q, self.stiffness, q)
        gravity = -np.einsum("bni,i,n->b", self.kinematics.frames(q)["positions"], self.g, self.node_mass)
        return kinetic + elastic + gravity

    def rest_q(self):
        """Gravity equilibrium with slack cables (straight rod when gravity is along it)."""
        if self._rest_q is None:
            self._rest_q = statics.equilibrium(self, np.zeros((1, self.n_inputs)))[0][0]
        return self._rest_q.copy()

    def _step(self, q, qd, force, h):
        """One linearly implicit trapezoidal step (D3): K, D implicit; M, G at the explicit
        half step; the convective force predicted with qd, then corrected once with the
        mean velocity of the step (keeps it second order and the energy balance tight)."""
        q_half = q + 0.5 * h * qd
        here, *along = self.kinematics.frames_along(q_half, qd, _CONVECTIVE_STEP)  # one call: 3 frames
        f, Jp, M, G = self._dynamics_terms(q_half, here)
        K, D = self.stiffness, self.damping_matrix
        implicit = 0.5 * h * D + 0.25 * h * h * K
        lhs = M + implicit
        known = np.einsum("bij,bj->bi", M, qd) - rowwise(qd, implicit.T) + h * (force + G - rowwise(q, K.T))
        qd_next = qd
        for corrector in (False, True):  # predictor (along qd), corrector (along the step's mean velocity)
            if corrector:
                along = self.kinematics.positions_along(q_half, 0.5 * (qd + qd_next), _CONVECTIVE_STEP)
            c = self._convective_force(Jp, f["positions"], along)
            qd_next = np.linalg.solve(lhs, (known - h * c)[..., None])[..., 0]
        return q + 0.5 * h * (qd + qd_next), qd_next

    def _advance(self, u, q, qd):
        """Sample-by-sample integration of one chunk; q, qd at the T+1 sample times."""
        B, T, _ = u.shape
        qs, qds = np.empty((B, T + 1, self.nq)), np.empty((B, T + 1, self.nq))
        qs[:, 0], qds[:, 0] = q, qd
        h = self.dt / self.substeps
        for t in range(T):
            force = rowwise(u[:, t], self.cable_map.T)
            for _ in range(self.substeps):
                q, qd = self._step(q, qd, force, h)
            qs[:, t + 1], qds[:, t + 1] = q, qd
        return qs, qds

    def _map_chunks(self, work, B, progress):
        """Run work(slice) over cache-sized chunks of the batch on a thread pool (numpy
        releases the GIL) and concatenate the results along the batch axis."""
        # every thread gets work, but never so little that per-step overhead outweighs it
        size = min(self.chunk_size, max(MIN_THREAD_CHUNK, -(-B // self.threads)))
        chunks = [slice(i, min(i + size, B)) for i in range(0, B, size)]
        if len(chunks) == 1 and not progress:  # a closed loop's step: a pool's thread costs more than the work
            return list(work(chunks[0]))
        with (
            ThreadPoolExecutor(self.threads) as pool,
            tqdm(total=B, disable=not progress, desc="simulating", unit="episode") as bar,
        ):
            results = []
            for chunk, result in zip(chunks, pool.map(work, chunks)):
                results.append(result)
                bar.update(chunk.stop - chunk.start)
        return [np.concatenate(parts) for parts in zip(*results)]

    def integrate(self, u, q0, qd0, *, progress: bool = False):
        """Advance every rod through u (B, T, m) from (q0, qd0) (B, nq); zero-order hold.

        Returns q and qd at the T+1 sample times, each (B, T+1, nq).
        """
        u = self._actuation(u, (None, None, self.n_inputs))
        B = u.shape[0]
        q0, _ = as_real_array(np.broadcast_to(q0, (B, self.nq)), "q0", (B, self.nq))
        qd0, _ = as_real_array(np.broadcast_to(qd0, (B, self.nq)), "qd0", (B, self.nq))
        return self._map_chunks(lambda c: self._advance(u[c], q0[c], qd0[c]), B, progress)

    def rollout(self, u, *, start_q=None, progress: bool = False):
        """Tip states (B, T+1, 6) = [p, v] for actuation u (B, T, m) from rest: the rest pose,
        or ``start_q`` (B, nq) (e.g. an equilibrium, ``static_q``) at zero velocity."""
        u = self._actuation(u, (None, None, self.n_inputs))
        B = u.shape[0]
        q0 = self.rest_q() if start_q is None else as_real_array(start_q, "start_q", (B, self.nq))[0]
        q0, qd0 = np.broadcast_to(q0, (B, self.nq)), np.zeros((B, self.nq))

        def work(c):
            qs, qds = self._advance(u[c], q0[c], qd0[c])  # (b, T+1, nq) each
            return (self._tip_states(qs, qds),)

        return self._map_chunks(work, B, progress)[0]

    def _tip_states(self, qs, qds):
        """tip_state at every sample of histories (b, T+1, nq) -> (b, T+1, 6), blocks of samples per
        call (the rows are independent: the bits of one call per sample)."""
        b, samples = qs.shape[:2]
        per_call = max(1, _TIP_STATE_ROWS // b)
        blocks = [
            self.tip_state(qs[:, t : t + per_call].reshape(-1, self.nq), qds[:, t : t + per_call].reshape(-1, self.nq))
            for t in range(0, samples, per_call)
        ]
        return np.concatenate([block.reshape(b, -1, 6) for block in blocks], 1)

    # ------------------------------------------------------------------ statics (softflow.statics)
    def static_q(self, u):
        """Equilibrium generalized coordinates for actuation u (B, m) -> (B, nq)."""
        return statics.equilibrium(self, self._actuation(u, (None, self.n_inputs)))[0]

    def static_tip(self, u):
        """Equilibrium tip position for constant actuation u (B, m) -> (B, 3)."""
        return statics.static_tip(self, self._actuation(u, (None, self.n_inputs)))

    def inverse_static(self, p, tol=1e-10, max_iter=50, max_residual=None):
        """Actuation (B, m) whose equilibrium tip is closest to p (B, 3), least squares; for a
        rod with more than three inputs (``TWO_SEGMENT_ROD``), which reaches a point with a
        curve of u, the u of least norm |u| among those that reach it (the stationary point
        of |u| on that curve that Gauss-Newton with a null-space Newton step finds from the
        tip cables' arc, docs/simulator.md S4). ValueError for a point farther than
        ``max_residual`` (m; default a quarter of the rod's length) from every equilibrium
        tip: wrong units or frame."""
        p, _ = as_real_array(p, "p", (None, 3))
        if p.shape[0] == 0:
            raise ValueError("p must hold at least one point (its batch axis is empty)")
        return statics.inverse_static(self, p, tol, max_iter, max_residual)

    def fit_holding(self, p, index: int, value, start=None, tol=1e-10, max_iter=50):
        """Actuation (B, m) with input ``index`` held at ``value`` (N; a number or one per point,
        (B,)) whose equilibrium tip is p (B, 3), for a rod with more inputs than three
        (``TWO_SEGMENT_ROD``): another u than ``inverse_static``'s least-norm one that puts the
        tip at the same point, e.g. u_1 one newton above it. Gauss-Newton on the other inputs
        from ``start`` (B, m) (default the tip cables' arc through p). ValueError where no
        equilibrium with that input held reaches a point (within |u| <= u_bound)."""
        if self.n_inputs <= 3:
            raise ValueError(
                f"fit_holding needs a rod with more inputs than the tip's 3 coordinates; {self.robot.name!r} has "
                f"{self.n_inputs}, whose tip fixes u (use inverse_static)"
            )
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < self.n_inputs:
            raise ValueError(f"index must be an input's index, an integer in [0, {self.n_inputs - 1}]; got {index!r}")
        p, _ = as_real_array(p, "p", (None, 3))
        if p.shape[0] == 0:
            raise ValueError("p must hold at least one point (its batch axis is empty)")
        value = as_real_array(
            np.broadcast_to(value, p.shape[:1]) if np.ndim(value) == 0 else value, "value", (len(p),)
        )[0]
        if start is not None:
            start = self._actuation(start, (len(p), self.n_inputs))
        try:
            u, tip = statics.fit_holding(self, p, index, value, start, tol, max_iter, u_limit=self.u_bound)
        except (RuntimeError, np.linalg.LinAlgError) as error:
            raise ValueError(
                f"no equilibrium with u{index + 1} held at the values given reaches every point of p "
                f"within |u| <= {self.u_bound:.1f} N ({error}): hold it nearer inverse_static(p)'s u{index + 1}"
            ) from error
        miss = np.linalg.norm(tip - p, axis=-1)
        if miss.max() > _REACH:
            i = int(miss.argmax())
            raise ValueError(
                f"p[{i}] = {np.round(p[i], 4).tolist()} m is not reached with u{index + 1} held at {value[i]:.3f} N "
                f"(the fit stops {1e3 * miss[i]:.3g} mm away): hold it nearer inverse_static(p)'s u{index + 1}"
            )
        return u

    def static_lift(self, yz, u_max: float = U_MAX):
        """The equilibrium whose tip has lateral position yz (B, 2): tip p (B, 3), actuation
        u (B, 2) and d p / d(y, z) (B, 3, 2), for lifting y-z paths to 3D (two-input rods)."""
        yz, _ = as_real_array(yz, "yz", (None, 2))
        return statics.static_lift(self, yz, u_max)

    def static_table(self) -> statics.StaticTable:
        """The tabulated statics of this two-input rod (the RF-Physical prior), built once per simulator."""
        if self._static_table is None:
            self._static_table = statics.StaticTable(self)
        return self._static_table
