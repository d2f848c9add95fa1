"""Cables: differential actuation u -> per-cable tensions, and rod shape -> cable length change.

Cable c runs straight along the rod at body offset r (cos a_c, sin a_c) in the
cross-section (y, z), guided by spacer disks and anchored at the disk s_c where it ends
(the tip unless ``Robot.cable_anchors`` says otherwise). Its tension T_c loads [0, s_c]
with the body moment T_c r (cos a_c, sin a_c) in (kappa_1, kappa_2) terms, so the cables
that end at one disk act through u_g = sum_c T_c (cos a_c, sin a_c): for four cables
u_1 = T_1a - T_1b and u_2 = T_2a - T_2b, as in the paper. u lists these pairs per disk,
base outwards (``Robot.cable_groups``); a group turned on the circle (the two-segment
rod's tip cables, 45 degrees) still has its u_g along +y and +z.
"""

from __future__ import annotations

import numpy as np

from softflow.checks import as_real_array
from softflow.rod.robots import Robot


def cable_directions(robot: Robot) -> np.ndarray:
    """Unit offset direction (cos a_c, sin a_c) of each cable in the (y, z) cross-section: (C, 2)."""
    angles = np.asarray(robot.cable_angles)
    return np.stack([np.cos(angles), np.sin(angles)], -1)


def _antagonistic_groups(cables: tuple[int, ...]) -> list[list[int]]:
    """Cables of one disk whose tensions may share a common offset without changing u:
    opposite pairs for four cables (listed a, b, a, b), all three for the 120-degree layout."""
    return [list(cables[:2]), list(cables[2:])] if len(cables) == 4 else [list(cables)]


def cable_tensions(u, robot: Robot, pretension: float = 0.0) -> np.ndarray:
    """Non-negative tensions (B, C) that realise u (B, m), the slackest cable of each
    antagonistic group held at ``pretension`` (N)."""
    u, _ = as_real_array(u, "u", (None, robot.n_inputs))
    if not pretension >= 0:
        raise ValueError(f"pretension must be >= 0 N; got {pretension!r}")
    directions = cable_directions(robot)
    tensions = np.empty((len(u), robot.n_cables))  # (B, C)
    for g, cables in enumerate(robot.cable_groups):
        # minimum-norm solution per disk; directions^T directions = C_g/2 I
        tensions[:, cables] = u[:, 2 * g : 2 * g + 2] @ np.linalg.pinv(directions[list(cables)])
        for group in _antagonistic_groups(cables):
            tensions[:, group] -= tensions[:, group].min(1, keepdims=True) - pretension
    return tensions


def cable_actuation(tensions, robot: Robot) -> np.ndarray:
    """The differential actuation u (B, m) that cable tensions (B, C) exert: per disk sum_c T_c (cos a_c, sin a_c)."""
    tensions, _ = as_real_array(tensions, "tensions", (None, robot.n_cables))
    directions = cable_directions(robot)
    return np.concatenate([tensions[:, cables] @ directions[list(cables)] for cables in robot.cable_groups], -1)


def cable_displacements(bend_angles, robot: Robot) -> np.ndarray:
    """Length change (m, negative = shortened) of each cable for a rod shape: (B, m) -> (B, C).

    For an inextensible, torsion-free rod a cable at offset r_c ending at s_c shortens by
    r_c . (Theta_1, Theta_2), where Theta_i = int_0^{s_c} kappa_i ds are the bend angles up
    to its disk (``Simulator.bend_angles``): the exact length, not a small-angle approximation.
    """
    bend_angles, _ = as_real_array(bend_angles, "bend_angles", (None, robot.n_inputs))
    directions = cable_directions(robot)
    displacements = np.empty((len(bend_angles), robot.n_cables))  # (B, C)
    for g, cables in enumerate(robot.cable_groups):
        displacements[:, cables] = -robot.cable_radius * bend_angles[:, 2 * g : 2 * g + 2] @ directions[list(cables)].T
    return displacements
