"""Physical parameters of the two rods in the paper (SI units)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from softflow.store import content_key

# The simulation rod's actuation range and sample period: the paper's values, defined once.
U_MAX = 4.0  # N, actuation range [-U_MAX, U_MAX] of each differential tension
DT = 0.01  # s, sampling interval


@dataclass(frozen=True)
class Robot:
    """A cantilevered, cable-driven elastic rod with a circular cross-section.

    Cables run straight along the rod on a circle of diameter ``cable_distance``
    (the paper's W) and are anchored at the tip; ``cable_angles`` place them on
    that circle, measured from +y towards +z.
    """

    name: str
    length: float  # m
    diameter: float  # m
    cable_distance: float  # m, diameter of the cable circle (W)
    youngs_modulus: float  # Pa
    damping: float  # Pa s, Kelvin-Voigt viscosity (eta)
    density: float  # kg/m^3
    cable_angles: tuple[float, ...]  # rad

    def __post_init__(self):
        for field in ("length", "diameter", "cable_distance", "youngs_modulus", "density"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{field} must be a positive finite number; got {value!r}")
        if not (math.isfinite(self.damping) and self.damping >= 0):
            raise ValueError(f"damping must be a non-negative finite number; got {self.damping!r}")
        if len(self.cable_angles) not in (3, 4):
            raise ValueError(f"cable_angles must list 3 or 4 cables; got {len(self.cable_angles)}")

    @property
    def area(self) -> float:  # m^2
        return math.pi * self.diameter**2 / 4

    @property
    def second_moment(self) -> float:  # m^4, I of a solid circle
        return math.pi * self.diameter**4 / 64

    @property
    def bending_stiffness(self) -> float:  # N m^2, EI
        return self.youngs_modulus * self.second_moment

    @property
    def mass_per_length(self) -> float:  # kg/m, rho A
        return self.density * self.area

    @property
    def cable_radius(self) -> float:  # m, moment arm r = W/2
        return self.cable_distance / 2

    @property
    def n_cables(self) -> int:
        return len(self.cable_angles)


# Simulation rod of the paper (Sec. IV-A): two orthogonal antagonistic pairs,
# cable 1a at +y, 1b at -y, 2a at +z, 2b at -z.
SIM_ROBOT = Robot(
    name="sim",
    length=0.4,
    diameter=0.004,
    cable_distance=0.055,
    youngs_modulus=2e9,
    damping=5e7,
    density=12000.0,
    cable_angles=(0.0, math.pi, math.pi / 2, 3 * math.pi / 2),
)

# Hardware rod of the paper (Sec. V-A): three cables at 120 degrees, first at +y.
HW_ROBOT = Robot(
    name="hw",
    length=0.45,
    diameter=0.004,
    cable_distance=0.025,
    youngs_modulus=3.5e9,
    damping=4e7,
    density=12400.0,
    cable_angles=(0.0, 2 * math.pi / 3, 4 * math.pi / 3),
)

ROBOTS = {robot.name: robot for robot in (SIM_ROBOT, HW_ROBOT)}


def rod_folder(robot: Robot, gravity: str) -> str:
    """Sub-folder of a rod and gravity configuration, keyed by the rod's parameters (a
    calibrated copy of a rod never shares its folder); "" for the paper's simulation rod."""
    if (robot, gravity) == (SIM_ROBOT, "vertical"):
        return ""
    parameters = {k: v for k, v in asdict(robot).items() if k != "name"}
    return f"{robot.name}-{gravity}-{content_key(parameters, 8)}"
