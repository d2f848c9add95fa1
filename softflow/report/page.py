"""docs/results.md (``results_page``): every table, the claims checked, and the studies'
verdicts in words.

The verdicts are computed here from the studies' rows (figures/sweeps/, intervals only, no
model runs), so every one follows the current rule: words only where both the bootstrap and
the paired t-interval exclude zero."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from softflow.machine import description
from softflow.models.registry import label
from softflow.profiles import Profile
from softflow.report.provenance import commit, recorded_wall_times
from softflow.report.study_tables import (
    best_against_best,
    floor_progress,
    interval_text,
    lambda_decision,
    recorded_model_rule,
    recording_rule,
    regime_map,
    regime_rows,
    size_effects,
    table_order,
    two_segment_differences,
    verdict_counts,
)
from softflow.report.tables import (
    BASELINES,
    LABELS,
    RF_FAMILY,
    computed_rows,
    machine_counts,
    markdown,
    our_table,
    read_result,
    read_sweep,
)
from softflow.studies import one_step, stats, trunk, trunk_v2
from softflow.studies.recorded import RECORDED
from softflow.studies.recorded import cells as recorded_cells
from softflow.studies.study import FLOOR
from softflow.studies.table1 import TABLE1
from softflow.studies.two_segment import TWO_SEGMENT
from softflow.studies.two_segment import cells as two_segment_cells

WALL_TIMES = "reproduce.csv"  # per notebook, under the profile's bench folder
FIGURES = [
    ("Open-loop tracking, RF family (Circle, Heart, Rand2, Rand3)", "04_tracking_rf.png"),
    ("Open-loop tracking, baselines", "03_tracking_baselines.png"),
    ("Euler steps: RMSE and latency", "04_euler_sweep.png"),
    ("High-speed burst circle", "05_burst.png"),
    ("Where tracking breaks", "05_break_curve.png"),
    ("Forward-then-inverse on complex 3D actuation", "05_complex3d.png"),
    ("Noise-draw spread against tracking error", "05_uncertainty.png"),
    ("Hardware twin: camera-measured tracking", "06_twin_tracking.png"),
    ("Hardware twin: stroboscopic composites", "06_stroboscope.png"),
    ("Table I with 95 % intervals over seeds and references, and the ILC floor", "08_table1_ci.png"),
    ("Mean RMSE on the shapes under each evaluation protocol", "08_protocol.png"),
    ("RMSE against the shapes' speed, with the coverage by the training states", "08_speed.png"),
    ("Open against closed loop on the twin's star (camera tracks)", "10_open_closed.png"),
    ("Closed loop against camera latency", "10_latency.png"),
    ("Where the twin's loops break on the burst", "10_burst.png"),
    ("Identified reality-gap terms against the truth", "10_identified.png"),
    ("Where a flow beats the MLP: flow - MLP against the measured ambiguity", "09_regime_map.png"),
    ("Tracking RMSE against the training-set size", "09_data_size.png"),
    ("Per-step u error and the data's conditional spread per dataset variant", "09_ambiguity.png"),
    ("RF-FWD's consistency weight", "11_fwd_lambda.png"),
    ("Two-segment rod: one tip path reached by two input histories", "12_redundancy.png"),
    ("Two-segment rod: open-loop tracking by the models of the tip", "12_tracking.png"),
    ("Cable friction: the twin's hysteresis loop against the friction coefficient", "13_hysteresis.png"),
    ("The ASL trunk: judged tip error of each planner", "14_judged.png"),
    (
        "The ASL trunk asked again: each judge's resolution curve (known perturbations of the inputs)",
        "14_v2_resolution.png",
    ),
    ("A flow in one step: tracking RMSE of each plan (model@steps)", "15_one_step.png"),
]


def claims(profile: Profile) -> pd.DataFrame:
    """The paper's headline numbers beside ours, each with what the measurements say about a
    gap (every number from a result CSV; notebook 08 for the intervals, floor and protocol).
    The best-against-best row rests on the table1 study's seeds alone, its change and its
    difference alike."""
    ours = our_table(profile)
    burst = read_result(profile, "stress_burst.csv").set_index("model").loc["rf-fwd"]
    complex3d = read_result(profile, "stress_complex3d.csv").query("model == 'rf-fwd'")
    twin = read_result(profile, "table3_twin.csv").set_index("reference").loc["mean"]
    latency = read_result(profile, "euler_sweep.csv").set_index("steps").latency_ms.loc[4]
    gaps = read_result(profile, "twin_sensitivity.csv")
    gaps = gaps.set_index(gaps.columns[0])  # the CSV's index column: the gap variant
    other = gaps.drop(index=["no gap", "typical gap", "2 x youngs_modulus", "2 x density"]).horizontal.max()
    closed = read_result(profile, "10_table3_extended.csv").set_index(["gravity", "reference"]).xs("mean", level=1)
    summary = read_result(profile, "08_table1_ci.csv").set_index(["family", "model"])["mean"]
    seeds = read_sweep(profile, "table1")
    differences = best_against_best(seeds)
    improving, references = floor_progress(seeds, TABLE1[profile.name].ilc_iterations)
    protocol = read_result(profile, "08_protocol.csv").set_index("condition")
    models = summary.drop(index=FLOOR, level="model")
    ratio = {f: models.loc[f] / summary.loc[(f, FLOOR)] for f in ("shape", "random")}
    change = " / ".join(
        _change_text(
            100 * (summary.loc[(f, d.best_rf)] / summary.loc[(f, d.best_baseline)] - 1),
            stats.ranking(*stats.row_intervals(d)),
        )
        for f, d in differences.iterrows()
    )
    paired = "; ".join(
        f"{f}: {d.difference_mm:+.2f} mm [{d.low:+.2f}, {d.high:+.2f}] (t: [{d.t_low:+.2f}, {d.t_high:+.2f}]), "
        f"{d.verdict}"
        for f, d in differences.iterrows()
    )
    baselines = protocol.reindex(columns=BASELINES)
    spread = protocol.reindex(columns=RF_FAMILY).stack()
    rows = [
        (
            "Best RF variant against the best baseline (shapes / random)",
            "> 50 % lower / > 50 % lower",
            change,
            f"the change and the difference of the means over {seeds.loc[seeds.model != FLOOR, 'seed'].nunique()} "
            f"seeds and the references (notebook 08), best RF variant - best baseline, {paired}; every model is "
            f"{ratio['shape'].min():.0f}-{ratio['shape'].max():.0f}x (shapes) and {ratio['random'].min():.0f}-"
            f"{ratio['random'].max():.0f}x (random) above the ILC floor of {summary.loc[('shape', FLOOR)]:.2f} / "
            f"{summary.loc[('random', FLOOR)]:.2f} mm (still improving at its last trial on {improving} of "
            f"{references} references: at most that)",
        ),
        (
            "RF-FWD RMSE, shapes / random (mm)",
            "5.0 / 3.5",
            f"{ours.loc['rf-fwd', 'shape_mm']:.2f} / {ours.loc['rf-fwd', 'random_mm']:.2f}",
            f"the protocol alone moves the shape RMSE of the RF family over "
            f"{spread.min():.1f}-{spread.max():.1f} mm and "
            f"of the baselines over {baselines.min().min():.1f}-{baselines.max().max():.1f} mm (notebook 08)",
        ),
        (
            "Burst circle: RF-FWD peak speed (m/s), y-z RMSE (mm, % L)",
            "2.03, 20.65 (5.16 %)",
            f"{burst.peak_speed:.2f}, {burst.rmse_yz_mm:.2f} ({burst.rmse_pct_L:.2f} %)",
            f"our assumed circle (r = 0.15 m; the paper states no radius) with period >= 1.2 s asks for "
            f"{burst.reference_peak_speed:.2f} m/s at most; the paper's 2.03 m/s needs a faster path (the paper "
            f"also gives the same 20.65 mm for its simulated and its hardware burst)",
        ),
        (
            "Complex 3D: RF-FWD MAE u1 / u2 (N)",
            "0.027 / 0.033",
            f"{complex3d.mae_u1.mean():.3f} / {complex3d.mae_u2.mean():.3f}",
            f"{complex3d.mae_u1.mean() / 0.027:.1f}x / {complex3d.mae_u2.mean() / 0.033:.1f}x the paper's",
        ),
        (
            "Hardware mean RMSE, vertical / horizontal (mm)",
            "4.30 / 6.40",
            f"{twin.vertical:.2f} / {twin.horizontal:.2f}",
            f"a twin, not the robot: without a reality gap {gaps.loc['no gap', 'vertical']:.1f} / "
            f"{gaps.loc['no gap', 'horizontal']:.1f} mm; horizontally the gap's E and rho errors dominate "
            f"(doubling the E "
            f"error gives {gaps.loc['2 x youngs_modulus', 'horizontal']:.1f} mm, the rho error "
            f"{gaps.loc['2 x density', 'horizontal']:.1f} mm, any other term at most {other:.1f} mm; notebook 06); "
            f"calibrated on an identification run and learnt across 5 repetitions in closed loop: "
            f"{closed.loc['vertical', 'closed-ilc-calibrated']:.2f} / "
            f"{closed.loc['horizontal', 'closed-ilc-calibrated']:.2f} mm "
            f"(notebook 10)",
        ),
        (
            "Inference per step, batch 1 (ms)",
            "0.995",
            f"{latency:.3f} (eager torch, N = 4)",
            "a smaller network on a CPU; `Controller.step`, one compiled call, is faster still (README, Speed)",
        ),
    ]
    return pd.DataFrame(rows, columns=["claim", "paper", "ours", "what the measurements say"]).set_index("claim")


def floor_note(rows: pd.DataFrame, iterations: int) -> str:
    """What the ILC floor is, and on how many references it was still improving when it stopped."""
    improving, references = floor_progress(rows, iterations)
    return (
        "The floor is iterative learning control on the true simulator: what an open-loop plan reaches with an "
        f"exact model and many trials. Its best trial was its last (trial {iterations}; trial 0 is the quasi-static "
        f"plan) on {improving} of {references} references, so it was still improving there when it stopped: an "
        "upper bound on the true floor."
    )


def ranking_rule_section(profile: Profile) -> list[str]:
    """The rule for stating a ranking in words, and how many of the studies' comparisons it
    ranks beside the bootstrap alone (notebooks 08, 09, 11)."""
    tables = {
        "table1": best_against_best(read_sweep(profile, "table1")),
        "ambiguity": regime_map(regime_map_rows(profile)),
        "data_size": size_effects(read_sweep(profile, "data_size")),
        "fwd_lambda": lambda_decision(read_sweep(profile, "fwd_lambda"))[0],
    }
    return [
        "## When a ranking is stated",
        "",
        "A difference between two models gets two 95 % intervals: the two-way bootstrap over training seeds and "
        "references, and the paired t-interval over references on each model's mean over its seeds "
        "(`softflow.studies.stats`). A ranking (lower, higher, better) is stated in words only where both exclude "
        "zero. The studies' comparisons, and how many each rule ranks (the per-step u error is one number per "
        "trained model: no references to pair over, so no t-interval and no ranking in words):",
        "",
        markdown(verdict_counts(tables)),
        "",
    ]


def trust_section(profile: Profile) -> list[str]:
    """Table I with intervals and the floor, the paired difference and the protocol table (notebook 08)."""
    summary = read_result(profile, "08_table1_ci.csv")
    summary["cell"] = interval_text(summary)
    table = summary.pivot(index="model", columns="family", values="cell")[["shape", "random"]]
    table = table.reindex(table_order(table.index))
    counts = summary.groupby("family").agg(seeds=("seeds", "max"), references=("references", "max"))
    seeds = read_sweep(profile, "table1")
    differences = best_against_best(seeds)
    protocol = read_result(profile, "08_protocol.csv").set_index("condition")
    return [
        "## Table I with 95 % intervals and the floor (notebook 08)",
        "",
        f"Mean RMSE (mm) [95 % two-way bootstrap interval over {counts.seeds.max()} training seeds and "
        f"{counts.loc['shape', 'references']} shapes / {counts.loc['random', 'references']} random references; "
        f"seed 0 is the shipped model]. {floor_note(seeds, TABLE1[profile.name].ilc_iterations)}",
        "",
        markdown(table),
        "",
        "Best RF variant - best baseline, paired over references (bootstrap low, high; paired t-interval t_low, "
        "t_high):",
        "",
        markdown(
            differences[["best_rf", "best_baseline", "difference_mm", "low", "high", "t_low", "t_high", "verdict"]], 3
        ),
        "",
        "## The evaluation protocol's effect (notebook 08)",
        "",
        "Mean RMSE (mm) on the shapes with the shipped models under each choice the paper leaves open; coverage: "
        "the share of reference states as close to the training states as held-out validation states are.",
        "",
        markdown(protocol.rename(columns=LABELS)),
        "",
    ]


def closed_loop_section(profile: Profile) -> list[str]:
    """Table III extended, latency, lost frames, each gap term doubled, the burst's break and the
    identified parameters (notebook 10)."""
    table = read_result(profile, "10_table3_extended.csv").set_index(["gravity", "reference"])
    each = table.drop(index="mean", level="reference")
    worse = pd.DataFrame(
        {
            mode: (each[mode] > each["open"]).groupby(level="gravity", sort=False).sum()
            for mode in each.columns.drop("open")
        }
    ).astype(int)
    latency = read_result(profile, "10_latency.csv").set_index(["latency", "dropped"])
    gaps = read_result(profile, "10_gap_sensitivity.csv", header=[0, 1], index_col=0)
    gaps.columns = [f"{mode}, {gravity}" for gravity, mode in gaps.columns]
    breaks = read_result(profile, "10_burst_breaks.csv").set_index("model")
    identified = read_result(profile, "10_identified.csv", index_col=0)
    return [
        "## Closing the loop on the twin (notebook 10)",
        "",
        "Table III extended: RMSE through the camera (mm) under `TYPICAL_GAP` with 33 ms camera latency, RF-FWD "
        "twin models, per loop mode (notebook 10 says what each is); `mean` is over the four shapes.",
        "",
        markdown(table),
        "",
        "References (of the four shapes and the burst) on which a mode is worse than the open loop:",
        "",
        markdown(worse),
        "",
        "Closed loop (`closed`) against camera latency (s) and lost frames, mean over the shapes (mm):",
        "",
        markdown(latency),
        "",
        "Each term of the reality gap doubled, mean over the shapes (mm):",
        "",
        markdown(gaps),
        "",
        "Where the loops break on the burst circle sped up to a 0.2 s period (the first "
        "revolution above 10 % of L; empty: never):",
        "",
        markdown(breaks),
        "",
        "System identification through the camera (relative errors of E, eta, rho; motor lag in s):",
        "",
        markdown(identified, 3),
        "",
    ]


def regime_summary(regimes: pd.DataFrame) -> str:
    """The regime map in words, generated: how many flow-vs-MLP tracking comparisons each side
    wins (both 95 % intervals, bootstrap and paired t, exclude zero), then per variant how many
    and by how much (the ranges of the differences); the table beside it has the bootstrap
    intervals."""
    clauses, totals = [], {"flow": 0, "MLP": 0, "none": 0}
    for variant, rows in regimes.groupby(level="variant", sort=False):
        differences = {"flow": [], "MLP": [], "none": []}
        for _, row in rows.iterrows():
            for family in ("shape", "random"):
                side = {0: "none", -1: "flow", 1: "MLP"}[stats.ranking(*stats.row_intervals(row, f"{family}_"))]
                differences[side].append((family, abs(row[f"{family}_mm"])))
        parts = [
            f"the {side} lower in {len(d)} ({_families_text(d)}, by {_range_text([v for _, v in d])} mm)"
            for side, d in differences.items()
            if side != "none" and d
        ]
        if differences["none"]:
            parts.append(f"{len(differences['none'])} without ranking")
        clauses.append(f"{variant}: " + ", ".join(parts))
        for side, d in differences.items():
            totals[side] += len(d)
    comparisons = sum(totals.values())
    return (
        f"Of {comparisons} comparisons of a flow with the MLP (tracking RMSE, z = 0 plans; variant x flow x "
        f"reference family), the flow is lower in {totals['flow']}, the MLP in {totals['MLP']}, and "
        f"{totals['none']} {'has' if totals['none'] == 1 else 'have'} no ranking (the bootstrap or the paired "
        "t-interval contains 0). "
        "By variant: " + "; ".join(clauses) + "."
    )


def _families_text(differences) -> str:
    """Which reference families some (family, difference) pairs cover, as words."""
    families = {family for family, _ in differences}
    return (
        "on both families"
        if len(families) == 2
        else {"shape": "on the shapes", "random": "on the random references"}[families.pop()]
    )


def _range_text(values, digits: int = 2) -> str:
    """ "a" or "a-b": the span of some positive numbers, as the words of a summary give it."""
    low, high = min(values), max(values)
    return f"{low:.{digits}f}" if round(low, digits) == round(high, digits) else f"{low:.{digits}f}-{high:.{digits}f}"


def _difference_text(estimate, low, high, digits: int = 2) -> pd.Series:
    """ "+d [low, high]" per row, from three aligned Series."""
    return pd.Series(
        [f"{d:+.{digits}f} [{lo:+.{digits}f}, {hi:+.{digits}f}]" for d, lo, hi in zip(estimate, low, high)],
        index=estimate.index,
    )


def _family_differences(frame: pd.DataFrame) -> dict:
    """ "<family> (mm)" -> "+d [low, high]" per row, from the columns <family>_mm, _low, _high."""
    return {
        f"{family} (mm)": _difference_text(*(frame[f"{family}_{k}"] for k in ("mm", "low", "high")))
        for family in ("shape", "random")
    }


def regime_map_rows(profile: Profile) -> pd.DataFrame:
    """The ambiguity study's rows and, as far as they are computed, the two_segment study's as two
    more variants of the regime map (``two_segment_variants``)."""
    return regime_rows(read_sweep(profile, "ambiguity"), computed_rows(profile, "two_segment"))


def where_flows_win_section(profile: Profile) -> list[str]:
    """The regime map with its paragraph, and what the prior and being generative each change
    with data size (notebook 09)."""
    regimes = regime_map(regime_map_rows(profile))
    table = pd.DataFrame(
        {
            "spread / floor (N)": [
                f"{a:.3f} / {b:.3f}" for a, b in zip(regimes["conditional_spread"], regimes["spread_floor"])
            ],
            **_family_differences(regimes),
            "per step (N)": _difference_text(regimes.step_N, regimes.step_low, regimes.step_high, 4),
        },
        index=regimes.index,
    )
    table = table.reset_index("flow").assign(flow=lambda t: t["flow"].map(LABELS))
    effects = size_effects(read_sweep(profile, "data_size"))
    by_size = _difference_text(effects.difference_mm, effects.low, effects.high).unstack("family")
    by_size = by_size[["shape", "random"]].reset_index("effect")
    return [
        "## Where a flow beats regression (notebook 09)",
        "",
        regime_summary(regimes),
        "",
        "Each flow minus the MLP per dataset variant, with the variant's conditional spread of u and its estimator "
        "floor: tracking RMSE paired over Table I's references (mean [95 % bootstrap interval] over seeds and "
        "references; the words above also need the paired t-interval) and the per-step u error on held-out "
        "transitions (interval over seeds). Below zero the flow's error is the smaller.",
        "",
        markdown(table),
        "",
        "What the physics prior and being generative each change, per training-set size (the model with minus "
        "the model without, mm):",
        "",
        markdown(by_size),
        "",
    ]


def consistency_weight_section(profile: Profile, taus=(0.05, 0.5)) -> list[str]:
    """RF-FWD's consistency weight against the shipped lambda = 1, the rule's choice, and what
    the term sees per weight at a small and a middle tau (notebook 11)."""
    diagnostics = read_result(profile, "11_fwd_lambda_diagnostics.csv", index_col=0)
    seen = pd.DataFrame(
        {
            "inverse u error (N)": diagnostics.u_rmse_test,
            "surrogate one-step tip error (mm)": diagnostics.forward_step_mm,
            **{
                f"u error at tau = {tau:g}, one step / Euler (N)": [
                    f"{a:.3f} / {b:.3f}"
                    for a, b in zip(
                        diagnostics[f"one_step_u_error_tau{tau:g}"], diagnostics[f"euler_u_error_tau{tau:g}"]
                    )
                ]
                for tau in taus
            },
        },
        index=diagnostics.index,
    )
    decision = lambda_decision(read_sweep(profile, "fwd_lambda"))[0]
    chosen = decision.index[decision["chosen"].astype(bool)]
    table = pd.DataFrame(_family_differences(decision))
    verdict = (
        f"lambda = {chosen[0]:g} is better on both families, so the default changes to it"
        if len(chosen)
        else "no weight is better than lambda = 1 on both families, so the default stays"
    )
    return [
        "## RF-FWD's consistency weight (notebook 11)",
        "",
        "Each lambda minus the shipped lambda = 1 (mm, paired over Table I's references); by the rule fixed before "
        f"the study ran (with both intervals, as every verdict here), {verdict}:",
        "",
        markdown(table),
        "",
        consistency_term_summary(diagnostics),
        "",
        "What the term sees on held-out transitions, per lambda (mean over seeds): the inverse's per-step u error, "
        "the frozen forward surrogate's one-step error, and the u error of the loss's one-step endpoint estimate "
        "xi_tau + (1 - tau) v beside a short Euler rollout from the same tau:",
        "",
        markdown(seen, 4),
        "",
    ]


def consistency_term_summary(diagnostics: pd.DataFrame, small: float = 0.05, middle: float = 0.5) -> str:
    """What RF-FWD's consistency term does, in words generated from notebook 11's diagnostics
    (indexed by lambda, 0 = RF): the inverse's per-step error per weight, the residual the term
    penalises against the surrogate's own error, and how crude the estimate it judges is."""
    weighted, rf, strongest = diagnostics[diagnostics.index > 0], diagnostics.loc[0.0], diagnostics.index.max()
    floor = diagnostics["residual_floor"].iloc[0]
    ratio = diagnostics[f"one_step_residual_tau{middle:g}"] / floor
    one_step, euler = diagnostics[f"one_step_u_error_tau{small:g}"], diagnostics[f"euler_u_error_tau{small:g}"]
    below = (
        " (below 1: the flow's estimate suits the surrogate's own error better than the true u does)"
        if ratio.min() < 1
        else ""
    )
    return (
        f"What the term does here: the inverse's per-step u error on held-out transitions is {rf.u_rmse_test:.4f} N "
        f"without the term (RF) and {' / '.join(f'{e:.4f}' for e in weighted.u_rmse_test)} N at lambda = "
        f"{' / '.join(f'{w:g}' for w in weighted.index)}. The term penalises the frozen surrogate's miss for the "
        f"one-step estimate of u; at the true u the surrogate already misses by a residual of {floor:.4f} "
        f"(normalised increment, RMS; its one-step tip error is {_range_text(diagnostics.forward_step_mm, 3)} mm). "
        f"The estimate's residual at tau = {middle:g} is {ratio.loc[0.0]:.2f} times that without the term and "
        f"{ratio.loc[strongest]:.2f} times at lambda = {strongest:g}{below}. At tau = {small:g} the one-step "
        f"estimate misses u by {_range_text(one_step, 4)} N, {_range_text(one_step / euler, 1)} times a short Euler "
        f"rollout from the same tau ({_range_text(euler, 4)} N): early on the path the term judges a cruder u than "
        f"the flow's own sampler gives."
    )


def design_choices(profile: Profile) -> list[str]:
    """The sweeps behind the defaults: baseline sizes (notebook 03), RF design at the short budget (04)."""
    sizes = read_result(profile, "baseline_sizes.csv").set_index("model")[
        ["size", "parameters", "rmse_shape_mm", "rmse_random_mm", "epochs"]
    ]
    design = read_result(profile, "design_sweep.csv")
    design = design.set_index(design.columns[0]).rename_axis("variant")  # the CSV's index column
    return [
        "## Design choices",
        "",
        "Baseline sizes, each with its model's full budget (notebook 03; the middle size is the default):",
        "",
        markdown(sizes),
        "",
        "RF design sweep, every variant at the short budget (the sequence models') "
        "(notebook 04; logit-normal tau and lambda = 1 are the defaults):",
        "",
        markdown(design),
        "",
    ]


def relative(lower_pct: float) -> str:
    """A reduction in percent as words: 12 -> '12 % lower', -5 -> '5 % higher'."""
    return f"{abs(lower_pct):.0f} % {'lower' if lower_pct >= 0 else 'higher'}"


def _change_text(change_pct: float, side: int) -> str:
    """A change in percent: in words where a ranking is stated (``side`` from stats.ranking),
    else signed, with 'no ranking'."""
    return relative(-change_pct) if side else f"{change_pct:+.0f} %, no ranking"


OBSERVED = {"tip": "the tip only", "tip+disk": "the tip and the middle disk"}


def two_segment_summary(differences: pd.DataFrame, computed: int, cells: int | None) -> str:
    """One paragraph: per observation and family, best RF variant minus best baseline with its
    interval and the rule's verdict, whichever way it comes out, and how many cells it rests on
    (of ``cells``, the grid's, where the profile has one)."""
    done = f"{computed} of the study's {cells} cells have rows" if cells else f"{computed} cells have rows"
    if differences.empty:
        return (
            f"On the two-segment rod no observation has rows of both an RF variant and a baseline yet ({done}; "
            "`softflow sweep two_segment --profile paper` computes the rest)."
        )
    parts = []
    for observation, table in differences.groupby(level="observation", sort=False):
        families = [
            f"{family} {row.difference_mm:+.2f} mm [{row.low:+.2f}, {row.high:+.2f}] "
            f"({LABELS.get(row.best_rf, row.best_rf)} against {LABELS.get(row.best_baseline, row.best_baseline)}: "
            f"{row.verdict})"
            for (_, family), row in table.iterrows()
        ]
        parts.append(f"observing {OBSERVED.get(observation, observation)}, " + "; ".join(families))
    return (
        "On the two-segment rod, the best RF variant minus the best baseline in tracking RMSE "
        f"(mean [95 % bootstrap interval]), {' and, '.join(parts)} ({done})."
    )


def two_segment_section(profile: Profile) -> list[str]:
    """The redundant rod (notebook 12): whether the RF family beats the best regression when four
    inputs reach one tip, from the study's rows as far as they are computed."""
    rows = computed_rows(profile, "two_segment")
    differences = two_segment_differences(rows)
    return [
        "## A two-segment rod: four inputs, one tip (notebook 12)",
        "",
        two_segment_summary(
            differences,
            rows["key"].nunique(),
            len(two_segment_cells(profile.name)) if profile.name in TWO_SEGMENT else None,
        ),
        "",
        *([markdown(differences), ""] if len(differences) else []),
    ]


def recorded_summary(needed: pd.DataFrame, best: pd.DataFrame, computed: int, cells: int | None) -> str:
    """One paragraph on the recorded study: per configuration and recording size, the better model
    of recordings minus the better open-loop simulator-trained RF-FWD with its interval and verdict
    (``recording_rule``), then per gap the best RF variant minus the best baseline
    (``recorded_model_rule``) and whether friction changes the winner; whichever way they come
    out, and how many cells they rest on."""
    done = f"{computed} of the study's {cells} cells have rows" if cells else f"{computed} cells have rows"
    if needed.empty and best.empty:
        return (
            f"On the twin's recordings no comparison has rows of both its sides yet ({done}; "
            "`softflow sweep recorded --profile paper` computes the rest)."
        )
    sentences = []
    if len(needed):
        sizes = [
            f"{gravity}, {runs} runs: {row.difference_mm:+.2f} mm [{row.low:+.2f}, {row.high:+.2f}] ({row.verdict})"
            for (gravity, runs), row in needed.iterrows()
        ]
        sentences.append(
            "Trained on the twin's recordings alone (motor commands in, the camera's tip out), the better of MLP "
            "and RF minus the better of the simulator-trained RF-FWD open and open-calibrated, in shape RMSE through "
            f"the camera under cable friction (mean [95 % bootstrap interval]): {'; '.join(sizes)}."
        )
    if len(best):
        gaps = [
            f"{gravity} under the {gap} gap {row.difference_mm:+.2f} mm [{row.low:+.2f}, {row.high:+.2f}] "
            f"({LABELS.get(row.best_rf, row.best_rf)} against {LABELS.get(row.best_baseline, row.best_baseline)}: "
            f"{row.verdict})"
            for (gravity, gap), row in best.iterrows()
        ]
        answers = {
            answer: sorted({gravity for (gravity, _), row in best.iterrows() if row.friction_changes == answer})
            for answer in ("yes", "no", "unanswered")
        }
        words = {
            "yes": "friction changes which model is best",
            "no": "friction leaves the same model best",
            "unanswered": "whether friction changes the best model is unanswered (a gap without a ranking)",
        }
        said = [f"{words[answer]} ({', '.join(where)})" for answer, where in answers.items() if where]
        sentences.append(
            f"Best RF variant minus best baseline on the most recording: {'; '.join(gaps)}; {'; '.join(said)}."
        )
    return " ".join(sentences) + f" ({done}.)"


def recorded_section(profile: Profile) -> list[str]:
    """Learning from recorded runs (notebook 13): how much recording a model needs to match the
    simulator-trained RF-FWD on the twin, and whether friction changes the best model."""
    rows = computed_rows(profile, "recorded")
    needed, best = recording_rule(rows), recorded_model_rule(rows)
    cells = len(recorded_cells(profile.name)) if profile.name in RECORDED else None
    return [
        "## Learning from recorded runs (notebook 13)",
        "",
        recorded_summary(needed, best, rows["key"].nunique(), cells),
        "",
        *([markdown(needed), ""] if len(needed) else []),
        *([markdown(best), ""] if len(best) else []),
    ]


def trunk_summary(tables: dict, computed: int, cells: int | None) -> str:
    """One paragraph on the real robot (notebook 14) from ``trunk.summarise``'s tables: how many
    cells have rows, whether the judge tells the training mean from the recorded inputs per family
    (the gate), each observation's best flow against its best baseline with the verdict, and the
    conditional spread over its floor, tip alone against every disk; whichever way they come out."""
    done = f"{computed} of the study's {cells} cells have rows" if cells else f"{computed} cells have rows"
    if not computed:
        return f"On the ASL trunk no cell has rows yet ({done}; `softflow sweep trunk --profile paper`)."
    check, rule, spread = tables["judge_check"], tables["flow_rule"], tables["spread"]
    gate = check[check.planner == trunk.GATE]
    told = [f"{row.family} {row.difference_mm:+.2f} mm [{row.low:+.2f}, {row.high:+.2f}]" for row in gate.itertuples()]
    passed = int(gate.tells_apart.sum())
    sentences = [
        f"On the ASL trunk's held-out runs ({done}), the forward judge puts the training-mean input above the recorded "
        f"inputs by {'; '.join(told)} (judged tip error, mm), telling them apart on {passed} of {len(gate)} families."
    ]
    for observation, part in rule.groupby("observation", sort=False) if len(rule) else ():
        said = [
            f"{row.family} {row.difference_mm:+.2f} mm [{row.low:+.2f}, {row.high:+.2f}] "
            f"({LABELS[row.best_flow]} against {LABELS[row.best_baseline]}: {row.verdict})"
            for row in part.itertuples()
        ]
        sentences.append(f"Best flow minus best baseline observing {observation}: {'; '.join(said)}.")
    if len(spread):
        ratios = [f"{observation} {row['spread / floor']:.1f}x" for observation, row in spread.iterrows()]
        sentences.append(f"The conditional spread of u over its estimator floor: {', '.join(ratios)}.")
    if cells and computed == cells and len(rule):
        sentences.append(trunk.answer_sentence(rule))
    return " ".join(sentences)


def trunk_section(profile: Profile) -> list[str]:
    """A real robot (notebook 14): the trunk study's verdicts from its rows as far as computed."""
    rows = computed_rows(profile, "trunk")
    tables = trunk.summarise(rows) if len(rows) else {}
    rule = tables.get("flow_rule", pd.DataFrame())
    cells = len(trunk.cells(profile.name)) if profile.name in trunk.TRUNK_GRID else None
    return [
        "## A real robot: the ASL trunk (notebook 14)",
        "",
        trunk_summary(tables, rows["key"].nunique(), cells),
        "",
        *([markdown(rule.set_index(["observation", "family"])), ""] if len(rule) else []),
        *(
            [
                "Asked again with two judges that never saw the run they score, validated before any planner row "
                f"(`trunk_v2`, notebook 14): {trunk_v2.answer(computed_rows(profile, 'trunk_v2'), profile.name)}",
                "",
            ]
            if profile.name in trunk_v2.GRID
            else []
        ),
    ]


def one_step_summary(tables: dict, computed: int, cells: int | None) -> str:
    """One paragraph on the one-step study (notebook 15) from ``one_step.summarise``'s tables:
    each rule's comparisons with their intervals and words, whichever way they come out, and
    what waits for cells without rows."""
    done = f"{computed} of the study's {cells} cells have rows" if cells else f"{computed} cells have rows"
    if not computed:
        return f"No cell of the one-step study has rows yet ({done}; `softflow sweep one_step --profile paper`)."

    def ratios(table: pd.DataFrame) -> str:
        return "; ".join(
            f"{label(row.model)} over {label(row.other)} on the {row.rod} rod's {row.family} references "
            f"{row.ratio:.2f}x [{row.low:.2f}, {row.high:.2f}] ({row.within_10_percent})"
            for row in table.itertuples()
        )

    sentences = [
        f"The one-step study ({done}; a plan is model@steps, the ratio's interval the two-way bootstrap paired over "
        f"references; within 10 % means the interval inside [{one_step.BAND[0]}, {one_step.BAND[1]}])."
    ]
    if len(tables["parity"]):
        sentences.append(f"Parity, a one-step flow at 1 step over its parent at 4: {ratios(tables['parity'])}.")
    if len(tables["collapse"]):
        sentences.append(f"The collapse, a flow in 1 Euler step over the MLP: {ratios(tables['collapse'])}.")
    win = tables["tip_win"]
    if len(win):
        said = [
            f"{label(row.model)} minus {label(row.other)} on the {row.family} references {row.difference_mm:+.2f} mm "
            f"[{row.low:+.2f}, {row.high:+.2f}] ({row.verdict})"
            for row in win.itertuples()
        ]
        sentences.append(f"The tip-alone win on the two-segment rod: {'; '.join(said)}.")
    else:
        sentences.append("The tip-alone win on the two-segment rod waits for that rod's cells.")
    return " ".join(sentences)


def one_step_section(profile: Profile) -> list[str]:
    """A flow in one step (notebook 15): the one-step study's rules from its rows as far as computed."""
    rows = computed_rows(profile, "one_step")
    tables = one_step.summarise(rows) if len(rows) else {}
    cells = len(one_step.cells(profile.name)) if profile.name in one_step.ONE_STEP else None
    rmse = pd.DataFrame()
    if tables:
        counts = {column: tables["rmse"][column].astype(int).astype(str) for column in ("seeds", "references")}
        rmse = tables["rmse"].assign(**counts).set_index(["rod", "family", "model"])  # counts without ".00"
    return [
        "## A flow in one step (notebook 15)",
        "",
        one_step_summary(tables, rows["key"].nunique(), cells),
        "",
        *([markdown(rmse), ""] if len(rmse) else []),
    ]


def portability_section(profile: Profile) -> list[str]:
    """Which numbers are the same on every CPU and which move, and by how much (make portability)."""
    bench = profile.output_dir / "bench"
    runs, spread = bench / "portability.csv", bench / "portability_spread.csv"
    lines = [
        "## Numbers across CPUs",
        "",
        "Exact on every CPU, because they are read, not computed: every table of the studies (notebooks 08-14 read "
        "`figures/sweeps/*-paper.csv`, the design sweep of notebook 04 too), the shipped references and static "
        "tables (`cache/`). Computed from the shipped weights by a rollout (Tables I-III, the stress tables of "
        "notebook 05): the same weights give the same plans, and the rollout's arithmetic moves their last bits only. "
        "What moves is what is trained or simulated on your machine (a fresh clone's ci datasets and ci models, "
        "a model you train): a CPU's `exp`, vector width or BLAS changes the last bits of the data, and training "
        "carries them on. `make portability` runs `make test` under forced kernel paths; the notebooks compare such "
        'numbers within a tolerance set by that spread (docs/assumptions.md, "Numbers across CPUs").',
        "",
    ]
    if runs.exists():
        table = pd.read_csv(runs)[["path", "kernels", "passed", "test_minutes", "largest_share_of_tolerance"]]
        lines += [
            f"`make test` on fresh clones (`figures/bench/{runs.name}`):",
            "",
            markdown(table.set_index("path"), 4),
            "",
        ]
    if spread.exists():
        moved = pd.read_csv(spread)
        if len(moved):
            largest = moved.pivot_table(index="file", columns="path", values="largest_relative_difference")
            lines += [
                "The ci results trained under each forced path against the native ones, largest relative difference "
                f"of any number per file (`figures/bench/{spread.name}`):",
                "",
                markdown(largest.loc[largest.max(axis=1).sort_values(ascending=False).index], 6),
                "",
            ]
    return lines


def machines_section(profile: Profile) -> list[str]:
    """Which CPUs computed each study's shipped rows: a table that mixes machines says so here
    (CPUs differ in the last bits of what they train, docs/assumptions.md)."""
    counts = {
        path.name.removesuffix(f"-{profile.name}.csv"): machine_counts(pd.read_csv(path, low_memory=False))
        for path in sorted((profile.output_dir / "sweeps").glob(f"*-{profile.name}.csv"))
    }
    if not counts:
        return []
    said = {study: ", ".join(f"{m} ({n} row{'s' * (n != 1)})" for m, n in c.items()) for study, c in counts.items()}
    table = pd.Series(said, name="machines").rename_axis("study").to_frame()
    mixed = [study for study, c in counts.items() if len(c) > 1]
    return [
        "## Where the rows were computed",
        "",
        "The CPU of each study's shipped rows, as the rows record it (`machine`; rows made before that column "
        f"was added say unknown). Tables that mix rows of different or unknown machines: {', '.join(mixed) or 'none'}.",
        "",
        markdown(table),
        "",
    ]


def results_page(profile: Profile, tables: dict, run_dir: Path) -> str:
    """docs/results.md: machine, commit, wall times, Tables I-IV, the paper's claims, key figures."""
    times = recorded_wall_times(run_dir, profile.output_dir / "bench" / WALL_TIMES)
    lines = [
        "# Results (paper profile)",
        "",
        "Generated by `notebooks/07_comparison_tables.ipynb` from the CSV results of notebooks 03-06 and 08-15 and "
        "the studies' rows in `figures/sweeps/` (`make reproduce`). Do not edit by hand.",
        "",
        f"- Machine: {description()}",
        f"- Commit: {commit()}",
        f"- Generated: {pd.Timestamp.now(tz='UTC').strftime('%Y-%m-%d %H:%M UTC')}",
        "- Training minutes are the wall times recorded in each checkpoint; they grow when other jobs share the cores.",
        "",
        "## Wall time per notebook (`make reproduce`, data and checkpoints cached)",
        "",
        *(
            [
                f"Each notebook's last timed run of this profile (`figures/bench/{WALL_TIMES}`); a run of some "
                "notebooks replaces only their rows, so the machine and commit are given per row.",
                "",
                markdown(times, 1),
                "",
                f"Total: {times.minutes.sum():.1f} min.",
            ]
            if len(times)
            else ["(no papermill run found)"]
        ),
        "",
    ]
    titles = {
        "table1_tracking": "Table I - open-loop tracking RMSE (mm), shapes / random references",
        "table2_inputs": "Table II - phase lag on shapes (s), input energy on random references (N^2 s)",
        "table3_hardware": "Table III - hardware-twin tracking RMSE through the camera (mm)",
        "table4_literature": "Table IV - comparison with the literature",
    }
    for name, title in titles.items():
        lines += [f"## {title}", "", tables[name], ""]
    lines += ranking_rule_section(profile)
    lines += trust_section(profile)
    lines += closed_loop_section(profile)
    lines += where_flows_win_section(profile)
    lines += consistency_weight_section(profile)
    lines += two_segment_section(profile)
    lines += recorded_section(profile)
    lines += trunk_section(profile)
    lines += one_step_section(profile)
    lines += machines_section(profile)
    lines += portability_section(profile)
    lines += ["## The paper's claims, reproduced or not", "", markdown(claims(profile)), ""]
    lines += design_choices(profile)
    lines += ["## Key figures", ""]
    lines += [
        f"### {caption}\n\n![{caption}](../figures/{name})\n"
        for caption, name in FIGURES
        if (profile.output_dir / name).exists()
    ]
    return "\n".join(lines).rstrip() + "\n"
