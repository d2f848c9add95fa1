"""The studies' sections, the one writer of their words: each study's question, rule and answer
live in one Jinja partial (``templates/studies/<study>.md.j2``), filled from its verdict tables
(computed here from the shipped rows and result files); the results page renders each section
whole (``templates/section.md.j2``: question, rule and its commit, answer, one table, one
figure), the README's result block its answer on one line beside the headline table."""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import pandas as pd

from softflow.models.specs import label
from softflow.profiles import Profile
from softflow.report.study_tables import (
    ROTATED_PATHS,
    best_against_best,
    interval_text,
    lambda_decision,
    recorded_model_rule,
    recording_rule,
    regime_map,
    regime_rows,
    size_effects,
    table_order,
    two_segment_differences,
    with_ci,
)
from softflow.report.tables import BASELINES, LABELS, RF_FAMILY, computed_rows, markdown, read_result, read_sweep
from softflow.studies import loop, one_step, stats, trunk, trunk_v2
from softflow.studies.catalogue import STUDIES
from softflow.studies.study import FLOOR

TEMPLATES = Path(__file__).with_name("templates")
SETTING, FOLDED = "paper", "folded"  # the regime map's variants the ambiguity answer names
FLOOR_LABEL = "ILC floor (true simulator, an upper bound)"
OBSERVED = {"tip": "seen at the tip alone", "tip+disk": "seen at the tip and the middle disk"}
FAMILY_ORDER = {"shape": 0, "random": 1}  # the order the words list families in
RECORDING_SIDES = ("recordings", "simulator")  # the recording rule's a and b in words
ROTATED_WORDS = "not ranked: one path in three rotations"
TRUNK_UNJUDGED = f"no ranking (the judge does not tell the {trunk.GATE} input from the recorded inputs)"
TRUNK_V2_UNJUDGED = (
    "not judged (a judge separates no perturbation here, or rates a known-worse input below the recorded)"
)


def trunk_v2_verdict(row) -> str:
    """The trunk_v2 rule's answer on one comparison (``trunk_v2.flow_rule``'s ``rule_lower``) in words."""
    if pd.isna(row.resolution_mm):
        return TRUNK_V2_UNJUDGED
    return f"{label(row.rule_lower)} lower" if isinstance(row.rule_lower, str) else "not resolved by the judges"


@dataclass(frozen=True)
class Section:
    """One study's section: its partial's name (and the page's anchor), title, notebook, the
    numbers its words read (``context``), its one table and its one figure (under figures/)."""

    study: str
    title: str
    context: dict
    table: pd.DataFrame = field(default_factory=pd.DataFrame)
    digits: int = 2
    figure: str = ""

    @property
    def notebook(self) -> str:
        return STUDIES[self.study].notebook.split("_")[0]

    @property
    def fixed_in(self) -> str:
        return STUDIES[self.study].fixed_in


def environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(TEMPLATES),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def words(section: Section, part: str) -> str:
    """The partial's ``part`` ("question", "rule" or "answer") of a section, on one line."""
    macro = getattr(environment().get_template(f"studies/{section.study}.md.j2").module, part)
    return " ".join(str(macro(section.context)).split())


def rendered(section: Section, figures: Path, width: int = 110) -> str:
    """The section as the results page shows it (its figure where ``figures`` holds it), its
    paragraphs filled to ``width`` columns."""
    text = (
        environment()
        .get_template("section.md.j2")
        .render(
            s=section,
            question=words(section, "question"),
            rule=words(section, "rule"),
            answer=words(section, "answer"),
            table=table_text(section),
            figure=bool(section.figure) and (figures / section.figure).exists(),
        )
    )
    return filled(text, width)


def result_block(profile: Profile) -> str:
    """The README's result block (without its markers): Table I with its answer, then each other
    study's answer on one line, linking to its section of the results page."""
    first, *others = sections(profile)
    context = dict(
        headline=dict(answer=words(first, "answer"), table=table_text(first)),
        studies=[dict(study=s.study, title=s.title, answer=words(s, "answer")) for s in others],
    )
    return environment().get_template("result.md.j2").render(**context).strip()


def filled(markdown_text: str, width: int = 110) -> str:
    """Each paragraph refilled to ``width`` columns; tables, headings, images, anchors and lists kept."""
    kept = ("|", "#", "!", "<", "- ")
    paragraphs = [p.strip() for p in markdown_text.strip().split("\n\n") if p.strip()]
    return "\n\n".join(
        p if p.startswith(kept) else textwrap.fill(" ".join(p.split()), width, break_on_hyphens=False)
        for p in paragraphs
    )


# ---------------------------------------------------------------------------- numbers as the words read them
def verdict(row, sides=None) -> str:
    """A comparison of a verdict table (``stats.COMPARISON``'s columns) in words, the only place
    they are made: "<lower side> lower", "... (not after Holm)" where the family-wise view removes
    that ranking, or "no ranking"; ``sides`` names a and b (default: the models' labels)."""
    if not isinstance(row.lower, str) and pd.isna(row.lower):
        return "no ranking"
    names = dict(zip((row.a, row.b), sides or (label(row.a), label(row.b))))
    words = f"{names[row.lower]} lower"
    return words if row.kept_after_holm else f"{words} (not after Holm)"


def numbers(row) -> dict:
    """A comparison's estimate and bootstrap interval as the partials print them."""
    return dict(mm=f"{row.estimate:+.2f}", interval=f"[{row.low:+.2f}, {row.high:+.2f}]")


def difference(row, sides=None) -> dict:
    """A verdict table's comparison as the partials read it: ``numbers`` and its words (``verdict``)."""
    return dict(numbers(row), verdict=verdict(row, sides))


def compared_text(table: pd.DataFrame, sides=None) -> list[str]:
    """ "+d [low, high] (verdict)" per comparison of a verdict table."""
    return ["{mm} {interval} ({verdict})".format(**difference(row, sides)) for row in table.itertuples()]


def with_words(table: pd.DataFrame, sides=None) -> pd.DataFrame:
    """A verdict table as a section shows it: its judgement's columns in words (``verdict``)."""
    words = [verdict(row, sides) for row in table.itertuples()]
    return table.drop(columns=["p", "lower", "kept_after_holm"]).assign(verdict=words)


def span(values, form: str = "{:+.2f}", joint: str = " to ") -> str:
    """ "a to b" over ``values`` in ``form`` (one value: itself; ``joint`` "-" makes "a-b")."""
    low, high = form.format(min(values)), form.format(max(values))
    return low if low == high else f"{low}{joint}{high}"


def tally(verdicts) -> str:
    """How often each verdict occurs, most often first: "no ranking in 3 of 4, ..."."""
    counts = pd.Series(list(verdicts)).value_counts()
    return ", ".join(f"{word} in {n} of {counts.sum()}" for word, n in counts.items())


def progress(profile: Profile, study: str, rows: pd.DataFrame) -> dict:
    """How many of the profile's cells of ``study`` have rows (``cells`` None: a profile the study
    has no grid for, whose rows are complete when there are any) and whether that is all."""
    computed = int(rows["key"].nunique()) if len(rows) else 0
    try:
        cells = len(STUDIES[study].cells(profile.name))
    except KeyError:  # the study's grids are by profile name
        cells = None
    return dict(computed=computed, cells=cells, complete=computed > 0 and computed == (cells or computed))


# ---------------------------------------------------------------------------- one builder per study
def table1_section(profile: Profile) -> Section:
    rows = read_sweep(profile, "table1")
    summaries = {family: with_ci(rows, "rmse_mm", family) for family in ("shape", "random")}
    models = [m for m in summaries["shape"].index if m != FLOOR]
    ratios = [summaries[f].loc[m, "mean"] / summaries[f].loc[FLOOR, "mean"] for f in summaries for m in models]
    differences = best_against_best(rows)
    change = {
        d.family: 100 * (summaries[d.family].loc[d.a, "mean"] / summaries[d.family].loc[d.b, "mean"] - 1)
        for d in differences.itertuples()
    }
    rf_lower = [d.lower == d.a and d.kept_after_holm for d in differences.itertuples()]
    table = pd.DataFrame({f: interval_text(s) for f, s in summaries.items()})
    table = table.reindex(table_order(table.index)).rename(index={**LABELS, FLOOR: FLOOR_LABEL})
    table.columns = ["shapes", "random references"]
    context = dict(
        reproduces=all(rf_lower) and all(c <= -50 for c in change.values()),
        differences={
            d.family: dict(best_rf=label(d.a), best_baseline=label(d.b), **difference(d))
            for d in differences.itertuples()
        },
        above_floor=f"{min(ratios):.0f}-{max(ratios):.0f}",
    )
    title = "Table I with 95 % intervals and the floor"
    return Section("table1", title, context, table.rename_axis("model"), figure="08_table1_ci.png")


def protocol_section(profile: Profile) -> Section:
    protocol = read_result(profile, "08_protocol.csv").set_index("condition")
    flows, baselines = protocol.reindex(columns=RF_FAMILY).stack(), protocol.reindex(columns=BASELINES).stack()
    context = dict(flows=span(flows, "{:.1f}"), baselines=span(baselines, "{:.1f}"))
    table = protocol.rename(columns=LABELS)
    return Section("protocol", "The evaluation protocol's effect", context, table, figure="08_protocol.png")


def regime_map_rows(profile: Profile) -> pd.DataFrame:
    """The ambiguity study's rows and, as far as computed, the two_segment study's as two more variants."""
    return regime_rows(read_sweep(profile, "ambiguity"), computed_rows(profile, "two_segment"))


def ambiguity_section(profile: Profile) -> Section:
    regimes = regime_map(regime_map_rows(profile))
    tracked = regimes[regimes.family.isin(("shape", "random"))]
    sides = [stats.lower_side(row) for row in tracked.itertuples()]

    def named(variant: str) -> tuple[str, str]:
        part = tracked[tracked.variant == variant].sort_values(
            "family", key=lambda f: f.map(FAMILY_ORDER), kind="stable"
        )
        return span(part.estimate), tally(verdict(row) for row in part.itertuples())

    (folded, folded_tally), (setting, setting_tally) = named(FOLDED), named(SETTING)
    context = dict(
        folded=folded,
        folded_tally=folded_tally,
        setting=setting,
        setting_tally=setting_tally,
        comparisons=len(sides),
        flow_lower=sides.count(-1),
        mlp_lower=sides.count(1),
        unranked=sides.count(0),
        removed_by_holm=int((tracked.lower.notna() & ~tracked.kept_after_holm).sum()),
    )
    shown = tracked.assign(compared=compared_text(tracked), flow=tracked.a.map(label))
    table = shown.pivot(index=["variant", "flow"], columns="family", values="compared")
    spread = shown.groupby(["variant", "flow"], sort=False)[["conditional_spread", "spread_floor"]].first()
    table = pd.DataFrame(
        {
            "spread / floor (N)": [
                f"{a:.3f} / {b:.3f}" for a, b in zip(spread.conditional_spread, spread.spread_floor)
            ],
            **{f"{f} (mm)": table.loc[spread.index, f] for f in ("shape", "random")},
        },
        index=spread.index,
    )
    return Section(
        "ambiguity", "Where a flow beats regression", context, table.reset_index("flow"), figure="09_regime_map.png"
    )


def data_size_section(profile: Profile) -> Section:
    effects = size_effects(read_sweep(profile, "data_size"))
    context = dict(comparisons=len(effects), tally=tally(verdict(row) for row in effects.itertuples()))
    shown = effects.assign(compared=compared_text(effects))
    table = shown.pivot(index=["episodes", "effect"], columns="family", values="compared")[["shape", "random"]]
    table = table.reindex(list(dict.fromkeys(zip(effects.episodes, effects.effect))))
    title = "The prior or being generative, by data size"
    return Section("data_size", title, context, table.reset_index("effect"), figure="09_data_size.png")


def fwd_lambda_section(profile: Profile) -> Section:
    decision, chosen = lambda_decision(read_sweep(profile, "fwd_lambda"))
    context = dict(chosen=None if chosen == 1.0 else f"{chosen:g}")
    shown = decision.assign(
        compared=["{mm} {interval}".format(**numbers(row)) for row in decision.itertuples()],
        consistency=decision.a,
    )
    table = shown.pivot(index="consistency", columns="family", values="compared")[["shape", "random"]]
    better = decision.groupby("a").better_on_both.first().map({True: "yes", False: "no"})
    table = table.rename(columns=lambda f: f"{f} (mm)").assign(**{"better on both": better})
    return Section("fwd_lambda", "RF-FWD's consistency weight", context, table, figure="11_fwd_lambda.png")


def closed_loop_section(profile: Profile) -> Section:
    table = read_result(profile, "10_table3_extended.csv").set_index(["gravity", "reference"])
    means = table.xs("mean", level="reference").reindex(["vertical", "horizontal"])

    def both(mode: str) -> str:
        return " / ".join(f"{value:.2f}" for value in means[mode])

    context = dict(open=both("open"), closed=both("closed"), best=both("closed-ilc-calibrated"))
    return Section("closed_loop", "Closing the loop on the twin", context, table, figure="10_open_closed.png")


def two_segment_section(profile: Profile) -> Section:
    rows = computed_rows(profile, "two_segment")
    differences = two_segment_differences(rows)
    observations = [
        dict(
            words=OBSERVED.get(observation, observation),
            families=[
                dict(family=row.family, **difference(row))
                for row in part.itertuples()
                if row.family in ("shape", "random")
            ],
        )
        for observation, part in differences.groupby("observation", sort=False)
    ]
    context = dict(observations=observations, **progress(profile, "two_segment", rows))
    title = "A two-segment rod: four inputs, one tip"
    table = with_words(differences).set_index(["observation", "family"])
    table.loc[table.index.get_level_values("family") == ROTATED_PATHS, "verdict"] = ROTATED_WORDS
    return Section("two_segment", title, context, table, figure="12_tracking.png")


def recorded_section(profile: Profile) -> Section:
    rows = computed_rows(profile, "recorded")
    needed, best = recording_rule(rows), recorded_model_rule(rows)
    context = dict(
        needed_count=len(needed),
        needed=span(needed.estimate) if len(needed) else "",
        needed_tally=tally(verdict(row, RECORDING_SIDES) for row in needed.itertuples()),
        best_count=len(best),
        best=span(best.estimate) if len(best) else "",
        best_tally=tally(verdict(row) for row in best.itertuples()),
        friction={
            answer: where
            for answer in ("yes", "no", "unanswered")
            if (where := sorted(set(best.gravity[best.friction_changes == answer])))
        },
        **progress(profile, "recorded", rows),
    )
    title = "Learning from recorded runs"
    table = with_words(needed, RECORDING_SIDES).set_index(["gravity", "runs"])
    return Section("recorded", title, context, table, figure="13_recording.png")


def trunk_section(profile: Profile) -> Section:
    rows = computed_rows(profile, "trunk")
    rule = trunk.summarise(rows)["flow_rule"] if len(rows) else pd.DataFrame()
    answer = trunk.ANSWERS[trunk.notebook_12_answer(rule)] if len(rule) else ""
    context = dict(answer=answer, **progress(profile, "trunk", rows))
    table = with_words(rule).set_index(["observation", "family"]) if len(rule) else rule
    if len(rule):
        table.loc[~table.pop("judge_passes").to_numpy(bool), "verdict"] = TRUNK_UNJUDGED
    return Section("trunk", "A real robot: the ASL trunk", context, table, figure="14_judged.png")


def trunk_v2_section(profile: Profile) -> Section:
    rows = computed_rows(profile, "trunk_v2")
    rule = trunk_v2.flow_rule(rows) if len(rows) else pd.DataFrame()
    answer = trunk_v2.ANSWERS[trunk_v2.notebook_12_answer(rule)]
    context = dict(answer=answer, **progress(profile, "trunk_v2", rows))
    table = rule
    if len(rule):
        table = with_words(rule).set_index(["observation", "family", "judge"]).drop(columns="rule_lower")
        table = table.rename(columns={"verdict": "this judge"}).assign(
            rule=[trunk_v2_verdict(r) for r in rule.itertuples()]
        )
    title = "The ASL trunk asked again"
    return Section("trunk_v2", title, context, table, figure="14_v2_resolution.png")


def one_step_section(profile: Profile) -> Section:
    rows = computed_rows(profile, "one_step")
    tables = one_step.summarise(rows) if len(rows) else {}

    def ratios(table: pd.DataFrame) -> dict:
        if table.empty:
            return dict(range="no comparison yet", tally="none")
        return dict(range=f"{span(table.ratio, '{:.2f}')}x", tally=tally(table.within_10_percent))

    win = tables.get("tip_win", pd.DataFrame())
    context = dict(
        parity=ratios(tables.get("parity", pd.DataFrame())),
        collapse=ratios(tables.get("collapse", pd.DataFrame())),
        tip_win=[dict(model=label(row.a), family=row.family, **difference(row)) for row in win.itertuples()],
        **progress(profile, "one_step", rows),
    )
    table = pd.DataFrame()
    if tables:
        counts = {column: tables["rmse"][column].astype(int).astype(str) for column in ("seeds", "references")}
        table = tables["rmse"].assign(**counts).set_index(["rod", "family", "model"])  # counts without ".00"
    return Section("one_step", "A flow in one step", context, table, figure="15_one_step.png")


def loop_section(profile: Profile) -> Section:
    rows = computed_rows(profile, "loop")
    rule = loop.summarise(rows)["rule"] if len(rows) else pd.DataFrame()
    models = [
        dict(label=label(row.model), ratio=f"{row.ratio:.2f} [{row.low:.2f}, {row.high:.2f}]")
        for row in rule.itertuples()
    ]
    met = [label(row.model) for row in rule.itertuples() if row.met]
    context = dict(goal=f"{loop.GOAL:g}", models=models, met=met, **progress(profile, "loop", rows))
    table = rule.set_index("model") if len(rule) else rule
    return Section("loop", "The loop of a model of recorded runs", context, table, 3, figure="16_loop.png")


BUILDERS = (
    table1_section,
    protocol_section,
    ambiguity_section,
    data_size_section,
    fwd_lambda_section,
    closed_loop_section,
    two_segment_section,
    recorded_section,
    trunk_section,
    trunk_v2_section,
    one_step_section,
    loop_section,
)


def sections(profile: Profile) -> list[Section]:
    """Every study's section, in the order of the notebooks."""
    return [build(profile) for build in BUILDERS]


def table_text(section: Section) -> str:
    """The section's table as markdown ("" for an empty one)."""
    return markdown(section.table, section.digits) if len(section.table) else ""
