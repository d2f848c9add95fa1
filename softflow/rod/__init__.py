"""The rod: parameter sets, strain kinematics, the GVS simulator, statics, cables and the
closed-form checks. Imports only the foundation (checks, store).
"""

from softflow.lazy import facade

EXPORTS = {
    "robots": ["U_MAX", "DT", "Robot", "SIM_ROBOT", "HW_ROBOT", "TWO_SEGMENT_ROD", "ROBOTS", "rod_folder"],
    "dynamics": ["SIMULATOR_VERSION", "GRAVITY", "GRAVITY_DIRECTIONS", "Simulator"],
    "statics": [
        "STATICS_VERSION",
        "MAX_RESIDUAL",
        "gravity_force",
        "tangent_stiffness",
        "equilibrium",
        "arc_actuation",
        "fit_static",
        "static_tip",
        "inverse_static",
        "static_lift",
        "StaticTable",
        "InverseGrid",
    ],
    "kinematics": ["rowwise", "RodKinematics"],
    "cables": ["cable_directions", "cable_tensions", "cable_actuation", "cable_displacements"],
    "validation": [
        "MM",
        "arc_tip",
        "arc_disk_positions",
        "euler_bernoulli_frequencies",
        "kelvin_voigt_damping_ratio",
        "heavy_cantilever_shape",
        "linear_modes",
        "tip_error",
        "convergence_study",
        "released_energy",
        "free_vibration_spectrum",
        "heavy_cantilever_tip",
    ],
}
SUBMODULES = ["statics", "validation", "cables", "kinematics"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
