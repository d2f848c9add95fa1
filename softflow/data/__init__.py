"""Data: excitation families, the simulated datasets and their cache, reference trajectories,
dataset variants, recorded runs (``recordings``). Imports the rod and the foundation.
"""

from softflow.lazy import facade

EXPORTS = {
    "dataset": [
        "DATA_VERSION",
        "OBSERVATIONS",
        "BLOCK_EPISODES",
        "Dataset",
        "subset",
        "split_episodes",
        "dataset_path",
        "load_dataset",
        "DatasetOnDemand",
        "simulated_dataset",
        "gather_windows",
        "coverage",
    ],
    "excitation": ["polynomial_excitation", "sum_of_sines_excitation", "mixed_excitation"],
    "references": [
        "REFERENCE_VERSION",
        "NOMINAL_SPEED",
        "APPROACH_SECONDS",
        "RAMP_SECONDS",
        "SIZE",
        "HARDWARE_SHAPES",
        "HARDWARE_SIZE",
        "HARDWARE_BURST_RADIUS",
        "Reference",
        "SHAPES",
        "shape_points",
        "shape_reference",
        "least_norm_lift",
        "depth_circle_reference",
        "burst_circle_reference",
        "actuated_references",
        "random_references",
        "complex3d_references",
        "STRUCTURED",
        "cached_references",
        "burst_references",
        "hardware_burst_reference",
        "hardware_references",
        "evaluation_references",
    ],
    "variants": ["EXCITATIONS", "HOLD_SECONDS", "Variant", "VARIANTS", "piecewise_excitation", "variant_dataset"],
}
SUBMODULES = ["recordings"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
