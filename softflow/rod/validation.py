"""Validation of the simulator: closed-form and independent reference solutions, and
the studies (convergence, energy, spectrum) that tests and notebook 01 share.

The reference solutions never use the GVS model: each solves a textbook problem
directly, so comparing the simulator with them means something.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_bvp
from scipy.optimize import brentq

from softflow.rod import statics
from softflow.rod.dynamics import GRAVITY, Simulator
from softflow.rod.robots import Robot

MM = 1e-3  # m


def arc_disk_positions(u, robot: Robot) -> np.ndarray:
    """Ends of the rod's segments (its disks, the tip last) without gravity: (B, m) -> (B, S, 3).

    A cable group anchored at s_g loads [0, s_g] with the constant moment u_g r, so segment j
    is a circular arc of curvature r / EI times the sum of u_g over the groups that pass it,
    bent towards that sum; the arcs are chained by Rodrigues' rotation."""
    u = np.asarray(u, float)
    pairs = u.reshape(len(u), -1, 2)  # (B, G, 2), base outwards
    anchors = np.array(sorted(set(robot.anchors)))
    rotation, position, disks = np.broadcast_to(np.eye(3), (len(u), 3, 3)), np.zeros((len(u), 3)), []
    for end, length in zip(robot.segment_ends, robot.segment_lengths):
        kappa = pairs[:, anchors >= end].sum(1) * robot.cable_radius / robot.bending_stiffness  # (B, 2)
        magnitude = np.linalg.norm(kappa, axis=-1)
        y, z = (np.divide(kappa, magnitude[:, None], out=np.zeros_like(kappa), where=magnitude[:, None] > 0)).T
        angle = magnitude * length
        # chord: (sin t, (1 - cos t) d) / kappa, written with sinc so a straight segment needs no division
        along = length * np.sinc(angle / np.pi)
        lateral = length * angle / 2 * np.sinc(angle / (2 * np.pi)) ** 2
        chord = np.stack([along, lateral * y, lateral * z], -1)
        position = position + (rotation @ chord[..., None])[..., 0]
        disks.append(position)
        # turn by the angle about e1 x d = (0, -z, y): R = I + sin t A + (1 - cos t) A^2
        axis = np.zeros((len(u), 3, 3))
        axis[:, 0, 1], axis[:, 0, 2], axis[:, 1, 0], axis[:, 2, 0] = -y, -z, y, z
        turn = np.eye(3) + np.sin(angle)[:, None, None] * axis + (1 - np.cos(angle))[:, None, None] * axis @ axis
        rotation = rotation @ turn
    return np.stack(disks, 1)


def arc_tip(u, robot: Robot) -> np.ndarray:
    """Tip of the gravity-free piecewise circular arc under u: (B, m) -> (B, 3); for cables
    anchored at the tip, one arc of curvature |u| r / EI bent towards (u_1, u_2)."""
    return arc_disk_positions(u, robot)[:, -1]


def euler_bernoulli_frequencies(robot: Robot, n_modes: int) -> np.ndarray:
    """Cantilever bending frequencies (Hz): cos(b) cosh(b) = -1, omega = b^2 sqrt(EI / (rho A L^4))."""
    roots = [brentq(lambda b: np.cos(b) * np.cosh(b) + 1, (k + 0.2) * np.pi, (k + 0.8) * np.pi) for k in range(n_modes)]
    scale = np.sqrt(robot.bending_stiffness / (robot.mass_per_length * robot.length**4))
    return np.array(roots) ** 2 * scale / (2 * np.pi)


def kelvin_voigt_damping_ratio(robot: Robot, frequency_hz) -> np.ndarray:
    """Modal damping ratio eta omega / (2 E) of a Kelvin-Voigt rod."""
    return robot.damping * 2 * np.pi * np.asarray(frequency_hz) / (2 * robot.youngs_modulus)


def heavy_cantilever_shape(robot: Robot, n_points: int = 100) -> np.ndarray:
    """Large-deflection elastica of a horizontal cantilever under its own weight (gravity
    along -z), solved as a boundary-value problem; returns (n_points, 3) along the rod:

        EI theta'' = w (L - s) cos(theta),  theta(0) = 0,  theta'(L) = 0,  (x, z)' = (cos, sin) theta.
    """
    w, EI, L = robot.mass_per_length * GRAVITY, robot.bending_stiffness, robot.length

    def rhs(s, y):
        return np.vstack([y[1], w * (L - s) * np.cos(y[0]) / EI, np.cos(y[0]), np.sin(y[0])])

    def boundary(base, tip):
        return np.array([base[0], tip[1], base[2], base[3]])

    s = np.linspace(0, L, 200)
    guess = np.vstack([-0.5 * s / L, -np.ones_like(s), s, -0.1 * s])
    solution = solve_bvp(rhs, boundary, s, guess, tol=1e-10, max_nodes=100000)
    if not solution.success:
        raise RuntimeError(f"elastica did not converge: {solution.message}")
    x, z = solution.sol(np.linspace(0, L, n_points))[2:]
    return np.stack([x, np.zeros_like(x), z], -1)


def linear_modes(sim: Simulator):
    """Natural frequencies (Hz) and damping ratios of the model linearised at rest, lowest first.

    Poles of M0 qdd + D qd + Kt q = 0, Kt the tangent stiffness including gravity."""
    q0 = sim.rest_q()[None]
    M = sim.mass_matrix(q0)[0]
    Kt = statics.tangent_stiffness(sim, q0, statics.gravity_force(sim, q0))[0]
    n = sim.nq
    state_matrix = np.block(
        [[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, Kt), -np.linalg.solve(M, sim.damping_matrix)]]
    )
    poles = np.linalg.eigvals(state_matrix)
    poles = poles[poles.imag > 0] if sim.damping_matrix.any() else poles[poles.imag > 1e-9]
    poles = poles[np.argsort(np.abs(poles))]
    return np.abs(poles) / (2 * np.pi), -poles.real / np.abs(poles)


def tip_error(X, reference) -> np.ndarray:
    """Largest tip-position distance (m) over time, per episode."""
    return np.linalg.norm(X[..., :3] - reference[..., :3], axis=-1).max(-1)


def convergence_study(robot: Robot, u, reference_options: dict, variants: dict[str, list[dict]]) -> dict:
    """Max tip error (m) of each option set against a finer reference simulator, on u (B, T, m)."""
    reference = Simulator(robot, **reference_options).rollout(u)
    return {
        name: [float(tip_error(Simulator(robot, **options).rollout(u), reference).max()) for options in option_list]
        for name, option_list in variants.items()
    }


def released_energy(robot: Robot, u_bend, n_steps: int, **options) -> np.ndarray:
    """Total energy (J) over time of a rod released at rest from the static bend of u_bend (B, m),
    without gravity or damping: (B, T+1); it should stay constant."""
    sim = Simulator(robot, gravity="none", damping=False, **options)
    q0 = sim.static_q(u_bend)
    q, qd = sim.integrate(np.zeros((len(q0), n_steps, sim.n_inputs)), q0, np.zeros_like(q0))
    B = len(q0)
    return sim.energy(q.reshape(-1, sim.nq), qd.reshape(-1, sim.nq)).reshape(B, -1)


def free_vibration_spectrum(robot: Robot, u_bend=(0.2, 0.0), seconds: float = 20.0, **options):
    """Amplitude spectrum of the tip y after releasing a small bend, undamped and without
    gravity: (frequencies Hz, amplitude). Its peaks are the simulated bending frequencies."""
    sim = Simulator(robot, gravity="none", damping=False, **options)
    q0 = sim.static_q(np.array([u_bend], float))
    n_steps = int(round(seconds / sim.dt))
    q, qd = sim.integrate(np.zeros((1, n_steps, sim.n_inputs)), q0, np.zeros_like(q0))
    y = sim.tip_state(q[0], qd[0])[:, 1]
    window = np.hanning(len(y))
    amplitude = np.abs(np.fft.rfft((y - y.mean()) * window))
    return np.fft.rfftfreq(len(y), sim.dt), amplitude / amplitude.max()


def heavy_cantilever_tip(robot: Robot) -> np.ndarray:
    """Tip of heavy_cantilever_shape: (3,)."""
    return heavy_cantilever_shape(robot, 2)[-1]
