"""docs/results.md (``results_page``): Tables I-IV, when a ranking is stated, each study's
section (``sections``: question, rule, answer, one table, one figure), where the rows were
computed, the claims checked, the design choices and the other key figures."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from softflow.machine import description
from softflow.profiles import Profile
from softflow.report.provenance import commit, recorded_wall_times
from softflow.report.sections import environment, filled, regime_map_rows, rendered, sections, span, verdict
from softflow.report.study_tables import (
    best_against_best,
    floor_progress,
    lambda_decision,
    regime_map,
    size_effects,
    verdict_counts,
)
from softflow.report.tables import (
    BASELINES,
    RF_FAMILY,
    machine_counts,
    markdown,
    our_table,
    read_result,
    read_sweep,
)
from softflow.studies.study import FLOOR
from softflow.studies.table1 import TABLE1

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


def claims(profile: Profile) -> dict:
    """The numbers the paper's headline claims are checked with (``templates/claims.md.j2``),
    each from a result CSV (notebook 08 for the intervals, floor and protocol). The
    best-against-best claim rests on the table1 study's seeds alone, its change and its
    difference alike."""
    burst = read_result(profile, "stress_burst.csv").set_index("model").loc["rf-fwd"]
    complex3d = read_result(profile, "stress_complex3d.csv").query("model == 'rf-fwd'")
    gaps = read_result(profile, "twin_sensitivity.csv")
    gaps = gaps.set_index(gaps.columns[0])  # the CSV's index column: the gap variant
    doubled = ["no gap", "typical gap", "2 x youngs_modulus", "2 x density"]
    closed = read_result(profile, "10_table3_extended.csv").set_index(["gravity", "reference"]).xs("mean", level=1)
    summary = read_result(profile, "08_table1_ci.csv").set_index(["family", "model"])["mean"]
    seeds = read_sweep(profile, "table1")
    improving, references = floor_progress(seeds, TABLE1[profile.name].ilc_iterations)
    protocol = read_result(profile, "08_protocol.csv").set_index("condition")
    models = summary.drop(index=FLOOR, level="model")
    families = ("shape", "random")
    return dict(
        best=[
            dict(
                d._asdict(),
                change=100 * (summary.loc[(d.family, d.a)] / summary.loc[(d.family, d.b)] - 1),
                ranked=isinstance(d.lower, str),
                verdict=verdict(d),
            )
            for d in best_against_best(seeds).itertuples()
        ],
        seeds=seeds.loc[seeds.model != FLOOR, "seed"].nunique(),
        above_floor={f: span_of(models.loc[f] / summary.loc[(f, FLOOR)]) for f in families},
        floor={f: summary.loc[(f, FLOOR)] for f in families},
        improving=improving,
        references=references,
        rf_fwd=our_table(profile).loc["rf-fwd"],
        protocol=dict(
            flows=span_of(protocol.reindex(columns=RF_FAMILY).stack()),
            baselines=span_of(protocol.reindex(columns=BASELINES).stack()),
        ),
        burst=burst,
        complex3d=dict(u1=complex3d.mae_u1.mean(), u2=complex3d.mae_u2.mean()),
        twin=read_result(profile, "table3_twin.csv").set_index("reference").loc["mean"],
        gaps=dict(
            no_gap=gaps.loc["no gap"],
            youngs_modulus=gaps.loc["2 x youngs_modulus", "horizontal"],
            density=gaps.loc["2 x density", "horizontal"],
            other=gaps.drop(index=doubled).horizontal.max(),
        ),
        closed=closed["closed-ilc-calibrated"],
        latency=read_result(profile, "euler_sweep.csv").set_index("steps").latency_ms.loc[4],
    )


def span_of(values) -> tuple[float, float]:
    return float(np.min(values)), float(np.max(values))


def claims_list(profile: Profile, width: int = 110) -> str:
    """The claims as a list (``templates/claims.md.j2``), one item each (the paper's number, ours,
    what the measurements say), filled to ``width`` columns."""
    text = environment().get_template("claims.md.j2").render(c=claims(profile), relative=relative)
    return "\n".join(
        textwrap.fill(" ".join(item.split()), width, subsequent_indent="  ", break_on_hyphens=False)
        for item in text.strip().split("\n")
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
        '<a id="ranking"></a>',
        "",
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


def consistency_term_summary(diagnostics: pd.DataFrame, small: float = 0.05, middle: float = 0.5) -> str:
    """What RF-FWD's consistency term does, in words generated from notebook 11's diagnostics
    (indexed by lambda, 0 = RF): the inverse's per-step error per weight, the residual the term
    penalises against the surrogate's own error, and how crude the estimate it judges is."""
    weighted, rf, strongest = diagnostics[diagnostics.index > 0], diagnostics.loc[0.0], diagnostics.index.max()
    floor = diagnostics["residual_floor"].iloc[0]
    ratio = diagnostics[f"one_step_residual_tau{middle:g}"] / floor
    one_step, euler = diagnostics[f"one_step_u_error_tau{small:g}"], diagnostics[f"euler_u_error_tau{small:g}"]
    spans = {  # "a-b", as notebook 11 prints them
        name: span(values, f"{{:.{digits}f}}", "-")
        for name, values, digits in (
            ("tip", diagnostics.forward_step_mm, 3),
            ("one_step", one_step, 4),
            ("times", one_step / euler, 1),
            ("euler", euler, 4),
        )
    }
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
        f"(normalised increment, RMS; its one-step tip error is {spans['tip']} mm). "
        f"The estimate's residual at tau = {middle:g} is {ratio.loc[0.0]:.2f} times that without the term and "
        f"{ratio.loc[strongest]:.2f} times at lambda = {strongest:g}{below}. At tau = {small:g} the one-step "
        f"estimate misses u by {spans['one_step']} N, {spans['times']} times a short Euler "
        f"rollout from the same tau ({spans['euler']} N): early on the path the term judges a cruder u than "
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
    shown = []
    for section in sections(profile):
        lines += [rendered(section, profile.output_dir), ""]
        shown.append(section.figure)
    lines += machines_section(profile)
    lines += portability_section(profile)
    lines += ["## The paper's claims, reproduced or not", "", claims_list(profile), ""]
    lines += design_choices(profile)
    lines += ["## Key figures", ""]
    lines += [
        f"### {caption}\n\n![{caption}](../figures/{name})\n"
        for caption, name in FIGURES
        if name not in shown and (profile.output_dir / name).exists()
    ]
    return "\n".join(filled(line) for line in lines).rstrip() + "\n"
