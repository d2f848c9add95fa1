"""Studies: the Dask sweep runner, one module per study, statistics. Imports everything below
report.
"""

from softflow.lazy import facade

EXPORTS = {
    "catalogue": ["STUDIES"],
    "study": ["FLOOR", "Study", "trained", "floor_rows", "held_out_plan", "unnamed"],
}
SUBMODULES = [
    "sweep",
    "stats",
    "stress",
    "protocol",
    "ambiguity",
    "table1",
    "data_size",
    "fwd_lambda",
    "design",
    "closed_loop",
    "twin_burst",
    "two_segment",
    "recorded",
    "smoke",
]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
