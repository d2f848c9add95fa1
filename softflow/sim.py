"""Geometric-variable-strain (GVS) model of a cable-driven Cosserat rod, batched in numpy.

Strain: the rod is inextensible, unshearable and torsion-free; its two bending
curvatures are Legendre series in the arc length,

    kappa_i(s) = sum_m q[i, m] P_m(2 s / L - 1),   i = 1 (towards +y), 2 (towards +z),

so the body curvature vector is k = (0, -kappa_2, kappa_1) and q has 2 (order + 1)
entries. Kinematics integrates g' = g xi^ along s on ``n_segments`` segments: each
segment rotates by the exact integral of k (Magnus, first term) and its chord is
the exact one for constant curvature, so a uniform bend is reproduced exactly.
Mass is lumped at the segment ends (trapezoid weights); rotary inertia of the
cross-section, (D/L)^2 ~ 1e-4 of the translational one, is neglected.

Dynamics (Lagrange, generalized coordinates q):

    M(q) qdd + c(q, qd) + K q + D qd = B u + G(q)

with K = int Phi^T EI Phi ds (diagonal for Legendre), D = (eta/E) K (Kelvin-Voigt),
B the cable map (a constant body moment u r over the length), G gravity and
c = sum_n m_n Jp_n^T (d/dt Jp_n) qd the convective term. Time stepping is linearly
implicit trapezoidal: K and D (stiff, constant) implicit, M, G and c evaluated at
an explicit half step, so the stiff overdamped high modes stay stable at the
0.01 s sampling with a few substeps.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.polynomial import legendre
from tqdm import tqdm

from .checks import as_real_array, check_choice
from .robots import Robot

GRAVITY = 9.81  # m/s^2
GRAVITY_DIRECTIONS = {
    "vertical": np.array([GRAVITY, 0.0, 0.0]),  # along +x: the rod hangs
    "horizontal": np.array([0.0, 0.0, -GRAVITY]),  # across the rod, along -z
    "none": np.zeros(3),
}
_SERIES_BELOW = 1e-2  # rad; below this angle (t - sin t)/t^3 and c'(t)/t use their Taylor series
_CONVECTIVE_STEP = 1e-3  # 1/m; curvature step of the central differences along qd


def _sinc(x):
    """sin(x)/x, exact at 0 (numpy's sinc is normalised by pi)."""
    return np.sinc(x / np.pi)


def _cubic_ratios(theta):
    """beta = (t - sin t)/t^3 and c'(t)/t for the chord factor c(t) = sin(t/2)/(t/2);
    both cancel catastrophically at small t, so a series is used there (never 0/0)."""
    small = theta < _SERIES_BELOW
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    beta = np.where(small, 1 / 6 - t2 / 120 + t2**2 / 5040, (t - np.sin(t)) / t**3)
    dchord = np.where(small, -1 / 12 + t2 / 480 - t2**2 / 53760, (t * np.cos(t / 2) - 2 * np.sin(t / 2)) / t**3)
    return beta, dchord


def _exp_bending(y, z, sinc, alpha):
    """Exp of the rotation vector (0, y, z) (Rodrigues, written out: no torsion component)."""
    E = np.empty(y.shape + (3, 3))
    E[..., 0, 0] = 1 - alpha * (y * y + z * z)
    E[..., 0, 1], E[..., 0, 2] = -sinc * z, sinc * y
    E[..., 1, 0], E[..., 1, 1], E[..., 1, 2] = sinc * z, 1 - alpha * z * z, alpha * y * z
    E[..., 2, 0], E[..., 2, 1], E[..., 2, 2] = -sinc * y, alpha * y * z, 1 - alpha * y * y
    return E


def _left_jacobian_columns(y, z, alpha, beta):
    """J_l(phi) e3 and J_l(phi) (-e2) for phi = (0, y, z), stacked on the last axis: (..., 3, 2).

    J_l(phi) = I + alpha phi^ + beta phi^2 maps a change of a segment's rotation vector
    to the change of its rotation in the spatial frame."""
    out = np.empty(y.shape + (3, 2))
    out[..., 0, 0], out[..., 1, 0], out[..., 2, 0] = alpha * y, beta * y * z, 1 - beta * y * y
    out[..., 0, 1], out[..., 1, 1], out[..., 2, 1] = alpha * z, beta * z * z - 1, -beta * y * z
    return out


def _cross_columns(a, b):
    """a x b along axis 2, for a (B, N, 3, ...) and b (B, N, 3) broadcast over the trailing axes."""
    b = b.reshape(b.shape + (1,) * (a.ndim - 3))
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, :, 0] = a[:, :, 1] * b[:, :, 2] - a[:, :, 2] * b[:, :, 1]
    out[:, :, 1] = a[:, :, 2] * b[:, :, 0] - a[:, :, 0] * b[:, :, 2]
    out[:, :, 2] = a[:, :, 0] * b[:, :, 1] - a[:, :, 1] * b[:, :, 0]
    return out


class Simulator:
    """Batched GVS rod: rollouts, statics and inverse statics.

    Parameters
    ----------
    robot: physical parameters (``SIM_ROBOT`` or ``HW_ROBOT``).
    gravity: "vertical" (along +x), "horizontal" (along -z) or "none".
    order: highest Legendre degree of each curvature (q has 2 (order+1) entries).
    n_segments: segments of the spatial integration.
    substeps: time steps per 0.01 s sample.
    damping: False switches the Kelvin-Voigt damping off (for validation).
    threads, chunk_size: rollouts run in chunks of ``chunk_size`` episodes on
        ``threads`` threads (default: up to 2); results do not depend on either.
    """

    def __init__(self, robot: Robot, gravity: str = "vertical", *, order: int = 3, n_segments: int = 32,
                 substeps: int = 4, dt: float = 0.01, damping: bool = True, threads: int | None = None,
                 chunk_size: int = 256):
        check_choice(gravity, "gravity", GRAVITY_DIRECTIONS)
        for name, value, low in (("order", order, 0), ("n_segments", n_segments, 1), ("substeps", substeps, 1)):
            if not isinstance(value, (int, np.integer)) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}; got {value!r}")
        if not dt > 0:
            raise ValueError(f"dt must be positive; got {dt!r}")
        self.robot, self.gravity, self.order = robot, gravity, order
        self.n_segments, self.substeps, self.dt = n_segments, substeps, dt
        self.threads, self.chunk_size = threads or min(2, os.cpu_count() or 1), chunk_size
        self.g = GRAVITY_DIRECTIONS[gravity]
        self.n_modes = order + 1
        self.nq = 2 * self.n_modes
        L, N = robot.length, n_segments
        self.ds = L / N

        # Exact segment integrals of the Legendre basis, a[k, m] = int_seg_k P_m ds (Gauss, exact).
        xg, wg = legendre.leggauss(self.n_modes + 1)
        edges = np.linspace(0.0, L, N + 1)
        s = edges[:-1, None] + (xg[None] + 1) / 2 * self.ds  # (N, n_gauss)
        basis = legendre.legvander(2 * s / L - 1, order)  # (N, n_gauss, n_modes)
        self.segment_basis = np.einsum("kgm,g->km", basis, wg * self.ds / 2)  # (N, n_modes)

        # K = int Phi^T EI Phi ds = EI L / (2m + 1) per mode (Legendre orthogonality); D = (eta/E) K.
        modal = robot.bending_stiffness * L / (2 * np.arange(self.n_modes) + 1)
        self.stiffness = np.diag(np.concatenate([modal, modal]))  # (nq, nq)
        self.damping_matrix = (robot.damping / robot.youngs_modulus) * self.stiffness if damping else np.zeros_like(self.stiffness)
        # Cable map: constant body moment u_i r over the length -> r int P_m ds = r L delta_m0.
        self.cable_map = np.zeros((self.nq, 2))  # (nq, 2)
        self.cable_map[0, 0] = self.cable_map[self.n_modes, 1] = robot.cable_radius * L
        # Lumped masses at segment ends 1..N (trapezoid weights; node 0 is clamped).
        self.node_mass = np.full(N, robot.mass_per_length * self.ds)
        self.node_mass[-1] /= 2
        self._rest_q = None

    # ------------------------------------------------------------------ kinematics
    def _frames(self, q):
        """Segment rotations, chords and node positions for q (B, nq).

        Segment k turns by phi_k = int_seg k ds = (0, y_k, z_k); its chord is
        ds c(theta) R_k Exp(phi_k / 2) e1, exact for constant curvature."""
        y = -q[:, self.n_modes:] @ self.segment_basis.T  # (B, N)
        z = q[:, : self.n_modes] @ self.segment_basis.T
        theta = np.hypot(y, z)
        sinc, chord = _sinc(theta), _sinc(theta / 2)
        steps = _exp_bending(y, z, sinc, 0.5 * chord * chord)  # (B, N, 3, 3)
        R_start = np.empty_like(steps)
        R = np.broadcast_to(np.eye(3), (q.shape[0], 3, 3))
        for k in range(self.n_segments):  # g_{k+1} = g_k Exp(phi_k): the only sequential part
            R_start[:, k] = R
            R = R @ steps[:, k]
        half_turn = np.stack([np.cos(theta / 2), chord * z / 2, -chord * y / 2], -1)  # Exp(phi/2) e1
        direction = (R_start @ half_turn[..., None])[..., 0]
        chords = (self.ds * chord)[..., None] * direction
        return dict(y=y, z=z, theta=theta, chord=chord, R_start=R_start, direction=direction,
                    chords=chords, positions=np.cumsum(chords, axis=1))  # positions: (B, N, 3), nodes 1..N

    def _position_jacobians(self, f):
        """Jp_n = d p_n / d q at every node from the frames of _frames: (B, N, 3, nq).

        dtheta (spatial) accumulates R_k J_l(phi_k) dphi_k over the segments before n;
        a chord changes by dtheta_mid x chord plus the change of its length c(theta)."""
        y, z, theta, R = f["y"], f["z"], f["theta"], f["R_start"]
        alpha = 0.5 * f["chord"] ** 2
        beta, dchord = _cubic_ratios(theta)
        alpha_h, beta_h = 0.5 * _sinc(theta / 4) ** 2, _cubic_ratios(theta / 2)[0]
        full = R @ _left_jacobian_columns(y, z, alpha, beta)  # (B, N, 3, 2)
        half = 0.5 * (R @ _left_jacobian_columns(y / 2, z / 2, alpha_h, beta_h))
        a = self.segment_basis[:, None, None, :]  # (N, 1, 1, n_modes)
        increments = full[..., None] * a  # (B, N, 3, 2, n_modes)
        Jw_mid = np.cumsum(increments, axis=1) - (full - half)[..., None] * a
        # d theta = phi . dphi / theta and dphi = e3 d(kappa_1 int) - e2 d(kappa_2 int): phi . (e3, -e2) = (z, -y).
        length_change = (self.ds * dchord)[..., None] * f["direction"]  # (B, N, 3), times theta d theta
        angle_rate = np.stack([z, -y], -1)  # (B, N, 2)
        d_chords = _cross_columns(Jw_mid, f["chords"]) + (length_change[..., None] * angle_rate[:, :, None, :])[..., None] * a
        return np.cumsum(d_chords, axis=1).reshape(d_chords.shape[:3] + (self.nq,))

    def centerline(self, q):
        """Rod shape: node positions (B, N+1, 3) and rotations (B, N+1, 3, 3), base first."""
        q, _ = as_real_array(q, "q", (None, self.nq))
        f = self._frames(q)
        last = f["R_start"][:, -1] @ _exp_bending(f["y"][:, -1], f["z"][:, -1], _sinc(f["theta"][:, -1]),
                                                   0.5 * f["chord"][:, -1] ** 2)
        positions = np.concatenate([np.zeros((len(q), 1, 3)), f["positions"]], 1)
        return positions, np.concatenate([f["R_start"], last[:, None]], 1)

    def tip_positions(self, q):
        """Tip position for generalized coordinates q (B, nq) -> (B, 3)."""
        return self._frames(q)["positions"][:, -1]

    def _along(self, q, qd):
        """Node positions at q +- eps qd and eps (B, 1): central differences along qd."""
        eps = _CONVECTIVE_STEP / np.maximum(np.abs(qd).max(-1, keepdims=True), 1e-12)
        return self._frames(q + eps * qd)["positions"], self._frames(q - eps * qd)["positions"], eps

    def _convective_force(self, Jp, q, qd, positions):
        """c = sum_n m_n Jp_n^T (d Jp_n/dt) qd, the acceleration by a second central difference."""
        plus, minus, eps = self._along(q, qd)
        acceleration = (plus - 2 * positions + minus) / (eps**2)[..., None]
        weighted = (acceleration * self.node_mass[:, None]).reshape(len(q), 1, -1)  # (B, 1, 3N)
        return (weighted @ Jp.reshape(len(q), -1, self.nq))[:, 0]

    def _dynamics_terms(self, q):
        """Frames, Jp, M(q) and the gravity force G(q)."""
        f = self._frames(q)
        Jp = self._position_jacobians(f)  # (B, N, 3, nq)
        flat = (Jp * np.sqrt(self.node_mass)[None, :, None, None]).reshape(Jp.shape[0], -1, self.nq)
        M = flat.transpose(0, 2, 1) @ flat
        G = np.einsum("bnik,i,n->bk", Jp, self.g, self.node_mass)
        return f, Jp, M, G

    def mass_matrix(self, q):
        """M(q) for q (B, nq) -> (B, nq, nq)."""
        q, _ = as_real_array(q, "q", (None, self.nq))
        return self._dynamics_terms(q)[2]

    def tip_state(self, q, qd):
        """Tip position and velocity (B, 6); velocity by a central difference along qd."""
        plus, minus, eps = self._along(q, qd)
        return np.concatenate([self.tip_positions(q), (plus[:, -1] - minus[:, -1]) / (2 * eps)], -1)

    def energy(self, q, qd):
        """Kinetic + elastic + gravitational energy (J) of each rod, (B,)."""
        _, _, M, _ = self._dynamics_terms(q)
        kinetic = 0.5 * np.einsum("bi,bij,bj->b", qd, M, qd)
        elastic = 0.5 * np.einsum("bi,ij,bj->b", q, self.stiffness, q)
        gravity = -np.einsum("bni,i,n->b", self._frames(q)["positions"], self.g, self.node_mass)
        return kinetic + elastic + gravity

    # ------------------------------------------------------------------ statics
    def _gravity_force(self, q):
        return np.einsum("bnik,i,n->bk", self._position_jacobians(self._frames(q)), self.g, self.node_mass)

    def _tangent_stiffness(self, q, G):
        """K - dG/dq by forward differences (the gravity part only; K is exact)."""
        if self.gravity == "none":
            return np.broadcast_to(self.stiffness, (q.shape[0], self.nq, self.nq))
        step = 1e-6
        shifted = (q[:, None, :] + step * np.eye(self.nq)[None]).reshape(-1, self.nq)
        dG = (self._gravity_force(shifted).reshape(q.shape[0], self.nq, self.nq) - G[:, None, :]) / step
        return self.stiffness[None] - dG.transpose(0, 2, 1)

    def _equilibrium(self, u, q=None, tol=1e-12, max_iter=50):
        """Solve K q = B u + G(q) by Newton; returns q and the tangent stiffness there."""
        force = u @ self.cable_map.T  # (B, nq)
        if q is None:
            q = np.linalg.solve(self.stiffness, force.T).T
        for _ in range(max_iter):
            G = self._gravity_force(q)
            residual = self.stiffness @ q.T - (force + G).T
            Kt = self._tangent_stiffness(q, G)
            dq = np.linalg.solve(Kt, residual.T[..., None])[..., 0]
            q = q - dq
            if np.max(np.abs(dq)) < tol * max(1.0, np.max(np.abs(q))):
                return q, Kt
        raise RuntimeError(f"static equilibrium did not converge in {max_iter} Newton steps")

    def static_q(self, u):
        """Equilibrium generalized coordinates for actuation u (B, 2) -> (B, nq)."""
        u, _ = as_real_array(u, "u", (None, 2))
        return self._equilibrium(u)[0]

    def static_tip(self, u):
        """Equilibrium tip position for constant actuation u (B, 2) -> (B, 3)."""
        return self.tip_positions(self.static_q(u))

    def _fit_static(self, target, rows, u, tol=1e-10, max_iter=50, u_limit=np.inf):
        """Gauss-Newton on u so that the equilibrium tip matches ``target`` in coordinates
        ``rows``, through d p/d u = Jp_tip Kt^-1 B. Returns u, the tip and d p/d u (B, 3, 2).
        Stops with a RuntimeError as soon as an iterate needs |u| > u_limit."""
        q = None
        for _ in range(max_iter):
            if np.abs(u).max() > u_limit:
                raise RuntimeError(f"static fit needs |u| > {u_limit} N")
            q, Kt = self._equilibrium(u, q)
            f = self._frames(q)
            J_tip = self._position_jacobians(f)[:, -1]  # (B, 3, nq)
            dp_du = J_tip @ np.linalg.solve(Kt, np.broadcast_to(self.cable_map, Kt.shape[:1] + self.cable_map.shape))
            J = dp_du[:, rows]
            error = target[:, rows] - f["positions"][:, -1, rows]
            JT = J.transpose(0, 2, 1)
            du = np.linalg.solve(JT @ J, JT @ error[..., None])[..., 0]  # normal equations
            u = u + du
            if np.max(np.abs(du)) < tol:
                return u, f["positions"][:, -1], dp_du
        raise RuntimeError(f"static fit did not converge in {max_iter} Gauss-Newton steps")

    def inverse_static(self, p, tol=1e-10, max_iter=50):
        """Least-squares actuation whose equilibrium tip is closest to p (B, 3) -> (B, 2).

        Starts from the gravity-free arc through p (closed form) and refines with
        Gauss-Newton through the equilibrium.
        """
        p, _ = as_real_array(p, "p", (None, 3))
        r = self.robot
        lateral = np.hypot(p[:, 1], p[:, 2])
        bend = 2 * np.arctan2(lateral, p[:, 0])  # arc angle whose chord points at p
        heading = np.arctan2(p[:, 2], p[:, 1])
        magnitude = bend / r.length * r.bending_stiffness / r.cable_radius
        u = magnitude[:, None] * np.stack([np.cos(heading), np.sin(heading)], -1)
        return self._fit_static(p, [0, 1, 2], u, tol, max_iter)[0]

    def static_lift(self, yz, u_max: float = 4.0):
        """The equilibrium whose tip has lateral position yz (B, 2): tip p (B, 3),
        actuation u (B, 2) and d p / d(y, z) (B, 3, 2), for lifting y-z paths to 3D.

        Raises ValueError for a point outside the static workspace |u_i| <= u_max."""
        yz, _ = as_real_array(yz, "yz", (None, 2))
        r = self.robot
        u = 2 * yz / r.length**2 * r.bending_stiffness / r.cable_radius  # small-deflection guess
        try:
            u, tip, dp_du = self._fit_static(np.concatenate([np.zeros((len(yz), 1)), yz], 1), [1, 2], u,
                                             u_limit=2 * u_max)
        except (RuntimeError, np.linalg.LinAlgError) as error:
            raise ValueError("y-z path leaves the reachable static workspace (no equilibrium found)") from error
        worst = np.abs(u).max()
        if worst > u_max:
            raise ValueError(f"y-z path leaves the reachable static workspace: needs |u| = {worst:.2f} N > {u_max} N")
        return tip, u, dp_du @ np.linalg.inv(dp_du[:, 1:])

    # ------------------------------------------------------------------ dynamics
    def rest_q(self):
        """Gravity equilibrium with slack cables (straight rod when gravity is along it)."""
        if self._rest_q is None:
            self._rest_q = self._equilibrium(np.zeros((1, 2)))[0][0]
        return self._rest_q.copy()

    def _step(self, q, qd, force, h):
        """One linearly implicit trapezoidal step: K, D implicit; M, G at the explicit half
        step; the convective force predicted with qd, then corrected once with the mean
        velocity of the step (keeps it second order and the energy balance tight)."""
        q_half = q + 0.5 * h * qd
        f, Jp, M, G = self._dynamics_terms(q_half)
        K, D = self.stiffness, self.damping_matrix
        implicit = 0.5 * h * D + 0.25 * h * h * K
        lhs = M + implicit
        known = np.einsum("bij,bj->bi", M, qd) - qd @ implicit.T + h * (force + G - q @ K.T)
        qd_next = qd
        for _ in range(2):  # predictor, corrector
            c = self._convective_force(Jp, q_half, 0.5 * (qd + qd_next), f["positions"])
            qd_next = np.linalg.solve(lhs, (known - h * c)[..., None])[..., 0]
        return q + 0.5 * h * (qd + qd_next), qd_next

    def _advance(self, u, q, qd):
        """Sample-by-sample integration of one chunk; q, qd at the T+1 sample times."""
        B, T, _ = u.shape
        qs, qds = np.empty((B, T + 1, self.nq)), np.empty((B, T + 1, self.nq))
        qs[:, 0], qds[:, 0] = q, qd
        h = self.dt / self.substeps
        for t in range(T):
            force = u[:, t] @ self.cable_map.T
            for _ in range(self.substeps):
                q, qd = self._step(q, qd, force, h)
            qs[:, t + 1], qds[:, t + 1] = q, qd
        return qs, qds

    def _map_chunks(self, work, B, progress):
        """Run work(slice) over cache-sized chunks of the batch on a thread pool (numpy
        releases the GIL) and concatenate the results along the batch axis."""
        size = min(self.chunk_size, -(-B // self.threads))  # every thread gets work
        chunks = [slice(i, min(i + size, B)) for i in range(0, B, size)]
        with ThreadPoolExecutor(self.threads) as pool, tqdm(total=B, disable=not progress, desc="simulating",
                                                               unit="episode") as bar:
            results = []
            for chunk, result in zip(chunks, pool.map(work, chunks)):
                results.append(result)
                bar.update(chunk.stop - chunk.start)
        return [np.concatenate(parts) for parts in zip(*results)]

    def integrate(self, u, q0, qd0, *, progress: bool = False):
        """Advance every rod through u (B, T, 2) from (q0, qd0) (B, nq); zero-order hold.

        Returns q and qd at the T+1 sample times, each (B, T+1, nq).
        """
        u, _ = as_real_array(u, "u", (None, None, 2))
        B = u.shape[0]
        q0, _ = as_real_array(np.broadcast_to(q0, (B, self.nq)), "q0", (B, self.nq))
        qd0, _ = as_real_array(np.broadcast_to(qd0, (B, self.nq)), "qd0", (B, self.nq))
        return self._map_chunks(lambda c: self._advance(u[c], q0[c], qd0[c]), B, progress)

    def rollout(self, u, *, progress: bool = False):
        """Tip states (B, T+1, 6) = [p, v] for actuation u (B, T, 2) from rest."""
        u, _ = as_real_array(u, "u", (None, None, 2))
        B = u.shape[0]
        q0, qd0 = np.broadcast_to(self.rest_q(), (B, self.nq)), np.zeros((B, self.nq))

        def work(c):
            qs, qds = self._advance(u[c], q0[c], qd0[c])
            return (np.stack([self.tip_state(qs[:, t], qds[:, t]) for t in range(qs.shape[1])], 1),)

        return self._map_chunks(work, B, progress)[0]

    def bend_angles(self, q):
        """Total bend angle of each curvature, int kappa_i ds (B, 2): what the cables feel."""
        q, _ = as_real_array(q, "q", (None, self.nq))
        return q[:, [0, self.n_modes]] * self.robot.length
