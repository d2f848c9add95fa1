"""The hardware twin: reality gap (cable friction among its terms), cable plant and motor
commands, camera and tracking, system identification, calibration, the replay experiment, and
the twin as a recording rig. Imports control and below.
"""

from softflow.lazy import facade

EXPORTS = {
    "gap": ["RealityGap", "GAP_TERMS", "NO_GAP", "TYPICAL_GAP", "FRICTION_GAP", "SLIDING_LENGTH"],
    "friction": ["dahl_state", "capstan_tensions"],
    "commands": [
        "CABLE_STIFFNESS",
        "PRETENSION",
        "cable_commands",
        "rest_command",
        "StepCommands",
        "write_commands",
        "read_commands",
        "write_marker_csv",
        "load_recording",
    ],
    "plant": ["CablePlant"],
    "hysteresis": ["HysteresisLoop", "hysteresis_loop", "hysteresis_loops"],
    "calibration": ["calibrate_sag"],
    "twin": ["CAMERA_DISTANCE", "twin_camera", "observe_run", "stroboscope_run", "tracked_rmse", "TwinRig"],
    "experiment": ["LOOPS", "run_twin", "run_commands"],
    "recorder": ["record_runs", "input_columns", "motor_columns"],
}
SUBMODULES = ["vision", "identification", "calibration"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
