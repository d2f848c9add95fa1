"""The hardware twin: reality gap, cable plant and motor commands, camera and tracking,
system identification, calibration, and the replay experiment. Imports control and below.
"""

from softflow.lazy import facade

EXPORTS = {
    "twin": [
        "CABLE_STIFFNESS",
        "PRETENSION",
        "CAMERA_DISTANCE",
        "RealityGap",
        "GAP_TERMS",
        "NO_GAP",
        "TYPICAL_GAP",
        "calibrate_sag",
        "cable_commands",
        "rest_command",
        "StepCommands",
        "CablePlant",
        "twin_camera",
        "observe_run",
        "stroboscope_run",
        "tracked_rmse",
        "TwinRig",
    ],
    "commands": ["write_commands", "read_commands", "write_marker_csv", "load_recording"],
    "experiment": ["LOOPS", "run_twin"],
}
SUBMODULES = ["vision", "identification", "calibration"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
