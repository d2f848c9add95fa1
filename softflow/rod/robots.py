"""Physical parameters of the paper's two rods and of the two-segment rod (SI units)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from softflow.store import content_key

# The simulation rod's actuation range and sample period: the paper's values, defined once.
U_MAX = 4.0  # N, actuation range [-U_MAX, U_MAX] of each differential tension
DT = 0.01  # s, sampling interval


@dataclass(frozen=True)
class Robot:
    """A cantilevered, cable-driven elastic rod with a circular cross-section.

    Cables run straight along the rod on a circle of diameter ``cable_distance``
    (the paper's W); ``cable_angles`` place them on that circle, measured from +y
    towards +z, and ``cable_anchors`` give the arc length at which each one ends
    (empty: all at the tip). The disks where cables end cut the rod into segments,
    each with its own strain basis; the cables that end at one disk (three, or four
    listed as two antagonistic pairs) form a group driven by one input pair (u_y, u_z),
    and u lists the groups' pairs from the base outwards.
    """

    name: str
    length: float  # m
    diameter: float  # m
    cable_distance: float  # m, diameter of the cable circle (W)
    youngs_modulus: float  # Pa
    damping: float  # Pa s, Kelvin-Voigt viscosity (eta)
    density: float  # kg/m^3
    cable_angles: tuple[float, ...]  # rad
    cable_anchors: tuple[float, ...] = ()  # m from the base, one per cable; () = all at the tip

    def __post_init__(self):
        for field in ("length", "diameter", "cable_distance", "youngs_modulus", "density"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{field} must be a positive finite number; got {value!r}")
        if not (math.isfinite(self.damping) and self.damping >= 0):
            raise ValueError(f"damping must be a non-negative finite number; got {self.damping!r}")
        if self.cable_anchors and len(self.cable_anchors) != len(self.cable_angles):
            raise ValueError(
                f"cable_anchors must give one arc length per cable ({len(self.cable_angles)}); "
                f"got {len(self.cable_anchors)}"
            )
        for anchor in self.cable_anchors:
            if not (isinstance(anchor, (int, float)) and 0 < anchor <= self.length):
                raise ValueError(f"cable_anchors must lie in (0, length = {self.length}] m; got {anchor!r}")
        holes = np.exp(1j * np.asarray(self.cable_angles))  # each cable's hole on the unit circle
        if np.abs(np.subtract.outer(holes, holes))[np.triu_indices(len(holes), 1)].min(initial=2.0) < 1e-9:
            raise ValueError(f"cable_angles must be distinct: two cables cannot share a hole; got {self.cable_angles}")
        for group in self.cable_groups:
            if len(group) not in (3, 4):
                raise ValueError(f"each anchor disk must end 3 or 4 cables; got {len(group)} (cables {list(group)})")

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

    @property
    def anchors(self) -> tuple[float, ...]:  # m, where each cable ends
        return self.cable_anchors or (self.length,) * self.n_cables

    @property
    def segment_ends(self) -> tuple[float, ...]:  # m, the disks that end a segment, base outwards
        return tuple(sorted(set(self.anchors) | {self.length}))

    @property
    def segment_lengths(self) -> tuple[float, ...]:  # m
        ends = self.segment_ends
        return tuple(end - start for start, end in zip((0.0,) + ends[:-1], ends))

    @property
    def cable_groups(self) -> tuple[tuple[int, ...], ...]:
        """The cables that end at each anchor disk, base outwards: one input pair each."""
        return tuple(
            tuple(c for c, anchor in enumerate(self.anchors) if anchor == end) for end in sorted(set(self.anchors))
        )

    @property
    def n_inputs(self) -> int:  # m: a differential pair (u_y, u_z) per anchor disk
        return 2 * len(self.cable_groups)

    def parameters(self) -> dict:
        """The parameters that key caches: every field but the name."""
        return {k: v for k, v in asdict(self).items() if k != "name"}


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

# The simulation rod in two segments of 0.2 m (the paper's future work): four cables end at
# the middle disk (u1, u2) and four run to the tip (u3, u4); the tip cables' holes are
# turned by 45 degrees from the middle ones' (two cables cannot share a hole).
TWO_SEGMENT_ROD = replace(
    SIM_ROBOT,
    name="two",
    cable_angles=tuple(a + offset for offset in (0.0, math.pi / 4) for a in SIM_ROBOT.cable_angles),
    cable_anchors=(0.2,) * 4 + (0.4,) * 4,
)

ROBOTS = {robot.name: robot for robot in (SIM_ROBOT, HW_ROBOT, TWO_SEGMENT_ROD)}


def rod_folder(robot: Robot, gravity: str) -> str:
    """Sub-folder of a rod and gravity configuration, keyed by the rod's parameters (a
    calibrated copy of a rod never shares its folder); "" for the paper's simulation rod."""
    if (robot, gravity) == (SIM_ROBOT, "vertical"):
        return ""
    return f"{robot.name}-{gravity}-{content_key(robot.parameters(), 8)}"
