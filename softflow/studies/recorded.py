"""recorded: can a model that never saw a model of the rod, trained on nothing but recorded runs of
a rig, plan that rig's paths as well as the simulator-trained RF-FWD, and how much recording does
it need? The twin of HW_ROBOT records runs of random actuation (``hardware.record_runs``: the
motor commands sent, the tip the camera tracked); models learn the motor commands from the
tracked tip and plan motor-command histories that are replayed on the plant as they are. Against
them the shipped RF-FWD, its commands made through the model rod (open, open-calibrated,
closed-ilc-calibrated), under the same gap: with cable friction (hysteresis) and without.
Fixed before any paper cell ran (docs/assumptions.md, "The recorded study").
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from softflow import data, hardware, training
from softflow.control.planning import Controller, recorded_range
from softflow.data import recordings
from softflow.data.references import Reference, hardware_references
from softflow.hardware import recorder
from softflow.profiles import FIXED_BUDGET, get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT
from softflow.store import content_key
from softflow.studies import ambiguity
from softflow.studies.closed_loop import CAMERA_LATENCY, learning_options, mode_options
from softflow.studies.study import Grid, recorded_cell_model, training_spec

GAPS = {"friction": hardware.FRICTION_GAP, "typical": hardware.TYPICAL_GAP}  # the cell's gap by name
RECORDINGS, SIMULATOR = "recordings", "simulator"  # what a cell's model was trained on
PLANNED_COMMANDS = "planned-commands"  # the mode of a model of recordings: its plan is the motor commands
SIMULATOR_MODES = ("open", "open-calibrated", "closed-ilc-calibrated")  # closed_loop.LOOP_MODES
TRAINING_SEED, HELD_OUT_SEED = 0, 1  # record_runs seeds of the training folder and of the held-out runs
VALIDATION = 0.1  # share of a training set's runs that validate (by recording, at least one)
SPLIT_SEED = 0
LOADER_FRACTIONS = (1 / 3, 1 / 3)  # any split load_dataset accepts for 3 runs or more; replaced by ours
MM = 1e-3  # m per unit of the motor columns (l1_mm, ...)


@dataclass(frozen=True, kw_only=True)
class RecordedGrid(Grid):
    configs: tuple[str, ...]  # gravity configurations of the twin
    seconds: float  # per recorded run
    held_out: int  # runs, seed HELD_OUT_SEED
    trained: dict[tuple[str, int], tuple[str, ...]]  # (gap, runs trained on): models
    simulator: dict[str, tuple[str, ...]]  # gap: loop modes of the simulator-trained RF-FWD
    references: tuple[str, ...] | None  # of hardware_references (None: all)
    draws: int


RECORDED = {  # per profile: the recordings, the grid and the references
    "ci": RecordedGrid(
        configs=("vertical",),
        seconds=1.0,  # per run
        held_out=4,  # runs, seed 1
        trained={("friction", 8): ("mlp", "rf")},  # (gap, runs trained on): models
        seeds=(0,),
        simulator={"friction": ("open",)},  # gap: modes of the simulator-trained RF-FWD
        references=("circle",),
        draws=16,
        train=FIXED_BUDGET["ci"],
    ),
    "paper": RecordedGrid(
        configs=("vertical", "horizontal"),
        seconds=5.0,
        held_out=60,  # 5 minutes
        trained={  # 720 runs: 60 minutes; 60 and 180: its first 5 and 15
            ("friction", 720): ("mlp", "lstm", "transformer", "rf", "rf-fwd"),
            ("friction", 60): ("mlp", "rf"),
            ("friction", 180): ("mlp", "rf"),
            ("typical", 720): ("mlp", "rf"),
        },
        seeds=(0, 1, 2),
        simulator={"friction": SIMULATOR_MODES, "typical": SIMULATOR_MODES},
        references=None,  # all of hardware_references: Table III's shapes and the burst circle
        draws=16,
        train=FIXED_BUDGET["paper"],  # 20 000 steps, no early stop
    ),
}


def cells(profile_name: str) -> list[dict]:
    grid = RECORDED[profile_name]
    cell = dict(study="recorded", seed=0)
    return [
        dict(cell, model=model, seed=seed, gravity=g, gap=gap, trained_on=RECORDINGS, runs=runs, mode=PLANNED_COMMANDS)
        for g in grid.configs
        for (gap, runs), names in grid.trained.items()
        for model in names
        for seed in grid.seeds
    ] + [
        dict(
            cell,
            model="rf-fwd",
            gravity=g,
            gap=gap,
            trained_on=SIMULATOR,
            mode=mode,
            latency=CAMERA_LATENCY,
            dropped=0.0,
            **learning_options(mode),
        )
        for g in grid.configs
        for gap, modes in grid.simulator.items()
        for mode in modes
    ]


def references(sim: Simulator, profile_name: str) -> list[Reference]:
    """The profile's references for the twin of ``sim``'s configuration (``hardware_references``)."""
    names = RECORDED[profile_name].references
    made = hardware_references(sim)
    return made if names is None else [r for r in made if r.name in names]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """A model trained on the cell's recordings, or the simulator-trained RF-FWD in one of its
    loop modes, on the twin under the cell's gap; one row per reference."""
    sim = Simulator(HW_ROBOT, cell["gravity"])
    scored = references(sim, profile_name)
    if cell["trained_on"] == SIMULATOR:
        return _simulator_rows(cell, profile_name, device, workdir, sim, scored)
    return _recorded_rows(cell, profile_name, device, workdir, sim, scored)


def _recorded_rows(cell, profile_name, device, workdir, sim, scored) -> list[dict]:
    """The model trained on the first ``runs`` runs of the training folder (motor commands in,
    the tracked tip out), scored per step on the held-out runs (u: motor commands, mm) and on the
    references: its plans clipped to the recorded range and replayed on the plant as they are."""
    grid = RECORDED[profile_name]
    model, checkpoint, dataset, held_out = recorded_model(cell, profile_name, device, workdir)
    planned, clipped = plan_commands(model, cell["model"], checkpoint, scored)
    rows, _ = hardware.run_commands([MM * u for u in planned], scored, sim, GAPS[cell["gap"]], clipped=clipped)
    measured = dict(
        recorded_minutes=cell["runs"] * grid.seconds / 60,
        train_runs=len(dataset.train),
        val_runs=len(dataset.val),
        held_out_runs=len(held_out.test),
        **ambiguity.cached_spread(dataset, workdir),
        **ambiguity.per_step_scores(_controller(model, cell["model"], checkpoint), held_out, grid.draws),
        best_val=float(checkpoint["best_val"]),
        epochs_run=int(checkpoint["epochs_run"]),
        train_minutes=float(checkpoint["wall_seconds"]) / 60,
    )
    return [dict(row, **measured) for row in rows.drop(columns=["gravity", "loop"]).to_dict("records")]


def recorded_model(cell: dict, profile_name: str, device: str, workdir: Path):
    """A recordings cell's model: its runs recorded where missing, read, and the model trained
    on them (or found trained); (model, checkpoint, training set, held-out set)."""
    grid, gravity, gap = RECORDED[profile_name], cell["gravity"], cell["gap"]
    dataset = training_set(record(workdir, profile_name, gravity, gap, TRAINING_SEED, cell["runs"]), workdir)
    held_out = held_out_set(record(workdir, profile_name, gravity, gap, HELD_OUT_SEED, grid.held_out), workdir)
    model, checkpoint = recorded_cell_model(cell, grid, profile_name, dataset, workdir, device)
    return model, checkpoint, dataset, held_out


def _controller(model, name: str, checkpoint: dict, **options) -> Controller:
    """A model of recordings as ``load_controller`` makes it, clipped to the recorded range
    (``options`` replace that), planning anything: a few minutes of recording span a small
    workspace, and extrapolation is measured, not refused."""
    options = options or dict(u_range=recorded_range(checkpoint["recorded"]))
    return Controller(model, name, robot=None, gravity=None, workspace_margin=None, **options)


def plan_commands(model, name: str, checkpoint: dict, scored) -> tuple[list[np.ndarray], list[int]]:
    """The motor-command history (T, C) in mm a model of recordings plans for each reference,
    clipped to the recorded range, and how many of its values were clipped."""
    low, high = recorded_range(checkpoint["recorded"])  # mm
    free = _controller(model, name, checkpoint, u_limit=np.inf)
    planned = [free.plan(r.states) for r in scored]  # (T, C) each, not clipped
    return [np.clip(u, low, high) for u in planned], [int(np.sum((u < low) | (u > high))) for u in planned]


def _simulator_rows(cell, profile_name, device, workdir, sim, scored) -> list[dict]:
    """closed_loop's twin cell with the cell's gap: the profile's RF-FWD of the configuration
    (paper: the shipped one) in the cell's loop mode; calibrated modes after an identification
    run on this rig (its gap)."""
    profile, gravity, gap = get_profile(profile_name), cell["gravity"], GAPS[cell["gap"]]
    # a ci model is trained in the sweep's folder, a paper cell finds the shipped one; the dataset is
    # the profile's, shared with closed_loop and notebook 06 (made only to train)
    dataset = data.DatasetOnDemand(profile, HW_ROBOT, gravity, progress=False)
    model, _ = training.ensure_trained(
        cell["model"], profile, dataset, HW_ROBOT, gravity, root=workdir / "models" / profile_name, device=device
    )
    options, identified = mode_options(cell["mode"], profile_name, sim, gap, workdir)
    controller = Controller(model, cell["model"], robot=HW_ROBOT, gravity=gravity)
    rows, _ = hardware.run_twin(
        controller, scored, sim, gap, camera_latency=cell["latency"], dropped=cell["dropped"], **options
    )
    return [dict(row, **identified) for row in rows.drop(columns=["gravity", "loop"]).to_dict("records")]


def recording_settings(profile_name: str, gravity: str, gap: str, seed: int) -> dict:
    """The settings ``record_runs`` records a folder with, and its version: they name the
    folder and key the rows, so a changed setting records anew instead of being refused."""
    return dict(
        version=recorder.RECORDER_VERSION,
        robot=HW_ROBOT.name,
        robot_parameters=HW_ROBOT.parameters(),
        gravity=gravity,
        gap=GAPS[gap].parameters(),
        seconds=float(RECORDED[profile_name].seconds),
        seed=int(seed),
        latency=0.0,  # frames stamped when taken
        dropped=0.0,  # none lost
    )


def record(
    workdir: Path, profile_name: str, gravity: str, gap: str, seed: int, n_runs: int, workers: int = 1
) -> list[Path]:
    """The first ``n_runs`` runs of the folder of (profile, configuration, gap, seed), recorded
    where missing by ``workers`` processes (resumable: workers racing on a folder write the same
    files)."""
    settings = recording_settings(profile_name, gravity, gap, seed)
    folder = workdir / "recordings" / profile_name / f"{gravity}-{gap}-seed{seed}-{content_key(settings, 8)}"
    return recorder.record_runs(
        folder,
        n_runs,
        settings["seconds"],
        robot=HW_ROBOT,
        gravity=gravity,
        gap=GAPS[gap],
        seed=seed,
        latency=settings["latency"],
        dropped=settings["dropped"],
        workers=workers,
        progress=False,
    )


def record_grid(profile_name: str, workdir, workers: int = 1) -> None:
    """Every folder the profile's grid trains or tests on, recorded in full one after another,
    each by ``workers`` processes (``workdir``: the sweep's, e.g. data/sweeps/recorded). Cells
    record what they lack themselves, but workers that reach one folder together each record all
    of it: recording first spares a cluster that (paper: about 6 CPU-hours for the four
    60-minute folders and the held-out runs)."""
    grid, workdir = RECORDED[profile_name], Path(workdir)
    for gravity in grid.configs:
        for gap in dict.fromkeys(gap for gap, _ in grid.trained):
            runs = max(n for g, n in grid.trained if g == gap)
            record(workdir, profile_name, gravity, gap, TRAINING_SEED, runs, workers)
            record(workdir, profile_name, gravity, gap, HELD_OUT_SEED, grid.held_out, workers)


def _read(files: list[Path], workdir: Path) -> data.Dataset:
    """The runs as training reads them: the motor commands in (mm), the tracked tip and its
    velocity (RTS smoother) on the commands' period, each step paired with the command sent at
    its start (delay 0, as pre-registered); one episode per run."""
    loaded = recordings.load_dataset(
        files,
        inputs=recorder.motor_columns(HW_ROBOT),
        delay=0.0,
        fractions=LOADER_FRACTIONS,
        seed=SPLIT_SEED,
        data_dir=workdir / "datasets",
    )
    if len(loaded.u) != len(files):
        raise ValueError(f"expected one episode per recorded run ({len(files)}); got {len(loaded.u)}")
    return loaded


def training_set(files: list[Path], workdir: Path) -> data.Dataset:
    """The runs split by recording into training and validation, 90 / 10 (at least one run
    validates), shuffled as ``split_episodes`` shuffles; no test split: held-out runs test."""
    loaded, n = _read(files, workdir), len(files)
    n_val = max(1, round(VALIDATION * n))
    if n - n_val < 1:
        raise ValueError(f"need at least 2 recorded runs to train and validate on; got {n}")
    order = np.random.default_rng(SPLIT_SEED).permutation(n)
    return replace(
        loaded,
        train=np.sort(order[: n - n_val]),
        val=np.sort(order[n - n_val :]),
        test=np.zeros(0, int),
        key=f"{loaded.key}-val{n_val}",
    )


def held_out_set(files: list[Path], workdir: Path) -> data.Dataset:
    """The held-out runs, every one in the test split (never trained or validated on)."""
    loaded = _read(files, workdir)
    empty = np.zeros(0, int)
    return replace(loaded, train=empty, val=empty, test=np.arange(len(loaded.u)), key=f"{loaded.key}-held-out")


def models(cell: dict, profile_name: str) -> dict:
    """The trained models' arguments and budgets; for a model of recordings also how its runs
    were recorded and read, so a changed setting recomputes the rows."""
    if cell["trained_on"] == SIMULATOR:
        return training_spec(cell["model"], get_profile(profile_name))
    grid, gravity, gap = RECORDED[profile_name], cell["gravity"], cell["gap"]
    recording = dict(
        training=recording_settings(profile_name, gravity, gap, TRAINING_SEED),
        held_out=recording_settings(profile_name, gravity, gap, HELD_OUT_SEED),
        held_out_runs=grid.held_out,
        inputs=recorder.motor_columns(HW_ROBOT),
        validation=VALIDATION,
        split_seed=SPLIT_SEED,
        loader=recordings.RECORDINGS_VERSION,
    )
    return dict(training_spec(cell["model"], grid.budget(profile_name), seed=cell["seed"]), recordings=recording)
