"""Kinematics of the GVS rod: strain basis, segment frames and position Jacobians.

Pure geometry of the generalized coordinates q (no mass, no force). Equation numbers
(K1)-(K5) refer to docs/simulator.md.

Strain (K1): the rod is inextensible, unshearable and torsion-free; its two bending
curvatures are Legendre series in the arc length,

    kappa_i(s) = sum_m q[i, m] P_m(2 s / L - 1),   i = 1 (towards +y), 2 (towards +z),

so the body curvature vector is k = (0, -kappa_2, kappa_1) and q has 2 (order + 1)
entries. A rod made of several segments (K5) has one such series per segment, in the
segment's own arc length, so the strain may jump where segments meet. The pose g(s)
integrates g' = g xi^ along s on spatial segments (K2): each turns by the exact integral
of k over it (first Magnus term), and its chord is the exact one for constant curvature,
so a uniform bend is exact at any resolution.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

_SERIES_BELOW = 1e-2  # rad; below this angle (t - sin t)/t^3 and c'(t)/t use their Taylor series


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


def _exp_bending(phi_y, phi_z, sinc, alpha):
    """Exp of the rotation vector (0, phi_y, phi_z) (Rodrigues, written out: no torsion)."""
    E = np.empty(phi_y.shape + (3, 3))
    E[..., 0, 0] = 1 - alpha * (phi_y * phi_y + phi_z * phi_z)
    E[..., 0, 1], E[..., 0, 2] = -sinc * phi_z, sinc * phi_y
    E[..., 1, 0], E[..., 1, 1], E[..., 1, 2] = sinc * phi_z, 1 - alpha * phi_z * phi_z, alpha * phi_y * phi_z
    E[..., 2, 0], E[..., 2, 1], E[..., 2, 2] = -sinc * phi_y, alpha * phi_y * phi_z, 1 - alpha * phi_y * phi_y
    return E


def _left_jacobian_columns(phi_y, phi_z, alpha, beta):
    """J_l(phi) e3 and J_l(phi) (-e2) for phi = (0, phi_y, phi_z), stacked on the last axis:
    (..., 3, 2). J_l(phi) = I + alpha phi^ + beta phi^2 (K3) maps a change of a segment's
    rotation vector to the change of its rotation in the spatial frame."""
    out = np.empty(phi_y.shape + (3, 2))
    out[..., 0, 0], out[..., 1, 0], out[..., 2, 0] = alpha * phi_y, beta * phi_y * phi_z, 1 - beta * phi_y * phi_y
    out[..., 0, 1], out[..., 1, 1], out[..., 2, 1] = alpha * phi_z, beta * phi_z * phi_z - 1, -beta * phi_y * phi_z
    return out


def _cross_columns(a, b):
    """a x b along axis 2, for a (B, N, 3, ...) and b (B, N, 3) broadcast over the trailing axes."""
    b = b.reshape(b.shape + (1,) * (a.ndim - 3))
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, :, 0] = a[:, :, 1] * b[:, :, 2] - a[:, :, 2] * b[:, :, 1]
    out[:, :, 1] = a[:, :, 2] * b[:, :, 0] - a[:, :, 0] * b[:, :, 2]
    out[:, :, 2] = a[:, :, 0] * b[:, :, 1] - a[:, :, 1] * b[:, :, 0]
    return out


def rowwise(x, W):
    """x @ W for x (B, k), one row at a time: the same bits for a row whatever the batch.
    (BLAS blocks a batched product differently for another batch size, and the convective
    term's second difference amplifies such last-bit differences about 1e7-fold.)"""
    return (x[:, None, :] @ W)[:, 0]


class RodKinematics:
    """Frames, node positions and their Jacobians for a rod of segments ``segment_lengths``
    whose curvatures are Legendre series of degree ``order`` in each segment (K5), integrated
    on ``n_segments`` spatial segments shared among the rod's segments by length (at least
    one each)."""

    def __init__(self, segment_lengths: tuple[float, ...], order: int, n_segments: int):
        self.length, self.order = sum(segment_lengths), order
        counts = [max(1, round(n_segments * part / self.length)) for part in segment_lengths]
        self.n_segments = sum(counts)
        self.modes_per_segment = order + 1
        self.n_modes = len(segment_lengths) * self.modes_per_segment  # per curvature
        self.nq = 2 * self.n_modes
        self.ds = np.concatenate([np.full(n, part / n) for part, n in zip(segment_lengths, counts)])  # (N,)
        self.segment_ends = np.cumsum(counts) - 1  # node index of each rod segment's end (the disks, the tip last)
        # Exact integrals of the basis over the spatial segments, a[k, j (order + 1) + m] = int_seg_k P_m ds
        # for k in rod segment j, 0 elsewhere (K5; Gauss, exact for polynomials).
        xg, wg = legendre.leggauss(self.modes_per_segment + 1)
        # Column-major, as einsum returns it: rowwise(q, segment_basis.T) then multiplies by a row-major
        # matrix, and a one-segment rod keeps the bits it had with a single einsum.
        self.segment_basis = np.zeros((self.n_segments, self.n_modes), order="F")  # (N, n_modes)
        rows = np.concatenate([[0], np.cumsum(counts)])
        for j, (part, n) in enumerate(zip(segment_lengths, counts)):
            ds = part / n
            edges = np.linspace(0.0, part, n + 1)
            s = edges[:-1, None] + (xg[None] + 1) / 2 * ds  # (n, n_gauss), from the segment's start
            basis = legendre.legvander(2 * s / part - 1, order)  # (n, n_gauss, order + 1)
            columns = slice(j * self.modes_per_segment, (j + 1) * self.modes_per_segment)
            self.segment_basis[rows[j] : rows[j + 1], columns] = np.einsum("kgm,g->km", basis, wg * ds / 2)

    def frames(self, q) -> dict:
        """Segment rotations, chords and node positions for q (B, nq) (K2).

        Segment k turns by phi_k = int_seg k ds = (0, phi_y, phi_z); its chord is
        ds c(theta) R_k Exp(phi_k / 2) e1, exact for constant curvature."""
        phi_y = -rowwise(q[:, self.n_modes :], self.segment_basis.T)  # (B, N)
        phi_z = rowwise(q[:, : self.n_modes], self.segment_basis.T)
        theta = np.hypot(phi_y, phi_z)
        sinc, chord = _sinc(theta), _sinc(theta / 2)
        steps = _exp_bending(phi_y, phi_z, sinc, 0.5 * chord * chord)  # (B, N, 3, 3)
        R_start = np.empty_like(steps)
        R = np.broadcast_to(np.eye(3), (q.shape[0], 3, 3))
        for k in range(self.n_segments):  # g_{k+1} = g_k Exp(phi_k): the only sequential part
            R_start[:, k] = R
            R = R @ steps[:, k]
        half_turn = np.stack([np.cos(theta / 2), chord * phi_z / 2, -chord * phi_y / 2], -1)  # Exp(phi/2) e1
        direction = (R_start @ half_turn[..., None])[..., 0]
        chords = (self.ds * chord)[..., None] * direction
        return dict(
            phi_y=phi_y,
            phi_z=phi_z,
            theta=theta,
            chord=chord,
            R_start=R_start,
            direction=direction,
            chords=chords,
            positions=np.cumsum(chords, axis=1),
        )  # positions: (B, N, 3), nodes 1..N

    def position_jacobians(self, f: dict):
        """Jp_n = d p_n / d q at every node from ``frames(q)``: (B, N, 3, nq) (K3).

        d theta (spatial) accumulates R_k J_l(phi_k) d phi_k over the segments before n;
        a chord changes by d theta_mid x chord plus the change of its length c(theta)."""
        phi_y, phi_z, theta, R = f["phi_y"], f["phi_z"], f["theta"], f["R_start"]
        alpha = 0.5 * f["chord"] ** 2
        beta, dchord = _cubic_ratios(theta)
        alpha_h, beta_h = 0.5 * _sinc(theta / 4) ** 2, _cubic_ratios(theta / 2)[0]
        full = R @ _left_jacobian_columns(phi_y, phi_z, alpha, beta)  # (B, N, 3, 2)
        half = 0.5 * (R @ _left_jacobian_columns(phi_y / 2, phi_z / 2, alpha_h, beta_h))
        a = self.segment_basis[:, None, None, :]  # (N, 1, 1, n_modes)
        increments = full[..., None] * a  # (B, N, 3, 2, n_modes)
        Jw_mid = np.cumsum(increments, axis=1) - (full - half)[..., None] * a
        # d theta = phi . d phi / theta, d phi = e3 d(kappa_1 int) - e2 d(kappa_2 int):
        # phi . (e3, -e2) = (phi_z, -phi_y).
        length_change = (self.ds * dchord)[..., None] * f["direction"]  # (B, N, 3), times theta d theta
        angle_rate = np.stack([phi_z, -phi_y], -1)  # (B, N, 2)
        d_chords = (
            _cross_columns(Jw_mid, f["chords"]) + (length_change[..., None] * angle_rate[:, :, None, :])[..., None] * a
        )
        return np.cumsum(d_chords, axis=1).reshape(d_chords.shape[:3] + (self.nq,))

    def tip_positions(self, q):
        """Tip position for q (B, nq) -> (B, 3)."""
        return self.frames(q)["positions"][:, -1]

    def disk_positions(self, q):
        """Position of each rod segment's end, base outwards (the tip last), for q (B, nq) -> (B, S, 3)."""
        return self.frames(q)["positions"][:, self.segment_ends]

    def centerline(self, q):
        """Node positions (B, N+1, 3) and rotations (B, N+1, 3, 3), base first."""
        f = self.frames(q)
        last = f["R_start"][:, -1] @ _exp_bending(
            f["phi_y"][:, -1], f["phi_z"][:, -1], _sinc(f["theta"][:, -1]), 0.5 * f["chord"][:, -1] ** 2
        )
        positions = np.concatenate([np.zeros((len(q), 1, 3)), f["positions"]], 1)
        return positions, np.concatenate([f["R_start"], last[:, None]], 1)

    def positions_along(self, q, qd, step: float):
        """Node positions at q + eps qd and q - eps qd, and eps (B, 1) = step / max|qd|: the
        central differences of the exact kinematics that give velocities and the convective
        term (K4). Truncation error ~ eps^2 |d^3 p / d eps^3|, round-off ~ 1e-16 |p| / eps."""
        _, plus, minus, eps = self.frames_along(q, qd, step, at_q=False)
        return plus, minus, eps

    def frames_along(self, q, qd, step: float, *, at_q: bool = True):
        """``frames(q)`` (None without ``at_q``) and ``positions_along(q, qd, step)`` from one
        stacked call: the sequential product over segments costs per call, not per row, and
        every row is computed alone (``rowwise``), so the bits are those of separate calls."""
        B = len(q)
        eps = step / np.maximum(np.abs(qd).max(-1, keepdims=True), 1e-12)
        f = self.frames(np.concatenate([q, q + eps * qd, q - eps * qd] if at_q else [q + eps * qd, q - eps * qd]))
        positions = f["positions"][B:] if at_q else f["positions"]  # (2B, N, 3): plus, then minus
        here = {name: value[:B] for name, value in f.items()} if at_q else None
        return here, positions[:B], positions[B:], eps
