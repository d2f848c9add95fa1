"""The one training loop, and where trained models are kept. Imports models, data, rod."""

from softflow.lazy import facade

EXPORTS = {
    "trainer": ["Sampler", "get_lr", "train", "ensure_trained"],
}
SUBMODULES = []
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
