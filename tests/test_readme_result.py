"""The README's result block is generated from the shipped study rows: a hand edit, a stale
number or a ranking the rule does not allow shows up here as a difference."""

import pandas as pd
import pytest

from softflow.profiles import get_profile
from softflow.report import readme, sections
from softflow.store import REPO


def test_the_committed_block_is_what_the_shipped_rows_make():
    text = (REPO / "README.md").read_text()
    block = readme.result_block(get_profile("paper"))
    assert readme.with_block(text, block) == text, "README.md's result block is stale: run `make readme`"


def test_the_block_is_table_i_and_one_line_per_study_linking_to_its_section():
    block = readme.result_block(get_profile("paper")).splitlines()
    assert len(block) - 2 <= 25  # the markers aside
    studies = [line for line in block if line.startswith("- **")]
    linked = [s.study for s in sections.sections(get_profile("paper"))[1:]]
    assert [line.rsplit("#", 1)[1].removesuffix("))") for line in studies] == linked


def test_a_block_replaces_only_what_lies_between_the_markers():
    text = f"intro\n{readme.BEGIN}\nold words\n{readme.END}\nrest\n"
    assert readme.with_block(text, "NEW") == "intro\nNEW\nrest\n"
    for broken in ("no markers", f"{readme.END}\n{readme.BEGIN}", f"{readme.BEGIN}{readme.BEGIN}{readme.END}"):
        with pytest.raises(ValueError, match="once each"):
            readme.with_block(broken, "NEW")


def test_the_words_are_made_from_the_judgement():
    """A comparison is quoted in the words its judgement makes: a ranking Holm removes is printed
    so, none ranks nothing, and ``sides`` names a study's two sides."""
    table = pd.DataFrame(
        dict(
            a=["rf", "rf-fwd", "rf"],
            b=["mlp", "lstm", "mlp"],
            estimate=[-1.234, 0.5, 2.0],
            low=[-2.0, -0.1, 1.0],
            high=[-0.5, 1.2, 3.0],
            lower=["rf", None, "mlp"],
            kept_after_holm=[False, False, True],
        )
    )
    words = [sections.difference(row) for row in table.itertuples()]
    assert [w["verdict"] for w in words] == ["RF lower (not after Holm)", "no ranking", "MLP lower"]
    assert (words[0]["mm"], words[0]["interval"]) == ("-1.23", "[-2.00, -0.50]")
    assert sections.verdict(next(table.iloc[2:].itertuples()), ("recordings", "simulator")) == "simulator lower"


def test_the_committed_speed_block_is_what_the_bench_csvs_make():
    text = (REPO / "README.md").read_text()
    block = readme.speed_block(REPO / "figures" / "bench")
    assert readme.with_block(text, block, readme.SPEED_BEGIN, readme.SPEED_END) == text, (
        "README.md's speed block is stale: run `make readme`"
    )


def _bench_csv(path, quantities: dict) -> None:
    pd.DataFrame(
        dict(quantity=list(quantities), value=list(quantities.values()), machine="a test machine", date="-", commit="-")
    ).to_csv(path, index=False)


def test_the_speed_words_follow_the_measured_medians(tmp_path):
    """A model whose graph's median is above the target is named above it, one at or below below
    it, whatever the table's order (the Python step's median does not decide); a loop file whose
    runs differ in length is refused."""
    planning = dict(profile="paper", trajectory_500_steps_ms=7.0)
    for name in readme.SPEED_MODELS:
        median = 0.04 if name == "rf-physical" else 0.06
        planning |= {f"step.{name}.graph_ms.median": median, f"step.{name}.eager_ms.median": 0.3}
        planning |= {f"step.{name}.step_ms.median": 0.07, f"step.{name}.step_ms.p99": 0.2}
    _bench_csv(tmp_path / "planning.csv", planning)

    def loop_run(name, periods):
        return {f"idle.{name}.step_ms.{q}": 0.1 for q in ("p50", "p99.9")} | {
            f"idle.{name}.periods": periods,
            f"idle.{name}.deadline_misses": 0,
        }

    _bench_csv(tmp_path / "loop.csv", loop_run("mlp", 2000))
    words = " ".join(readme.speed_block(tmp_path).split())
    assert "alone at most 0.05 ms median: RF-Physical (4 Euler steps); above it: MLP, RF (4 Euler steps)," in words
    _bench_csv(tmp_path / "loop.csv", loop_run("mlp", 2000) | loop_run("rf", 1000))
    with pytest.raises(ValueError, match="differ in length"):
        readme.speed_block(tmp_path)
