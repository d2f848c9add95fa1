"""Writes tests/data/sim_golden.npz: a fixed episode, statics and inverse statics of the
simulator as they were before sim.py was split into kinematics / dynamics / statics
(commit 4ac4fdb). test_sim.py compares today's simulator with it to 1e-12.

Rerun only when a change of the numbers is intended (and bump SIMULATOR_VERSION then):
    .venv/bin/python tests/make_sim_golden.py
"""

from pathlib import Path

import numpy as np

from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT

GOLDEN = Path(__file__).parent / "data" / "sim_golden.npz"


def golden_inputs():
    rng = np.random.default_rng(7)
    t = np.arange(60) * 0.01
    u = np.stack([3.0 * np.sin(2 * np.pi * 1.3 * t), 2.0 * np.cos(2 * np.pi * 0.7 * t) - 1.0], -1)[None]
    u_static = rng.uniform(-4, 4, (5, 2))
    return u, u_static


def golden_outputs():
    u, u_static = golden_inputs()
    out = {}
    for robot, gravity in ((SIM_ROBOT, "vertical"), (HW_ROBOT, "horizontal")):
        sim = Simulator(robot, gravity)
        tag = f"{robot.name}_{gravity}"
        out[f"{tag}_rollout"] = sim.rollout(u)
        out[f"{tag}_static_tip"] = tips = sim.static_tip(u_static)
        out[f"{tag}_inverse_static"] = sim.inverse_static(tips + 1e-3)
        tip, u_lift, dp_dyz = sim.static_lift(sim.static_tip(0.5 * u_static)[:, 1:])
        out[f"{tag}_lift_tip"], out[f"{tag}_lift_u"], out[f"{tag}_lift_jacobian"] = tip, u_lift, dp_dyz
    return out


if __name__ == "__main__":
    GOLDEN.parent.mkdir(exist_ok=True)
    np.savez(GOLDEN, **golden_outputs())
    print(f"wrote {GOLDEN}")
