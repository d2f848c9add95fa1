"""The reality gap: everything that separates the twin's plant from the model used to plan
(the rod's E, eta and rho, the motors' lag, the cables' slack and friction, the camera's
noise), in one seeded, hashable place, and the gaps the studies use."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from softflow.rod.robots import Robot

SLIDING_LENGTH = 5e-4  # m, the Dahl sliding length of a cable in its holes (assumed; docs/assumptions.md)


@dataclass(frozen=True)
class RealityGap:
    """Everything that separates the plant from the model used to plan, in one seeded place."""

    youngs_modulus: float = 0.0  # relative error of the plant's E
    damping: float = 0.0  # relative error of its eta
    density: float = 0.0  # relative error of its rho
    motor_lag: float = 0.0  # s, time constant of each motor's position loop
    slack: float = 0.0  # m, each cable's slack is drawn uniformly from [0, slack]
    depth_noise: float = 0.0  # m at 1 m, the camera's depth noise (grows with Z^2)
    pixel_noise: float = 0.0  # colour noise of the camera, 0-255
    seed: int = 0
    cable_friction: float = 0.0  # mu, Coulomb coefficient of a cable in the spacer disks' holes
    sliding_length: float = SLIDING_LENGTH  # m of sliding over which friction builds up (Dahl: F_c / sigma_0)

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not np.isfinite(value):
                raise ValueError(f"{name} must be finite; got {value!r}")
        for name in ("motor_lag", "slack", "depth_noise", "pixel_noise"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0; got {getattr(self, name)!r}")
        if min(self.youngs_modulus, self.damping, self.density) <= -1:
            raise ValueError("relative parameter errors must be > -1 (a positive parameter stays positive)")
        if self.cable_friction < 0:
            raise ValueError(
                "cable_friction must be a friction coefficient >= 0 (0: frictionless cables); "
                f"got {self.cable_friction!r}"
            )
        if not self.sliding_length > 0:
            raise ValueError(f"sliding_length must be a length > 0 m (Dahl's); got {self.sliding_length!r}")

    def parameters(self) -> dict:
        """The terms that key caches: all of them."""
        return asdict(self)

    def plant_robot(self, robot: Robot) -> Robot:
        return replace(
            robot,
            youngs_modulus=robot.youngs_modulus * (1 + self.youngs_modulus),
            damping=robot.damping * (1 + self.damping),
            density=robot.density * (1 + self.density),
        )

    def doubled(self, term: str) -> RealityGap:
        """This gap with one term twice as large: the sensitivity study."""
        if term not in GAP_TERMS:
            raise ValueError(f"term must be one of {GAP_TERMS}; got {term!r}")
        return replace(self, **{term: 2 * getattr(self, term)})


GAP_TERMS = ("youngs_modulus", "damping", "density", "motor_lag", "slack", "depth_noise", "pixel_noise")
NO_GAP = RealityGap()
# A bench-top rod: E, eta, rho within 10-20 % of their nominal values, a hobby servo's lag,
# a few tenths of a millimetre of slack, D435-like depth and colour noise.
TYPICAL_GAP = RealityGap(
    youngs_modulus=-0.15, damping=0.20, density=0.10, motor_lag=0.02, slack=3e-4, depth_noise=1e-3, pixel_noise=3.0
)
# The typical gap with cables that rub in their holes: nylon line in printed-plastic disks
# (mu assumed, docs/assumptions.md), a hysteresis loop of a few per cent of the reach.
FRICTION_GAP = replace(TYPICAL_GAP, cable_friction=0.15)
