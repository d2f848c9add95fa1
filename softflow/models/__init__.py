"""Inverse models u_t = g(x_{t-K+1}, ..., x_t, x_{t+1}): deterministic baselines, the RF family, the
forward surrogate, the registry that names them and checkpoint I/O. Imports only torch, numpy
and the foundation: never the rod (RF-Physical's prior is passed in) nor the data.
"""

from softflow.lazy import facade

EXPORTS = {
    "specs": ["MODELS", "ModelSpec", "build_model", "model_spec", "resolved_kwargs"],
    "checkpoints": [
        "SHIPPED",
        "TRAINED",
        "save_checkpoint",
        "load_checkpoint",
        "model_from_checkpoint",
        "identity",
        "matches",
        "checkpoint_path",
        "find_checkpoint",
    ],
}
SUBMODULES = ["baselines", "common", "flow", "forward"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
