"""Model cards of the shipped checkpoints: what each file holds, the rod and data it was trained
on, its budget and the committed results it scores. Generated from the files and the committed
tables, so checkpoints/README.md (``model_cards()``) cannot drift from them: a test compares
the two, and ``softflow models --cards`` prints it again."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from softflow.data.dataset import dataset_path
from softflow.models.checkpoints import SHIPPED, checkpoint_path, load_checkpoint
from softflow.models.common import Dims
from softflow.models.specs import CONTROLLERS, model_spec, resolved_kwargs
from softflow.profiles import get_profile
from softflow.report.tables import LABELS, TABLE1_MODELS, markdown, read_result, read_sweep, table1, table3
from softflow.rod.dynamics import GRAVITY_DIRECTIONS
from softflow.rod.robots import HW_ROBOT, ROBOTS, SIM_ROBOT, TWO_SEGMENT_ROD, Robot, rod_folder
from softflow.store import REPO
from softflow.studies.one_step import TWO_SEGMENT_TIP

README = SHIPPED / "README.md"
ROD_CONSTANTS = {SIM_ROBOT.name: "SIM_ROBOT", HW_ROBOT.name: "HW_ROBOT", TWO_SEGMENT_ROD.name: "TWO_SEGMENT_ROD"}
PROFILE = "paper"  # only paper-profile, seed-0 models ship (models.checkpoints.checkpoint_path)
ORDER = [
    *TABLE1_MODELS,
    *(name for name in CONTROLLERS if name not in TABLE1_MODELS),
    "forward",
]  # Table I order, then the rest
WHAT = {
    "mlp": "inverse MLP: u_t from (x_t, x_{t+1})",
    "mlp-physical": "inverse MLP that also reads the quasi-static prior u_phys(p_{t+1})",
    "lstm": "inverse LSTM over a window of past transitions and x_{t+1}",
    "transformer": "inverse Transformer over a window of past transitions and x_{t+1}",
    "rf": "conditional rectified flow: an MLP velocity field integrated from noise by Euler steps",
    "rf-physical": "rectified flow of the residual u - u_phys around the quasi-static prior",
    "rf-fwd": "rectified flow trained with a consistency term through the frozen forward surrogate",
    "rf-1": "one-step flow (MeanFlow): the average velocity over a span, so one network call samples u",
    "rf-fwd-1": "one-step flow (MeanFlow) with RF-FWD's consistency term on its one-step estimate",
    "rf-physical-1": "one-step flow (MeanFlow) of the residual u - u_phys around the quasi-static prior",
    "forward": "forward-dynamics surrogate (x_t, u_t) -> x_{t+1}: RF-FWD's consistency term, not a controller",
}


@dataclass(frozen=True)
class ShippedModel:
    """One shipped checkpoint: its file, its record and the rod it was trained for."""

    path: Path  # relative to the repository
    checkpoint: dict
    robot: Robot
    gravity: str

    @property
    def name(self) -> str:
        return self.checkpoint["name"]

    @property
    def variant(self) -> dict:
        """The constructor arguments that differ from the registry's ({} for the shipped default)."""
        default = resolved_kwargs(self.name)
        return {k: v for k, v in self.checkpoint["model_kwargs"].items() if v != default.get(k)}

    @property
    def paper_model(self) -> bool:
        """A model of Tables I-III: default arguments."""
        return not self.variant


def rod_of(folder: str) -> tuple[Robot, str]:
    """The rod and gravity whose checkpoint folder (``rod.rod_folder``) is ``folder``."""
    for robot in ROBOTS.values():
        for gravity in GRAVITY_DIRECTIONS:
            if rod_folder(robot, gravity) == folder:
                return robot, gravity
    raise ValueError(
        f"checkpoint folder {folder!r} is no rod of {sorted(ROBOTS)} in any gravity {sorted(GRAVITY_DIRECTIONS)}"
    )


def shipped_models() -> list[ShippedModel]:
    """Every checkpoint in checkpoints/ (its rod folders and their variants/), the simulation
    rod first, each folder in Table I order, variants last."""
    models = []
    for path in SHIPPED.rglob("*.pt"):
        parts = path.relative_to(SHIPPED).parent.parts
        folder = parts[0] if parts and parts[0] != "variants" else ""
        checkpoint = load_checkpoint(path)
        models.append(ShippedModel(_shown(path), checkpoint, *rod_of(folder)))

    def order(m):
        return (str(m.path.parent).removesuffix("variants"), not m.paper_model, ORDER.index(m.name), str(m.path))

    return sorted(models, key=order)


def _shown(path: Path) -> Path:
    return path.relative_to(REPO)


def training_data(model: ShippedModel) -> str:
    """The dataset a checkpoint names, in words when it is today's profile dataset for its rod."""
    profile = get_profile(PROFILE)
    key = model.checkpoint["data_key"]
    if key != dataset_path(profile, model.robot, model.gravity).stem:
        return f"{key} (not today's {PROFILE} dataset of this rod: retrain)"
    return f"{profile.n_episodes} x {profile.episode_seconds:g} s episodes"


def budget(model: ShippedModel) -> str:
    config = model.checkpoint["train_config"]
    return (
        f"{model.checkpoint['epochs_run']} of {config['epochs']} epochs x {config['steps_per_epoch']} steps, "
        f"batch {config['batch_size']}"
    )


def model_table(models: list[ShippedModel], results: dict | None = None) -> pd.DataFrame:
    """One row per checkpoint: model, rod, gravity, profile, training data, budget and its Table I
    row (mm; empty where it has none: other rods, size variants, the surrogate)."""
    results = committed_results() if results is None else results
    rows = []
    for m in models:
        row = table1_row(m, results)
        rows.append(
            {
                "checkpoint": str(m.path),
                "model": m.name,
                "rod": m.robot.name,
                "gravity": m.gravity,
                "profile": PROFILE,
                "training data": training_data(m),
                "budget": budget(m),
                "train min": m.checkpoint["wall_seconds"] / 60,
                "Table I shape mm": row.get("shape_mm", float("nan")),
                "Table I random mm": row.get("random_mm", float("nan")),
            }
        )
    return pd.DataFrame(rows).set_index("checkpoint")


def committed_results() -> dict:
    """The committed tables the cards quote (paper profile): Table I, the table1 sweep's rows and
    intervals, the size sweep, the twin's Table III."""
    profile = get_profile(PROFILE)
    return dict(
        table1=table1(profile),
        sweep=read_sweep(profile, "table1"),
        intervals=read_result(profile, "08_table1_ci.csv").set_index(["model", "family"]),
        sizes=read_result(profile, "baseline_sizes.csv").set_index(["model", "size"]),
        table3=table3(profile),
        two_segment=read_sweep(profile, "two_segment"),
        one_step=read_sweep(profile, "one_step"),
    )


def table1_row(model: ShippedModel, results: dict) -> dict:
    """{"shape_mm", "random_mm"} of the checkpoint's Table I row, or {} where it has none."""
    if not (model.paper_model and (model.robot, model.gravity) == (SIM_ROBOT, "vertical")):
        return {}
    if model.name not in results["table1"].index:
        return {}
    row = results["table1"].loc[model.name]
    return {column: row[(column, "ours")] for column in ("shape_mm", "random_mm")}


def _results_lines(model: ShippedModel, results: dict) -> list[tuple[str, str]]:
    """(what, value) rows of the committed results that score this checkpoint."""
    lines = []
    row = table1_row(model, results)
    if row:
        paper = results["table1"].loc[model.name]
        lines.append(
            (
                "Table I (figures/table1_tracking.csv: 8 shapes, Rand1-4), RMSE shape / random",
                f"{row['shape_mm']:.2f} / {row['random_mm']:.2f} mm "
                f"(paper: {paper[('shape_mm', 'paper')]:.1f} / {paper[('random_mm', 'paper')]:.1f} mm)",
            )
        )
        sweep = results["sweep"]
        seed0 = sweep[(sweep.model == model.name) & (sweep.seed == 0)].groupby("family").rmse_mm.mean()
        intervals = results["intervals"].loc[model.name]
        three = " / ".join(
            f"{intervals.loc[f, 'mean']:.2f} [{intervals.loc[f, 'low']:.2f}, {intervals.loc[f, 'high']:.2f}]"
            for f in ("shape", "random")
        )
        lines.append(
            (
                "table1 sweep (figures/sweeps/table1-paper.csv: 8 shapes, 24 random), shape / random",
                f"this checkpoint (seed 0) {seed0['shape']:.2f} / {seed0['random']:.2f} mm; "
                f"3 training seeds {three} mm (figures/08_table1_ci.csv, 95 % interval)",
            )
        )
    size = ", ".join(f"{k}={v}" for k, v in model.variant.items())
    if model.variant and (model.name, size) in results["sizes"].index:
        sized = results["sizes"].loc[(model.name, size)]
        lines.append(
            (
                "size sweep on Table I's references (figures/baseline_sizes.csv), shape / random",
                f"{sized.rmse_shape_mm:.2f} / {sized.rmse_random_mm:.2f} mm, {int(sized.parameters)} parameters",
            )
        )
    if model.robot == TWO_SEGMENT_ROD and model.name in CONTROLLERS:
        rows = results["two_segment"]
        mine = rows[(rows.model == model.name) & (rows.observation == "tip") & (rows.plan == "zero")]
        seed0 = mine[mine.seed == 0].groupby("family").rmse_mm.mean()
        steps = resolved_kwargs(model.name).get("steps")  # a one-step flow: the one_step study trained it
        rows = results["one_step"]
        mine = rows[(rows.rod == TWO_SEGMENT_TIP) & (rows.model == model.name) & (rows.plan_steps == steps)]
        one_step_seed0 = mine[mine.seed == 0].groupby("family").rmse_mm.mean()
        if len(seed0):
            lines.append(
                (
                    "two_segment sweep (figures/sweeps/two_segment-paper.csv: 8 shapes, 24 random, 3 3-D paths; "
                    "the tip observed), shape / random / 3-D paths",
                    f"this checkpoint (seed 0) {seed0['shape']:.2f} / {seed0['random']:.2f} / {seed0['path3d']:.2f} mm",
                )
            )
        elif len(one_step_seed0):
            lines.append(
                (
                    f"one_step sweep (figures/sweeps/one_step-paper.csv: 8 shapes, 24 random; the tip observed, "
                    f"{steps} step), shape / random",
                    f"this checkpoint (seed 0) {one_step_seed0['shape']:.2f} / {one_step_seed0['random']:.2f} mm",
                )
            )
    if model.paper_model and model.robot == HW_ROBOT and model.name == "rf-fwd":
        mean = results["table3"].loc["mean", (model.gravity, "ours")]
        paper = results["table3"].loc["mean", (model.gravity, "paper")]
        lines.append(
            (
                "Table III (figures/table3_twin.csv: twin, 4 shapes), mean RMSE",
                f"{mean:.2f} mm through the twin's camera (paper's robot: {paper:.2f} mm)",
            )
        )
    return lines


def _usage(model: ShippedModel) -> str:
    """How to use a checkpoint: the CLI and Python for a controller of Tables I-III."""
    if model.name not in CONTROLLERS:
        return "loaded with the model that requires it; not a controller"
    if model.variant:
        return (
            f"`control.Controller(checkpoints.model_from_checkpoint(checkpoints.load_checkpoint("
            f"{str(model.path)!r})), {model.name!r})` (`softflow.control`, `softflow.models.checkpoints`)"
        )
    options = "" if model.robot == SIM_ROBOT else f" --robot {model.robot.name}"
    arguments = "" if model.robot == SIM_ROBOT else f", robot={ROD_CONSTANTS[model.robot.name]}"
    if model.gravity != "vertical":
        options, arguments = options + f" --gravity {model.gravity}", arguments + f", gravity={model.gravity!r}"
    export = f", `softflow export {model.name} --shape circle{options} --out commands.csv`"
    return (
        f"`softflow plan {model.name} --shape circle{options} --out circle.csv`, "
        f"`softflow evaluate {model.name}{options}`{export if model.robot == HW_ROBOT else ''}, "
        f"`load_controller({model.name!r}{arguments})`"
    )


def model_card(model: ShippedModel, results: dict) -> str:
    """One checkpoint's card: a heading and a two-column Markdown table."""
    checkpoint = model.checkpoint
    dims = Dims(**checkpoint["dims"])
    config = checkpoint["train_config"]
    r = model.robot
    requires = model_spec(model.name).requires
    fields = [
        ("model", f"{LABELS[model.name]} (`{model.name}`)" if model.name in LABELS else f"`{model.name}`"),
        ("what", WHAT[model.name]),
        ("arguments", ", ".join(f"{k}={v}" for k, v in checkpoint["model_kwargs"].items())),
        ("sizes", f"{dims.inputs} inputs, {dims.position}-D tip and its velocity"),
        (
            "rod",
            f"{r.name}: L {r.length:g} m, D {r.diameter:g} m, W {r.cable_distance:g} m, E {r.youngs_modulus:g} Pa, "
            f"eta {r.damping:g} Pa s, rho {r.density:g} kg/m^3, {r.n_cables} cables",
        ),
        ("gravity", model.gravity),
        ("profile", PROFILE),
        ("training data", f"{training_data(model)} of random polynomial actuation, `{checkpoint['data_key']}`"),
        (
            "budget",
            f"{budget(model)}, lr {config['lr']:g}, patience {config['patience']}, seed {config['seed']}; "
            f"{checkpoint['wall_seconds'] / 60:.1f} min of training",
        ),
        ("best validation loss", f"{checkpoint['best_val']:.3g}"),
    ]
    rod = rod_folder(model.robot, model.gravity)
    if requires:
        needed = [_shown(checkpoint_path(name, PROFILE, rod, shipped=True)) for name in requires]
        fields.append(("requires", ", ".join(f"`{path}` (trained first, then frozen)" for path in needed)))
    fields += _results_lines(model, results)
    fields.append(("use", _usage(model)))
    lines = [f"### {model.path}", "", "| | |", "|---|---|"]
    return "\n".join(lines + [f"| {what} | {value} |" for what, value in fields])


def model_cards() -> str:
    """checkpoints/README.md: the table of shipped checkpoints, then a card per checkpoint."""
    models, results = shipped_models(), committed_results()
    head = [
        "# Shipped checkpoints",
        "",
        "Paper-profile weights (seed 0), so `load_controller` and the `softflow` verbs work right after a "
        "clone. Generated by `softflow.report.model_cards` (`softflow models --cards`); a test checks that "
        "this file is what the generator writes from the checkpoints and the committed results. Only "
        "`softflow train --ship` and, for the two-segment rod, `studies.two_segment.ship_models` (its study's "
        "seed-0 models, never overwriting) write this folder; models you train go to `data/checkpoints/`.",
        "",
        markdown(model_table(models, results)),
        "",
        "Rod folders: the paper's simulation rod (vertical) at the top; `<rod>-<gravity>-<key of the rod's "
        "parameters>/` for the others; `variants/` holds the size sweep's models (notebook 03).",
        "",
        "## Model cards",
    ]
    return "\n".join(head + [f"\n{model_card(m, results)}" for m in models]) + "\n"
