"""Report: the paper's tables, the results page, the studies' tables and the figures. Only
notebooks and the CLI import it.
"""

from softflow.lazy import facade

EXPORTS = {
    "tables": [
        "COLUMNS",
        "TABLE1_MODELS",
        "BASELINES",
        "RF_FAMILY",
        "LABELS",
        "PAPER_TABLE1",
        "PAPER_TABLE2",
        "PAPER_TABLE3",
        "PAPER_TABLE4",
        "read_result",
        "read_sweep",
        "our_table",
        "table1",
        "table2",
        "table3",
        "table4",
        "markdown",
        "save_table",
    ],
    "provenance": ["CODE", "notebook_wall_times", "recorded_wall_times", "machine", "commit"],
    "page": [
        "FIGURES",
        "claims",
        "claims_list",
        "ranking_rule_section",
        "consistency_term_summary",
        "design_choices",
        "relative",
        "results_page",
    ],
    "sections": ["Section", "sections", "words", "rendered", "result_block", "verdict", "with_words"],
    "study_tables": [
        "table_order",
        "interval_text",
        "with_ci",
        "table1_ci",
        "best_against_best",
        "protocol_table",
        "data_size_table",
        "per_step_table",
        "regime_map",
        "regime_rows",
        "SIZE_EFFECTS",
        "size_effects",
        "lambda_decision",
        "floor_progress",
        "VERDICTS",
        "verdict_counts",
        "gap_sensitivity",
        "closed_loop_table",
        "burst_models",
    ],
}
SUBMODULES = ["plots"]
__getattr__, __dir__, __all__ = facade(__name__, EXPORTS, SUBMODULES)
