"""Statics of the GVS rod: equilibria, inverse statics, lifting y-z paths to 3D, and a
tabulated inverse for millions of points (the prior of RF-Physical).

Every function takes a ``Simulator`` (its stiffness K, cable map B, gravity and
kinematics); equation numbers (S1)-(S4) refer to docs/simulator.md. A rod with more
inputs than the fitted tip coordinates (``TWO_SEGMENT_ROD``: four for a 3-D point) reaches
a point with many u; the inverse then returns the least-norm one (S4). The y-z lift and
the table assume two inputs and refuse other rods.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.optimize import least_squares
from tqdm import tqdm

from softflow.checks import as_real_array
from softflow.rod.robots import U_MAX, Robot
from softflow.store import DATA_DIR, cached_arrays

STATICS_VERSION = 1  # bump when a number the table or the solvers produce changes
# inverse_static refuses a point farther than this fraction of the rod's length from every
# equilibrium tip: wrong units or frame, not the few centimetres a moving rod's tip is off
# the static surface (RF-Physical's prior is the inverse statics of such points).
MAX_RESIDUAL = 0.25
# The least-norm inverse (S4). Its null-space step is known to about 1e-10 |u|: the tangent
# stiffness's forward difference of gravity (step 1e-6) leaves round-off of that size in J.
NULL_RTOL = 1e-8  # converged when the null-space step is below this fraction of |u|
_CURVATURE_STEP = 1e-3  # N, forward difference of J along the null space (relative error ~1e-4)
_HESSIAN_FLOOR = 0.1  # reduced Hessian eigenvalues floored here: a concave stretch still steps downhill in |u|
_RANK_RTOL = 1e-9  # singular values of d p/d u below this fraction of the largest count as zero
CONTINUATION_STEPS = (8, 32)  # gravity raised in this many equal steps where plain Newton wanders


def gravity_force(sim, q):
    """G(q) = sum_n m_n Jp_n^T g, the generalized gravity force (S1)."""
    return np.einsum("bnik,i,n->bk", sim.kinematics.position_jacobians(sim.kinematics.frames(q)), sim.g, sim.node_mass)


def tangent_stiffness(sim, q, G):
    """K - dG/dq, the gravity part by forward differences (K is exact)."""
    if sim.gravity == "none":
        return np.broadcast_to(sim.stiffness, (q.shape[0], sim.nq, sim.nq))
    step = 1e-6
    shifted = (q[:, None, :] + step * np.eye(sim.nq)[None]).reshape(-1, sim.nq)
    dG = (gravity_force(sim, shifted).reshape(q.shape[0], sim.nq, sim.nq) - G[:, None, :]) / step
    return sim.stiffness[None] - dG.transpose(0, 2, 1)


def equilibrium(sim, u, q=None, tol=1e-12, max_iter=50):
    """Solve K q = B u + G(q) (S1) by Newton; returns q and the tangent stiffness there. Where
    Newton from the start wanders (a rod so soft that gravity folds it: which CPU's last bits it
    converges on is chance), gravity is raised from zero in steps instead, each Newton starting
    at the equilibrium before (continuation). Raises RuntimeError when neither converges."""
    force = u @ sim.cable_map.T  # (B, nq)
    if q is None:
        q = np.linalg.solve(sim.stiffness, force.T).T
    solved = _newton(sim, force, q, 1.0, tol, max_iter)
    for steps in CONTINUATION_STEPS if solved is None and sim.gravity != "none" else ():
        solved = np.linalg.solve(sim.stiffness, force.T).T, None
        for scale in np.arange(1, steps + 1) / steps:
            solved = _newton(sim, force, solved[0], float(scale), tol, max_iter)
            if solved is None:
                break
        if solved is not None:
            break
    if solved is None:
        raise RuntimeError(f"static equilibrium did not converge in {max_iter} Newton steps")
    return solved


def _newton(sim, force, q, scale: float, tol: float, max_iter: int):
    """Newton on K q = B u + scale G(q) from q: (q, tangent stiffness), or None."""
    for _ in range(max_iter):
        G = gravity_force(sim, q)
        Kt = tangent_stiffness(sim, q, G)
        if scale != 1.0:  # K - scale dG/dq
            G, Kt = scale * G, (1.0 - scale) * sim.stiffness + scale * Kt
        residual = sim.stiffness @ q.T - (force + G).T
        dq = np.linalg.solve(Kt, residual.T[..., None])[..., 0]
        q = q - dq
        if np.max(np.abs(dq)) < tol * max(1.0, np.max(np.abs(q))):
            return q, Kt
    return None


def arc_actuation(robot: Robot, p):
    """Actuation (B, m) of the gravity-free circular arc whose tip chord points at p (B, 3):
    a uniform bend by 2 atan2(lateral, x) (S2) by the outermost cables (those that run to
    the tip), the others slack; the closed-form start of inverse statics."""
    lateral = np.hypot(p[:, 1], p[:, 2])
    bend = 2 * np.arctan2(lateral, p[:, 0])
    heading = np.arctan2(p[:, 2], p[:, 1])
    magnitude = bend / robot.length * robot.bending_stiffness / robot.cable_radius
    arc = magnitude[:, None] * np.stack([np.cos(heading), np.sin(heading)], -1)  # (B, 2)
    return np.concatenate([np.zeros((len(p), robot.n_inputs - 2)), arc], -1)


def disk_jacobians(sim, q, Kt):
    """Every disk's position (B, S, 3), base outwards with the tip last, and d position / d u =
    Jp Kt^-1 B (B, S, 3, m) at the equilibrium q with tangent stiffness Kt (S3)."""
    frames, ends = sim.kinematics.frames(q), sim.kinematics.segment_ends
    Jp = sim.kinematics.position_jacobians(frames)[:, ends]  # (B, S, 3, nq)
    dq_du = np.linalg.solve(Kt, np.broadcast_to(sim.cable_map, Kt.shape[:1] + sim.cable_map.shape))  # (B, nq, m)
    return frames["positions"][:, ends], Jp @ dq_du[:, None]


def _tip_jacobian(sim, q, Kt):
    """Tip (B, 3) and d p / d u (B, 3, m) at the equilibrium q (``disk_jacobians``' last disk)."""
    positions, jacobians = disk_jacobians(sim, q, Kt)
    return positions[:, -1], jacobians[:, -1]


def _least_norm_step(sim, J, error, u, q, rows):
    """Step (B, m) towards the least-norm u that fits, and its null-space part (S4).

    The fit J^+ e moves the tip onto the target; along the null space N of J, a Newton
    step on |u|^2 / 2 restricted to the solutions: N H^-1 N^T u with the reduced Hessian
    H = I - sum_i lambda_i N^T d2 p_i N (multipliers lambda = J^+T u; the curvature d2 p N
    by a forward difference of J, eigenvalues floored at _HESSIAN_FLOOR). The whole step
    is capped at u_bound / 4."""
    U, S, Vh = np.linalg.svd(J)  # (B, r, r), (B, r), (B, m, m)
    r = J.shape[1]
    # A straight rod's tip does not move along its axis to first order: drop such directions.
    inverse_S = np.divide(1.0, S, out=np.zeros_like(S), where=S > _RANK_RTOL * S[:, :1])  # (B, r)
    pinv = Vh[:, :r].transpose(0, 2, 1) * inverse_S[:, None, :] @ U.transpose(0, 2, 1)  # (B, m, r)
    N = Vh[:, r:].transpose(0, 2, 1)  # (B, m, k), orthonormal
    multipliers = (pinv.transpose(0, 2, 1) @ u[..., None])[..., 0]  # (B, r)
    curvature = []  # d2 p / du2 [N_a, N_b]: (k) x (B, r, k)
    for a in range(N.shape[2]):
        shifted = u + _CURVATURE_STEP * N[:, :, a]
        _, J_shifted = _tip_jacobian(sim, *equilibrium(sim, shifted, q))
        curvature.append((J_shifted[:, rows] - J) @ N / _CURVATURE_STEP)
    H = np.eye(N.shape[2]) - np.einsum("br,abrc->bac", multipliers, np.stack(curvature))  # (B, k, k)
    values, vectors = np.linalg.eigh(0.5 * (H + H.transpose(0, 2, 1)))
    H = vectors * np.maximum(values, _HESSIAN_FLOOR)[:, None, :] @ vectors.transpose(0, 2, 1)
    null = -(N @ np.linalg.solve(H, N.transpose(0, 2, 1) @ u[..., None]))[..., 0]
    step = (pinv @ error[..., None])[..., 0] + null
    return _capped(step, sim.u_bound / 4), null


def least_norm_rates(sim, u, rows):
    """Disk positions (B, S, 3) and their rates d position / d target (B, S, 3, r) at u (B, m), the
    least-norm solution of p_rows(u) = target (``fit_static``'s answer).

    Along the solutions u*(t), J du = dt, and the gradient of |u|^2 / 2 stays normal to the set
    that reaches t: N^T H du = 0, with N the null space of J = d p_rows / d u, H = I - sum_i
    lambda_i d2 p_i the Hessian of the Lagrangian and lambda = J^+T u its multipliers (as in
    ``_least_norm_step``). So du/dt = (I - N (N^T H N)^-1 N^T H) J^+, where N^T H needs only
    d2 p_i N: a forward difference of J along each null direction."""
    q, Kt = equilibrium(sim, u)
    positions, jacobians = disk_jacobians(sim, q, Kt)
    J = jacobians[:, -1, rows]  # (B, r, m)
    pinv = np.linalg.pinv(J)  # (B, m, r)
    null = np.linalg.svd(J)[2][:, len(rows) :].transpose(0, 2, 1)  # (B, m, k), orthonormal; k = 0 if m <= r
    du_dt = pinv
    if null.shape[2]:
        multipliers = (pinv.transpose(0, 2, 1) @ u[..., None])[..., 0]  # (B, r)
        projected = null.transpose(0, 2, 1).copy()  # N^T H, (B, k, m)
        for a in range(null.shape[2]):
            shifted = _tip_jacobian(sim, *equilibrium(sim, u + _CURVATURE_STEP * null[:, :, a], q))[1][:, rows]
            projected[:, a] -= np.einsum("kr,krm->km", multipliers, (shifted - J) / _CURVATURE_STEP)
        du_dt = pinv - null @ np.linalg.solve(projected @ null, projected @ pinv)
    return positions, jacobians @ du_dt[:, None]


def _capped(v, cap: float):
    """Each row of v (B, m) scaled down to norm ``cap`` where it is longer."""
    return v * np.minimum(1.0, cap / np.maximum(np.linalg.norm(v, axis=-1), 1e-300))[:, None]


def fit_static(sim, target, rows, u, tol=1e-10, max_iter=50, u_limit=np.inf):
    """Gauss-Newton on u so that the equilibrium tip matches ``target`` in coordinates
    ``rows``, through d p/d u = Jp_tip Kt^-1 B (S3). With more inputs than rows, the
    least-norm u that fits (S4): converged when the fitting step is below ``tol`` and the
    null-space step below NULL_RTOL |u|. Returns u, the tip and d p/d u (B, 3, m). Raises
    RuntimeError when it does not converge or an iterate needs |u| > u_limit."""
    q = None
    for _ in range(max_iter):
        if np.abs(u).max() > u_limit:
            raise RuntimeError(f"static fit needs |u| > {u_limit} N")
        q, Kt = equilibrium(sim, u, q)
        tip, dp_du = _tip_jacobian(sim, q, Kt)
        J = dp_du[:, rows]
        error = target[:, rows] - tip[:, rows]
        if J.shape[2] > J.shape[1]:
            du, null = _least_norm_step(sim, J, error, u, q, rows)
            converged = np.abs(du - null).max() < tol and np.abs(null).max() < NULL_RTOL * max(1.0, np.abs(u).max())
        else:
            JT = J.transpose(0, 2, 1)
            du = np.linalg.solve(JT @ J, JT @ error[..., None])[..., 0]  # normal equations
            converged = np.max(np.abs(du)) < tol
        u = u + du
        if converged:
            return u, tip, dp_du
    raise RuntimeError(f"static fit did not converge in {max_iter} Gauss-Newton steps")


def fit_holding(sim, p, index, value, u=None, tol=1e-10, max_iter=50, u_limit=np.inf):
    """The actuation (B, m) with input ``index`` held at ``value`` (a number or (B,)) whose
    equilibrium tip is p (B, 3): another point than the least-norm one (S4) of the curve of u
    that reaches p on a rod with more inputs than three, which shows the redundancy. Gauss-Newton
    on the other inputs through d p/d u (S3), from ``u`` (B, m) (default: the tip cables' arc
    through p, S2) with the held input set; each step the least-squares one (least-norm if more
    than three inputs are free; directions the tip cannot move along dropped as in S4), capped at
    u_bound / 4. Returns u and its tip (B, 3). Raises RuntimeError when it does not converge
    within ``tol`` (N) or an iterate needs |u| > u_limit."""
    free = np.delete(np.arange(sim.n_inputs), index)
    u = arc_actuation(sim.robot, p) if u is None else np.array(u, dtype=float)  # (B, m), a copy
    u[:, index] = value
    q = None
    for _ in range(max_iter):
        if np.abs(u).max() > u_limit:
            raise RuntimeError(f"fit with u[{index}] held needs |u| > {u_limit} N")
        q, Kt = equilibrium(sim, u, q)
        tip, dp_du = _tip_jacobian(sim, q, Kt)
        J = dp_du[:, :, free]  # (B, 3, m - 1)
        step = _capped(
            (np.linalg.pinv(J, rtol=_RANK_RTOL) @ (p - tip)[..., None])[..., 0], sim.u_bound / 4
        )  # (B, m - 1)
        u[:, free] += step
        if np.abs(step).max() < tol:
            return u, static_tip(sim, u)
    raise RuntimeError(f"fit with u[{index}] held did not converge in {max_iter} Gauss-Newton steps")


def static_tip(sim, u):
    """Equilibrium tip position for constant actuation u (B, m) -> (B, 3)."""
    return sim.kinematics.tip_positions(equilibrium(sim, u)[0])


def inverse_static(sim, p, tol=1e-10, max_iter=50, max_residual=None):
    """Least-squares actuation whose equilibrium tip is closest to p (B, 3) -> (B, m).

    Gauss-Newton from the gravity-free arc through p (S2, S3); where several u reach p
    (more than three inputs), the least-norm one near that start (S4). A point whose best
    fit is farther than ``max_residual`` (m; default MAX_RESIDUAL x the rod's length) from
    p, or that turns the rod beyond a full circle, is outside the static workspace:
    ValueError with the residual of the nearest equilibrium found."""
    if max_residual is None:
        max_residual = MAX_RESIDUAL * sim.robot.length
    u0 = arc_actuation(sim.robot, p)
    u0 = _capped(u0, sim.u_bound)
    try:
        u, residual = _fit_points(sim, p, u0, tol, max_iter)
    except (RuntimeError, np.linalg.LinAlgError):  # some point has no fit: find out which, one at a time
        u, residual = map(
            np.concatenate,
            zip(*(_fit_points(sim, p[i : i + 1], u0[i : i + 1], tol, max_iter, fallback=True) for i in range(len(p)))),
        )
    outside = np.flatnonzero(~(residual <= max_residual) | (sim.free_turning(u) > 2 * np.pi))
    if len(outside):
        i = outside[0]
        nearest = _nearest_equilibrium(sim, p[i], u0[i])
        if nearest <= max_residual:  # only a rod fitted exactly (more inputs than three) gets here
            raise ValueError(
                f"p[{i}] = {np.round(p[i], 4).tolist()} m has no equilibrium that reaches it exactly "
                f"(the nearest found is {1e3 * nearest:.3f} mm away): a rod with {sim.n_inputs} inputs "
                "is fitted exactly, so p must lie inside its static workspace"
            )
        raise ValueError(
            f"p[{i}] = {np.round(p[i], 4).tolist()} m is outside the static workspace: the nearest "
            f"equilibrium found (|u| <= {sim.u_bound:.1f} N) is {1e3 * nearest:.1f} mm away, more than "
            f"max_residual = {1e3 * max_residual:.1f} mm (is p in metres, robot frame?)"
        )
    return u


def _fit_points(sim, p, u0, tol, max_iter, fallback=False):
    """Gauss-Newton fit of every point and its residual (m); with ``fallback`` a point that
    has no fit gets its start u0 and an infinite residual instead of an exception."""
    try:
        u, tip, _ = fit_static(sim, p, [0, 1, 2], u0, tol, max_iter, u_limit=sim.u_bound)
    except (RuntimeError, np.linalg.LinAlgError):
        if not fallback:
            raise
        return u0, np.full(len(p), np.inf)
    return u, np.linalg.norm(tip - p, axis=-1)


def _nearest_equilibrium(sim, p, u0) -> float:
    """Distance (m) from p to the closest equilibrium tip a bounded local search finds from u0."""
    bound = sim.u_bound / np.sqrt(sim.n_inputs)  # the box inside the ball |u| <= u_bound
    fit = least_squares(lambda u: static_tip(sim, u[None])[0] - p, np.clip(u0, -bound, bound), bounds=(-bound, bound))
    return float(np.linalg.norm(fit.fun))


def static_lift(sim, yz, u_max: float = U_MAX):
    """The equilibrium whose tip has lateral position yz (B, 2): tip p (B, 3), actuation
    u (B, 2) and d p / d(y, z) (B, 3, 2), for lifting y-z paths to 3D.

    Raises ValueError for a point outside the static workspace |u_i| <= u_max, or for a rod
    with other than two inputs (whose tip reaches a y-z point at many heights)."""
    _two_inputs(sim, "static_lift")
    r = sim.robot
    u = 2 * yz / r.length**2 * r.bending_stiffness / r.cable_radius  # small-deflection guess
    try:
        u, tip, dp_du = fit_static(sim, np.concatenate([np.zeros((len(yz), 1)), yz], 1), [1, 2], u, u_limit=2 * u_max)
    except (RuntimeError, np.linalg.LinAlgError) as error:
        raise ValueError("y-z path leaves the reachable static workspace (no equilibrium found)") from error
    worst = np.abs(u).max()
    if worst > u_max:
        raise ValueError(f"y-z path leaves the reachable static workspace: needs |u| = {worst:.2f} N > {u_max} N")
    return tip, u, dp_du @ np.linalg.inv(dp_du[:, 1:])


def _two_inputs(sim, name):
    """ValueError unless the rod has two inputs: a (u1, u2) grid and a y-z point each fix one equilibrium."""
    if sim.n_inputs != 2:
        raise ValueError(
            f"{name} needs a rod with 2 inputs; {sim.robot.name!r} has {sim.n_inputs} "
            "(use inverse_static, the least-norm inverse, for it)"
        )


def table_spec(sim, u_range: float, step: float) -> dict:
    """What a static table is keyed by: the simulator's numbers, its range and step (N) and
    STATICS_VERSION."""
    return dict(simulator=sim.spec(), u_range=u_range, step=step, version=STATICS_VERSION)


class StaticTable:
    """Equilibrium tip p(u) on [-u_range, u_range]^2, sampled every ``step`` N, as bicubic
    splines: inverse statics on millions of points in seconds instead of hours."""

    def __init__(self, sim, u_range: float = 6.0, step: float = 0.2, progress: bool = False):
        _two_inputs(sim, "StaticTable")
        self.robot, self.u_range = sim.robot, u_range
        grid = np.linspace(-u_range, u_range, int(round(2 * u_range / step)) + 1)
        self.spec = table_spec(sim, u_range, step)

        def compute():
            u = np.stack(np.meshgrid(grid, grid, indexing="ij"), -1).reshape(-1, 2)
            chunks = [
                static_tip(sim, u[i : i + 256])
                for i in tqdm(range(0, len(u), 256), disable=not progress, desc="static table")
            ]
            return dict(tips=np.concatenate(chunks).reshape(len(grid), len(grid), 3))

        tips = cached_arrays(
            DATA_DIR,
            "static-table",
            self.spec,
            compute,
            valid=lambda a: a.get("tips") is not None and a["tips"].shape == (len(grid), len(grid), 3),
        )["tips"]
        self.splines = [RectBivariateSpline(grid, grid, tips[..., i], kx=3, ky=3) for i in range(3)]

    def tip(self, u):
        """Tip (B, 3) and its Jacobian d p / d u (B, 3, 2) from the splines."""
        u1, u2 = u[:, 0], u[:, 1]
        p = np.stack([s.ev(u1, u2) for s in self.splines], -1)
        J = np.stack([np.stack([s.ev(u1, u2, dx=1), s.ev(u1, u2, dy=1)], -1) for s in self.splines], 1)
        return p, J

    def inverse(self, p, iterations: int = 12) -> np.ndarray:
        """Least-squares actuation for tip positions p (..., 3) -> (..., 2), clipped to the table.

        Same answer as ``inverse_static`` inside the table (to the spline accuracy), for
        any number of points at once."""
        batch_shape = np.shape(p)[:-1]
        if np.shape(p)[-1:] != (3,):
            raise ValueError(f"p must have shape (..., 3); got {np.shape(p)}")
        p, _ = as_real_array(np.reshape(p, (-1, 3)), "p", (None, 3))
        u = np.clip(arc_actuation(self.robot, p), -self.u_range, self.u_range)
        for _ in range(iterations):
            tip, J = self.tip(u)
            JT = J.transpose(0, 2, 1)
            du = np.linalg.solve(JT @ J + 1e-12 * np.eye(2), JT @ (p - tip)[..., None])[..., 0]
            u = np.clip(u + du, -self.u_range, self.u_range)
        return u.reshape(batch_shape + (2,))


class InverseGrid:
    """``StaticTable.inverse`` tabulated once more, for RF-Physical's real-time step: its nodes
    in coordinates where the inverse is smooth, the gravity-free arc's actuation of the tip's
    chord (``arc_actuation``, closed form; (B, 2), N) and the chord's length |p|, and the cells
    with a node at the table's edge +-u_range (``kink``: a kink no interpolant follows). The
    step interpolates it (``control.step.GridPrior``), within 1e-3 N of the table on the paper
    rod's states (tests/test_statics_grid.py; the table is within ~1e-6 N of ``inverse_static``).

    Built from the table in seconds, once per rod, and cached by content."""

    def __init__(self, table: StaticTable, arcs: int = 97, lengths: int = 17):
        self.table, self.robot = table, table.robot
        L, R = table.robot.length, table.u_range
        self.low, self.high = np.array([-R, -R, 0.5 * L]), np.array([R, R, 1.001 * L])
        self.shape = np.array([arcs, arcs, lengths])
        self.spacing = (self.high - self.low) / (self.shape - 1)
        spec = dict(table=table.spec, arcs=arcs, lengths=lengths, version=STATICS_VERSION)

        def compute():
            axes = [np.linspace(a, b, n) for a, b, n in zip(self.low, self.high, self.shape)]
            nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)  # (N, 3) coordinates
            u = table.inverse(_chord_point(table.robot, nodes))  # (N, 2)
            edge = (np.abs(u) >= table.u_range - 1e-9).any(-1).reshape(*self.shape)  # clipped nodes
            kink = np.zeros(self.shape - 1, bool)  # cells with a clipped corner
            for corner in np.ndindex(2, 2, 2):
                kink |= edge[tuple(slice(c, c + n - 1) for c, n in zip(corner, self.shape))]
            return dict(u=u, kink=kink)

        arrays = cached_arrays(
            DATA_DIR,
            "inverse-grid",
            spec,
            compute,
            valid=lambda a: a.get("u") is not None and a["u"].shape == (int(np.prod(self.shape)), 2),
        )
        self.u, self.kink = arrays["u"], arrays["kink"].ravel()
        self.strides = np.array([arcs * lengths, lengths, 1])
        self.cell_strides = np.array([(arcs - 1) * (lengths - 1), lengths - 1, 1])
        self.corners = np.array(list(np.ndindex(2, 2, 2))) @ self.strides  # (8,) flat offsets of a cell's corners
        self.arc_scale = 2 * table.robot.bending_stiffness / table.robot.cable_radius / table.robot.length


def _chord_point(robot: Robot, coordinates):
    """Tip points (B, 3) of grid coordinates (B, 3) = (arc actuation (2), chord length): the
    inverse of ``arc_actuation`` along the chord, scaled to the length."""
    a, length = coordinates[:, :2], coordinates[:, 2]
    half_bend = np.hypot(a[:, 0], a[:, 1]) * robot.length * robot.cable_radius / robot.bending_stiffness / 2
    heading = np.arctan2(a[:, 1], a[:, 0])
    lateral = length * np.sin(half_bend)
    return np.stack([length * np.cos(half_bend), lateral * np.cos(heading), lateral * np.sin(heading)], -1)
