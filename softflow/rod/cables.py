"""Cables: differential actuation u -> per-cable tensions, and rod shape -> cable length change.

Cable c runs straight along the rod at body offset r (cos a_c, sin a_c) in the
cross-section (y, z), guided by spacer disks and anchored at the tip. Its tension T_c
loads the rod with the body moment T_c r (cos a_c, sin a_c) in (kappa_1, kappa_2)
terms, so u = sum_c T_c (cos a_c, sin a_c): for four cables u_1 = T_1a - T_1b and
u_2 = T_2a - T_2b, as in the paper.
"""

from __future__ import annotations

import numpy as np

from softflow.checks import as_real_array
from softflow.rod.robots import Robot


def cable_directions(robot: Robot) -> np.ndarray:
    """Unit offset direction (cos a_c, sin a_c) of each cable in the (y, z) cross-section: (C, 2)."""
    angles = np.asarray(robot.cable_angles)
    return np.stack([np.cos(angles), np.sin(angles)], -1)


def _antagonistic_groups(robot: Robot) -> list[list[int]]:
    """Cables whose tensions may share a common offset without changing u: opposite pairs
    for four cables (0 vs 1, 2 vs 3), all three for the 120-degree layout."""
    return [[0, 1], [2, 3]] if robot.n_cables == 4 else [list(range(robot.n_cables))]


def cable_tensions(u, robot: Robot, pretension: float = 0.0) -> np.ndarray:
    """Non-negative tensions (B, C) that realise u (B, 2), the slackest cable of each
    antagonistic group held at ``pretension`` (N)."""
    u, _ = as_real_array(u, "u", (None, 2))
    if not pretension >= 0:
        raise ValueError(f"pretension must be >= 0 N; got {pretension!r}")
    directions = cable_directions(robot)  # (C, 2), with directions^T directions = C/2 I
    tensions = u @ np.linalg.pinv(directions)  # minimum-norm solution, (B, C)
    for group in _antagonistic_groups(robot):
        tensions[:, group] -= tensions[:, group].min(1, keepdims=True) - pretension
    return tensions


def cable_actuation(tensions, robot: Robot) -> np.ndarray:
    """The differential actuation u (B, 2) that cable tensions (B, C) exert: sum_c T_c (cos a_c, sin a_c)."""
    tensions, _ = as_real_array(tensions, "tensions", (None, robot.n_cables))
    return tensions @ cable_directions(robot)


def cable_displacements(bend_angles, robot: Robot) -> np.ndarray:
    """Length change (m, negative = shortened) of each cable for a rod shape: (B, 2) -> (B, C).

    For an inextensible, torsion-free rod a cable at offset r_c shortens by
    r_c . (Theta_1, Theta_2), where Theta_i = int kappa_i ds are the total bend angles
    (``Simulator.bend_angles``): the exact length, not a small-angle approximation.
    """
    bend_angles, _ = as_real_array(bend_angles, "bend_angles", (None, 2))
    return -robot.cable_radius * bend_angles @ cable_directions(robot).T
