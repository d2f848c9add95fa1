"""softflow: flow-matching inverse dynamics for a cable-driven soft rod.

The short public API; everything else lives in the sub-packages, each of one concern (their
layering is a contract in pyproject.toml). Names load on first use, so ``import softflow``
costs nothing until a name is asked for.
"""

from softflow.lazy import facade

EXPORTS = {
    "rod": ["DT", "HW_ROBOT", "Robot", "SIM_ROBOT", "Simulator", "TWO_SEGMENT_ROD", "U_MAX"],
    "data": ["recordings"],
    "control": ["Controller", "evaluate", "load_controller"],
}
SUBMODULES = ["rod", "data", "models", "training", "control", "hardware", "studies", "report"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
