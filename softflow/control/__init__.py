"""Control: open-loop planning (``Controller``), its real-time step as an ONNX graph
(``export_onnx``), the loop of a model of recorded runs (``loop_of``; ``export_loop``), the
metrics, the ILC floor, tip-state estimation and the twin's closed loop. Imports models, data
and the rod, never training.
"""

from softflow.lazy import facade

EXPORTS = {
    "planning": [
        "NOISE",
        "WORKSPACE_MARGIN",
        "SaturationWarning",
        "Controller",
        "find_trained",
        "load_controller",
        "plan_all",
        "pad_plans",
        "evaluate",
        "evaluate_many",
        "score",
    ],
    "onnx_export": ["export_onnx", "export_loop"],
    "loop": ["Loop", "loop_of", "InputLimits", "Feedback"],
}
SUBMODULES = ["metrics", "floor", "estimation", "closed_loop"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
