"""`softflow VERB ...` (or `python -m softflow VERB ...`): the notebooks' steps without Jupyter.

  softflow data --profile paper                        generate (or verify) the dataset
  softflow train --profile paper mlp rf-fwd            train models; the last lines are their checkpoints
  softflow train --robot hw --gravity horizontal rf-fwd   a hardware-twin model
  softflow train --ship rf-fwd                         retrain a shipped model into checkpoints/ (maintainers)
  softflow check my_runs/                              what the loader finds in each recording, and its split
  softflow train mlp --recordings my_runs/ --profile quick   a model of recorded runs (docs/recordings.md)
  softflow sweep table1 --profile paper                a study's cells as Dask tasks (docs/sweeps.md)
  softflow models [--cards]                            the shipped checkpoints (and their model cards)
  softflow plan rf-fwd --shape circle --out u.csv      planned inputs for a shape, one row per sample
  softflow evaluate rf-fwd [--references random]       open-loop tracking RMSE in the simulator
  softflow export rf-fwd --shape star --out star.csv   motor commands for the hardware-twin rod
  softflow export rf-fwd --onnx rf-fwd.onnx            its real-time step as one ONNX graph (onnxruntime)

`softflow VERB --help` describes a verb. Trained models go to data/checkpoints/ (git-ignored);
only train --ship writes checkpoints/.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from softflow import control, data, hardware, training
from softflow.control.loop import WATCHDOG
from softflow.data import recordings
from softflow.models.checkpoints import checkpoint_path
from softflow.models.specs import CONTROLLERS, MODELS
from softflow.profiles import PROFILES, STUDY_PROFILES, get_profile
from softflow.report import model_cards, tables
from softflow.rod.dynamics import GRAVITY_DIRECTIONS, Simulator
from softflow.rod.robots import HW_ROBOT, ROBOTS, SIM_ROBOT, TWO_SEGMENT_ROD, rod_folder
from softflow.store import write_text
from softflow.studies import sweep, two_segment

# The rod's references for `evaluate`: the sim rod's are Table I's (8 shapes, Rand1..Rand4), the
# hardware rod's Table III's shapes (5 cm about its rest tip) and Rand1..Rand4 run on it.
REFERENCES = {"table1": ("shape", "random"), "shapes": ("shape",), "random": ("random",)}


def main(argv=None):
    """Run one verb. Bad input (a ValueError, which says what was expected) exits 2 with its
    message in the command line's words, as a bad argument does, without the usage block: the
    arguments parsed, the data or their combination was refused."""
    args = build_parser().parse_args(sys.argv[1:] if argv is None else list(argv))
    shown, warnings.formatwarning = warnings.formatwarning, _warning  # a user reads the message, not our source
    try:
        args.run(args)
    except ValueError as error:
        args.parser.exit(2, f"{args.parser.prog}: error: {in_flags(str(error))}\n")
    finally:
        warnings.formatwarning = shown


def _warning(message, category, *where, **options) -> str:
    return f"softflow: {in_flags(str(message))}\n"


SPLIT_NAMES = {"train": "trains on", "val": "validates on", "test": "tests on"}

# The package's messages name its Python keywords; on the command line they are these flags.
FLAGS = {
    "tip=[...]": "--tip COLS",
    "inputs=[...]": "--inputs COLS",
    "pass delay=": "pass --delay",
    "pass other fractions (e.g. (1/3, 1/3) for three)": "pass --fractions (e.g. --fractions 0.34,0.34 for three)",
    "(max_gap = ": "(--max-gap ",
    "than max_acceleration explains": "than --max-acceleration explains",
    "load_dataset(..., split_at_gaps=True)": "--split-at-gaps",
    "(dropouts=False keeps them)": "(in Python, recordings.read(..., dropouts=False) keeps them)",
    "(or give noise and jerk)": "(record longer runs; in Python, or give noise and jerk)",
}


def in_flags(message: str) -> str:
    """A package error as a command-line user reads it: Python keyword hints turned into flags."""
    for keyword, flag in FLAGS.items():
        message = message.replace(keyword, flag)
    return message


def build_parser() -> argparse.ArgumentParser:
    """The parser of every verb (built per call: a test may register a study)."""
    parser = argparse.ArgumentParser(
        prog="softflow", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    verbs = parser.add_subparsers(title="verbs", dest="verb", required=True, metavar="VERB")

    def verb(name, run, summary, description=None):
        sub = verbs.add_parser(
            name,
            help=summary,
            description=description or summary,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        sub.set_defaults(run=run, parser=sub)
        return sub

    sub = verb("data", _data, "generate (or verify) a profile's dataset; its path is the last line")
    _rod_options(sub)

    sub = verb(
        "train",
        _train,
        "train models (or reuse a current checkpoint); the checkpoint paths are the last lines",
    )
    sub.add_argument("models", nargs="+", metavar="MODEL", choices=sorted(MODELS), help=", ".join(sorted(MODELS)))
    _rod_options(sub)
    sub.set_defaults(robot=None, gravity=None)  # None: not given, so --recordings can refuse them
    sub.add_argument("--device", default="auto", choices=sweep.DEVICES, help="auto: CUDA, else MPS, else CPU")
    sub.add_argument(
        "--ship",
        action="store_true",
        help="write the paper-profile checkpoints committed in checkpoints/ and their model cards (maintainers)",
    )
    recorded = sub.add_argument_group(
        "recorded runs", "train on a folder of recordings (docs/recordings.md) instead of a simulated rod"
    )
    recorded.add_argument(
        "--recordings", type=Path, metavar="DIR", help="the folder of recordings (.csv, .csv.gz, .parquet)"
    )
    _recording_options(recorded)

    sub = verb(
        "check",
        _check,
        "what the loader finds in each recording before training: rates, lost frames, long gaps, delay, units, split",
        recordings.describe.__doc__,
    )
    sub.add_argument("recordings", type=Path, metavar="DIR", help="the folder of recordings (.csv, .csv.gz, .parquet)")
    _recording_options(sub)
    sub.add_argument("--no-delay", action="store_true", help="skip the delay estimates (they smooth every run)")

    sub = verb("sweep", _sweep, "run a study's cells as Dask tasks; the result CSV is the last line", sweep.__doc__)
    sub.add_argument("study", choices=sorted(sweep.STUDIES))
    sub.add_argument("--profile", required=True, choices=STUDY_PROFILES)
    cluster = sub.add_mutually_exclusive_group()
    cluster.add_argument("--scheduler-file", help="run on the cluster whose scheduler wrote this file")
    cluster.add_argument("--scheduler", metavar="ADDRESS", help="run on the cluster at this address (tcp://host:8786)")
    sub.add_argument("--workers", type=int, help="worker processes of the local cluster (default: one per core)")
    sub.add_argument("--device", default="auto", choices=sweep.DEVICES, help="auto: CUDA, else MPS, else CPU")
    sub.add_argument(
        "--recompute",
        action="store_true",
        help="recompute the cells whose rows ship in figures/sweeps/ (cached rows in data/sweeps/ still count)",
    )
    sub.add_argument(
        "--where",
        action="append",
        type=_field_values,
        metavar="FIELD=V[,V]",
        help="compute only the cells whose FIELD is one of the values (repeat for several fields), "
        "e.g. --where runs=60,180 --where gravity=vertical",
    )

    sub = verb("models", _models, "list the shipped checkpoints: rod, data, budget, Table I row", model_cards.__doc__)
    sub.add_argument("--cards", action="store_true", help="print every model card: the text of checkpoints/README.md")

    sub = verb(
        "plan",
        _plan,
        "plan a shape open loop: a CSV of time_s and one column per input (u1_N, ...), one row per sample",
    )
    _model_options(sub)
    _shape_options(sub)
    recorded = sub.add_argument_group(
        "recorded runs",
        "plan a desired path for a model of recorded runs: --reference, a CSV of time_s and the observed "
        "columns (velocities are estimated as for training); the inputs come in the recordings' units, "
        "advanced by their delay (row k is sent at period k)",
    )
    recorded.add_argument("--recordings", type=Path, metavar="DIR", help="the recordings the model was trained on")
    recorded.add_argument("--reference", type=Path, metavar="PATH.csv", help="the desired path")
    recorded.add_argument(
        "--check",
        action="store_true",
        help="refuse a plan that leaves each input's range or largest change per period in the training "
        "recordings (without it such a plan is written with a warning)",
    )
    _recording_options(recorded)

    sub = verb(
        "evaluate",
        _evaluate,
        "plan references, run the plans open loop in the simulator, print the RMSE per reference and family",
    )
    _model_options(sub)
    sub.add_argument(
        "--references",
        default="table1",
        choices=list(REFERENCES),
        help="table1 (default): shapes and random; shapes: Table I's eight (hw rod: Table III's four); "
        "random: Rand1..Rand4, held-out sum-of-sines actuation run through the rod",
    )

    sub = verb(
        "export",
        _export,
        "motor commands for a planned shape: a CSV time_s,l1_mm,... (docs/real_robot.md; --robot hw for the "
        "hardware twin); --onnx: the model's real-time step as one ONNX graph instead",
    )
    _model_options(sub)
    _shape_options(sub, out_required=False)
    sub.add_argument(
        "--onnx",
        type=Path,
        metavar="FILE.onnx",
        help="write Controller.step as one ONNX graph (inputs x_t, x_next; outputs u, outside) instead of commands",
    )
    sub.add_argument(
        "--loop",
        action="store_true",
        help="with --onnx and --recordings, the whole period of the loop as one graph: estimate, delay "
        "compensation, step and safety, its memory explicit (examples/run_loop.py runs it)",
    )
    sub.add_argument(
        "--rest",
        type=Path,
        metavar="FILE",
        help="with --loop, a rest run of today's session: frames are moved by its offset from the recordings' own "
        "rest run (a moved rest pose, a re-calibrated camera)",
    )
    sub.add_argument(
        "--watchdog",
        type=float,
        metavar="S",
        help=f"with --loop, how long a point may go without a fresh frame before the safe input (default {WATCHDOG} s)",
    )
    limits = sub.add_argument_group("limits", "with --onnx, what the graph may send")
    limits.add_argument(
        "--input-range",
        metavar="LOW:HIGH,...",
        help="each input's range in its units, one LOW:HIGH for all or one per input (write --input-range=-30:30 "
        "when LOW is negative); default: the model's (the rod's actuator range, or the range the recorded inputs took)",
    )
    limits.add_argument(
        "--safe-input",
        metavar="U,...",
        help="what the graph sends for a transition it refuses, one value for all or one per input, inside the "
        "range (default: the range's centre; with --loop, the recorded inputs' median)",
    )
    recorded = sub.add_argument_group(
        "recorded runs",
        "with --onnx, the model of recorded runs (found as plan finds it): its delay, sample period and "
        "observed columns go into the graph's metadata",
    )
    recorded.add_argument("--recordings", type=Path, metavar="DIR", help="the recordings the model was trained on")
    _recording_options(recorded)
    return parser


def _rod_options(sub):
    """The same rod by default for every verb: the paper's simulated rod, hanging."""
    sub.add_argument("--profile", default="paper", choices=sorted(PROFILES), help="run size (default: paper)")
    sub.add_argument(
        "--robot", default=SIM_ROBOT.name, choices=sorted(ROBOTS), help=f"the rod (default: {SIM_ROBOT.name})"
    )
    sub.add_argument(
        "--gravity", default="vertical", choices=list(GRAVITY_DIRECTIONS), help="configuration (default: vertical)"
    )


def _model_options(sub):
    sub.add_argument("model", metavar="MODEL", choices=CONTROLLERS, help=", ".join(CONTROLLERS))
    _rod_options(sub)


def _recording_options(group):
    """How recordings are read: the same options for training on them and planning with their model
    (the model is found by the Dataset they make)."""
    group.add_argument(
        "--inputs", type=_columns, metavar="COLS", help="input columns, comma-separated (default: those named u...)"
    )
    group.add_argument(
        "--tip",
        type=_columns,
        metavar="COLS",
        help="observed columns in m, comma-separated: the tip alone (x3_m,y3_m,z3_m) or several points "
        "(x1_m,...,z3_m) (default: x_m, y_m, z_m)",
    )
    group.add_argument(
        "--dt", type=_positive("seconds"), metavar="S", help="the period to resample to (default: the commands')"
    )
    group.add_argument(
        "--delay",
        type=_positive("seconds", zero=True),
        metavar="S",
        help="the input-to-motion delay in seconds (default: estimated per recording; 0: the inputs act at once)",
    )
    group.add_argument(
        "--fractions",
        type=_fractions,
        metavar="TRAIN,VAL",
        help="shares of the recordings for training and validation, the rest tested (split by recording; "
        "default: one recording in ten validates and one tests, at least one each)",
    )
    group.add_argument(
        "--max-gap",
        type=_positive("seconds"),
        metavar="S",
        help=f"the longest run of lost frames the smoother bridges (default {recordings.MAX_GAP:g} s)",
    )
    group.add_argument(
        "--max-acceleration",
        type=_positive("m/s^2"),
        metavar="A",
        help="the robot's largest acceleration: a frame further from its neighbours than it explains is a "
        f"jump, a lost frame (default {recordings.JUMP_ACCELERATION:g} m/s^2; lower it for a slow robot and camera)",
    )
    group.add_argument(
        "--split-at-gaps",
        action="store_true",
        help="cut a recording at a longer run of lost frames than --max-gap instead of refusing it",
    )
    group.add_argument(
        "--causal",
        action="store_true",
        help="states from the smoother's filter alone (each from the frames up to it), as the loop of "
        "export --loop sees them: train a model for the closed loop with it",
    )


def _shape_options(sub, out_required: bool = True):
    sub.add_argument("--shape", choices=sorted(data.SHAPES), help="the y-z shape to trace")
    sub.add_argument(
        "--size",
        type=_positive("metres"),
        help=f"half-extent in m, about the rest tip (default: {data.HARDWARE_SIZE:g} for hw, else {data.SIZE:g})",
    )
    sub.add_argument("--out", type=Path, required=out_required, metavar="FILE.csv", help="the CSV to write (replaced)")


def _positive(unit: str, *, zero: bool = False):
    """The argument type of a positive number of ``unit`` (``zero``: or 0)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (math.isfinite(value) and (value >= 0 if zero else value > 0)):
            what = f"a number of {unit} >= 0" if zero else f"a positive number of {unit}"
            raise argparse.ArgumentTypeError(f"expected {what}; got {text!r}")
        return value

    return parse


def _fractions(text: str) -> tuple[float, float]:
    """TRAIN,VAL -> (train, validation) shares."""
    try:
        shares = tuple(float(value) for value in text.split(","))
    except ValueError:
        shares = ()
    if len(shares) != 2:
        raise argparse.ArgumentTypeError(f"expected two shares TRAIN,VAL such as 0.8,0.1; got {text!r}")
    return shares


def _columns(text: str) -> list[str]:
    names = [name.strip() for name in text.split(",")]
    if not all(names):
        raise argparse.ArgumentTypeError(f"expected column names separated by commas; got {text!r}")
    return names


def _field_values(text: str) -> tuple[str, list[str]]:
    """FIELD=V[,V] -> (FIELD, [V, ...])."""
    field, _, values = text.partition("=")
    names = [value.strip() for value in values.split(",")]
    if not field.strip() or not all(names):
        raise argparse.ArgumentTypeError(f"expected FIELD=VALUE[,VALUE], e.g. runs=60,180; got {text!r}")
    return field.strip(), names


def _data(args):
    start = time.perf_counter()
    profile, robot = get_profile(args.profile), ROBOTS[args.robot]
    dataset = data.load_dataset(profile, robot, args.gravity)
    print(f"dataset {dataset.key}: {dataset.u.shape[0]} episodes ({time.perf_counter() - start:.0f} s)")
    print(data.dataset_path(profile, robot, args.gravity))


def _train(args):
    """Each model trained (or its current checkpoint reused); the last lines are the checkpoints
    ``load_controller`` now picks, one per model in order. With ``--recordings``, on those runs
    (no rod: ``--robot`` and ``--gravity`` are refused, and nothing ships)."""
    if args.ship and args.profile != "paper":
        raise ValueError(f"--ship writes the paper profile's checkpoints; got --profile {args.profile}")
    profile = get_profile(args.profile)
    if args.recordings is None:
        if given := _recording_flags(args):
            raise ValueError(f"{', '.join(given)} describe recordings; they need --recordings DIR")
        robot, gravity = ROBOTS[args.robot or SIM_ROBOT.name], args.gravity or "vertical"
        dataset = data.DatasetOnDemand(profile, robot, gravity)  # simulated only if a model must be trained
        found = dict(robot=robot, gravity=gravity)
    else:
        given = [f"--{option}" for option in ("robot", "gravity", "ship") if getattr(args, option)]
        if given:
            raise ValueError(
                f"{', '.join(given)} cannot go with --recordings: recorded runs have no simulated rod, and "
                "their models are trained into data/checkpoints/, never shipped"
            )
        robot = gravity = None
        dataset = _recordings(args)
        found = dict(recordings=dataset)
        print(
            f"{dataset.key}: {len(dataset.u)} episodes of {dataset.u.shape[1]} steps of "
            f"{dataset.dt:g} s, {dataset.dims.inputs} inputs ({', '.join(dataset.input_columns)}), "
            f"observed {', '.join(dataset.tip_columns)}; input-to-motion delay {dataset.delay_steps} periods "
            f"({dataset.delay_steps * dataset.dt:g} s, {'given' if args.delay is not None else 'estimated'})"
        )
        for split, files in dataset.split_files.items():
            print(f"{SPLIT_NAMES[split]}: {', '.join(files)}")
    paths = []
    for name in args.models:
        _, checkpoint = training.ensure_trained(
            name,
            profile,
            dataset,
            robot,
            gravity,
            ship=args.ship,
            device=sweep.resolve_device(args.device),
            progress=True,
        )
        print(
            f"{name}: {checkpoint['epochs_run']} epochs, best validation loss {checkpoint['best_val']:.3g}, "
            f"{checkpoint['wall_seconds'] / 60:.1f} min of training"
        )
        if args.ship:
            paths.append(checkpoint_path(name, profile.name, rod_folder(robot, gravity), shipped=True))
        else:
            paths.append(control.find_trained(name, profile.name, **found)[0])
    if args.ship:
        write_text(model_cards.README, model_cards.model_cards())
    print("\n".join(map(str, paths)))


# The recording options that take a value (the argparse group's), each part of a model's identity.
RECORDING_OPTIONS = ("inputs", "tip", "dt", "delay", "max_gap", "max_acceleration")


def _recording_flags(args) -> list[str]:
    """The options of ``_recording_options`` given on the command line."""
    given = [f"--{option.replace('_', '-')}" for option in RECORDING_OPTIONS if getattr(args, option) is not None]
    flags = ["--split-at-gaps"] * args.split_at_gaps + ["--causal"] * args.causal
    return given + flags + ["--fractions"] * (args.fractions is not None)


def _recordings(args):
    """The Dataset of ``--recordings`` read with the verb's column, period and delay options."""
    return recordings.load_dataset(
        args.recordings,
        inputs=args.inputs,
        tip=args.tip,
        dt=args.dt,
        delay=args.delay,
        fractions=args.fractions,
        max_gap=recordings.MAX_GAP if args.max_gap is None else args.max_gap,
        max_acceleration=recordings.JUMP_ACCELERATION if args.max_acceleration is None else args.max_acceleration,
        split_at_gaps=args.split_at_gaps,
        causal=args.causal,
    )


def _recorded_controller(args):
    """The model of ``--recordings`` read with the verb's options, and their Dataset; or a ValueError
    that gives the whole train command making it, with the options that are part of its identity."""
    dataset = _recordings(args)
    if control.find_trained(args.model, args.profile, recordings=dataset)[0] is None:
        raise ValueError(
            f"no trained {args.model!r} of {args.recordings} read with these options, profile {args.profile!r}; "
            f"train it with: softflow train {args.model} --profile {args.profile} --recordings {args.recordings}"
            + "".join(f" {flag}" for flag in _recording_values(args))
        )
    return control.load_controller(args.model, args.profile, recordings=dataset), dataset


def _recording_values(args) -> list[str]:
    """The options of ``_recording_options`` given, with their values, as they are typed."""
    typed = dict(inputs=args.inputs, tip=args.tip, fractions=args.fractions)
    out = []
    for option in (*RECORDING_OPTIONS, "fractions"):
        value = getattr(args, option)
        if value is not None:
            text = ",".join(map(str, typed[option])) if option in typed else f"{value:g}"
            out.append(f"--{option.replace('_', '-')} {text}")
    return out + ["--split-at-gaps"] * args.split_at_gaps + ["--causal"] * args.causal


def _check(args):
    """One line per recording: what ``recordings.describe`` finds. Exit 1 where a file would be refused."""
    given = [flag for flag, value in (("--dt", args.dt), ("--delay", args.delay)) if value is not None]
    if given or args.split_at_gaps:
        raise ValueError(f"check reads every file as it is; {', '.join(given) or '--split-at-gaps'} changes no report")
    report = recordings.describe(
        args.recordings,
        inputs=args.inputs,
        tip=args.tip,
        max_gap=recordings.MAX_GAP if args.max_gap is None else args.max_gap,
        max_acceleration=recordings.JUMP_ACCELERATION if args.max_acceleration is None else args.max_acceleration,
        fractions=args.fractions,
        delays=not args.no_delay,
    )
    with pd.option_context("display.max_colwidth", 80, "display.width", 200):
        print(report.dropna(axis=1, how="all").to_string(index=False, na_rep="", float_format="{:.1f}".format))
    if report.problem.notna().any():
        raise SystemExit(1)


def _sweep(args):
    """The CSV path is the last line of stdout; exit status 1 if a cell failed."""
    start = time.perf_counter()
    with sweep.connect(args.scheduler_file, args.scheduler, args.workers) as client:
        result = sweep.run_sweep(
            args.study,
            args.profile,
            client=client,
            device=args.device,
            shipped=not args.recompute,
            where=dict(args.where or ()),
        )
    for failure in result.failures:
        print(f"cell {failure.cell} failed: {failure.error}", file=sys.stderr)
    computed = result.computed - len(result.failures)
    unrun = result.missing - len(result.failures)
    print(
        f"{args.study}: {len(result.rows)} rows ({result.cached} cached, {computed} computed, "
        f"{len(result.failures)} failed{f', {unrun} cells not asked for' if unrun else ''}) "
        f"in {time.perf_counter() - start:.0f} s"
    )
    print(result.csv)
    if result.failures:
        raise SystemExit(1)


def _models(args):
    if args.cards:
        print(model_cards.model_cards(), end="")
    else:
        print(tables.markdown(model_cards.model_table(model_cards.shipped_models())))


def _controller(args):
    """The controller and simulator of the verb's model and rod. The simulator runs on one thread:
    a verb's dozen rods are too few to share (evaluate rf-fwd, the same RMSE: 19 s of CPU on one
    thread, 31.5 s on two, which also took longer on this 2-core machine)."""
    robot = ROBOTS[args.robot]
    sim = Simulator(robot, args.gravity, threads=1)
    return control.load_controller(args.model, args.profile, robot, args.gravity), sim


def shape_about_rest_tip(sim: Simulator, shape: str, size: float | None) -> data.Reference:
    """The named shape of half-extent ``size`` (m; None: the rod's default) about the rod's rest
    tip (the horizontal rod sags), cached like every reference."""
    size = (data.HARDWARE_SIZE if sim.robot == HW_ROBOT else data.SIZE) if size is None else size

    def about_rest_tip(sim):
        centre = sim.tip_positions(sim.rest_q()[None])[0, 1:]  # (2,) rest tip y, z
        return [data.shape_reference(sim, shape, size, centre=centre)]

    return data.cached_references(sim, f"shape-{shape}-{size!r}", about_rest_tip)[0]


def reference_set(sim: Simulator, which: str) -> list:
    """The references ``evaluate --references which`` scores on this rod (``REFERENCES``)."""
    families = REFERENCES[which]
    if sim.robot == HW_ROBOT:
        made = {
            "shape": lambda: [r for r in data.hardware_references(sim) if r.family == "shape"],
            "random": lambda: data.cached_references(sim, "random", data.random_references),
        }
        return [r for family in families for r in made[family]()]
    if sim.robot == TWO_SEGMENT_ROD:  # its study's references: the least-norm lift, four-input random draws
        return [r for r in two_segment.references(sim, "paper") if r.family in families]
    return [r for r in data.evaluation_references(sim) if r.family in families]


def _planned_shape(args):
    """(simulator, reference, plan (T, m)) of a shape verb."""
    if args.out.is_dir():
        raise ValueError(f"--out {args.out} is a directory; expected a file to write")
    if args.shape is None:
        recorded = " (or, for a model of recorded runs, --recordings DIR --reference PATH.csv)"
        raise ValueError(f"--shape is needed{recorded if hasattr(args, 'reference') else ''}")
    controller, sim = _controller(args)
    reference = shape_about_rest_tip(sim, args.shape, args.size)
    return sim, reference, controller.plan(reference.states)


def _plan(args):
    if args.recordings is not None or args.reference is not None or args.check:
        return _plan_recorded(args)
    given = [f"--{option.replace('_', '-')}" for option in RECORDING_OPTIONS if getattr(args, option) is not None]
    if given:
        raise ValueError(f"{', '.join(given)} describe recordings; they need --recordings DIR --reference PATH.csv")
    sim, reference, u = _planned_shape(args)
    frame = pd.DataFrame(u, columns=[f"u{i + 1}_N" for i in range(u.shape[1])])
    frame.insert(0, "time_s", np.arange(len(u)) * sim.dt)
    write_text(args.out, frame.to_csv(index=False, float_format="%.6f"))
    print(f"{args.model}: {len(u)} samples of {u.shape[1]} inputs for {reference.name} ({args.robot}, {args.gravity})")
    print(args.out)


def _plan_recorded(args):
    """A desired path planned by the model of recorded runs: time_s and the recordings' inputs."""
    if args.recordings is None or args.reference is None:
        raise ValueError("a model of recorded runs plans --reference PATH.csv with --recordings DIR: give both")
    if args.shape is not None or args.size is not None:
        raise ValueError("--shape and --size plan the simulated rod's shapes; with --recordings give --reference")
    if args.out.is_dir():
        raise ValueError(f"--out {args.out} is a directory; expected a file to write")
    controller, dataset = _recorded_controller(args)
    states = recordings.read_path(args.reference, tip=list(dataset.tip_columns), dt=dataset.dt)  # (T+1, 2k)
    u = controller.plan(states)  # (T, m), advanced by the delay
    if problems := control.InputLimits.of(dataset).violations(u, dataset.input_columns):
        said = "; ".join(problems)
        if args.check:
            raise ValueError(f"--check: the plan leaves what the training recordings did: {said}; nothing written")
        warnings.warn(f"the plan leaves what the training recordings did: {said} (--check refuses such a plan)")
    frame = pd.DataFrame(u, columns=list(dataset.input_columns))
    frame.insert(0, "time_s", np.arange(len(u)) * dataset.dt)
    write_text(args.out, frame.to_csv(index=False, float_format="%.6f"))
    print(
        f"{args.model}: {len(u)} samples of {u.shape[1]} inputs for {args.reference.name}, advanced by the "
        f"delay of {controller.delay_steps} periods ({controller.delay_steps * dataset.dt:g} s): send row k at "
        "period k, from the path's start state"
    )
    print(args.out)


def _export(args):
    if args.loop or args.watchdog is not None or args.rest is not None:
        return _export_loop(args)
    if args.onnx is not None:
        return _export_onnx(args)
    if given := ["--recordings"] * (args.recordings is not None) + _recording_flags(args):
        raise ValueError(
            f"{', '.join(given)}: a model of recorded runs has no cables to command; "
            "export its step with --onnx FILE.onnx"
        )
    if given := [f"--{o.replace('_', '-')}" for o in ("input_range", "safe_input") if getattr(args, o) is not None]:
        raise ValueError(f"{', '.join(given)}: limits of the step's graph; they need --onnx FILE.onnx")
    if args.out is None:
        raise ValueError("--out FILE.csv is needed (or --onnx FILE.onnx for the model's step as one graph)")
    sim, reference, u = _planned_shape(args)
    commands = hardware.cable_commands(u[None], sim)[0]  # (T, C) m
    hardware.write_commands(args.out, commands, sim.dt)
    print(f"{args.model}: {len(commands)} commands for {commands.shape[1]} motors, {reference.name} ({args.robot})")
    print(args.out)


def _numbers(text: str | None, flag: str) -> list[float] | None:
    """Comma-separated numbers of ``flag``; None when it was not given."""
    if text is None:
        return None
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"{flag} takes numbers separated by commas; got {text!r}") from None


def _input_range(text: str | None):
    """(low, high) of --input-range LOW:HIGH[,LOW:HIGH...]; None when it was not given."""
    if text is None:
        return None
    pairs = [part.split(":") for part in text.split(",")]
    if any(len(pair) != 2 for pair in pairs):
        raise ValueError(f"--input-range takes LOW:HIGH, one for all inputs or one per input; got {text!r}")
    low, high = zip(*(_numbers(",".join(pair), "--input-range") for pair in pairs))
    return list(low), list(high)


def _export_onnx(args):
    """The model's step as one ONNX graph: the verb's rod, or with --recordings the model of those runs."""
    if given := [f"--{option}" for option in ("shape", "size", "out") if getattr(args, option) is not None]:
        raise ValueError(f"{', '.join(given)}: options of a command file; --onnx writes the model's step alone")
    if args.recordings is not None:
        controller, _ = _recorded_controller(args)
        made_for = f"recordings {args.recordings}"
    elif given := _recording_flags(args):
        raise ValueError(f"{', '.join(given)} describe recordings; they need --recordings DIR")
    else:
        controller = control.load_controller(args.model, args.profile, ROBOTS[args.robot], args.gravity)
        made_for = f"{args.robot} rod, {args.gravity}"
    if args.input_range is not None or args.safe_input is not None:
        controller = controller.limited(_input_range(args.input_range), _numbers(args.safe_input, "--safe-input"))
    path = control.export_onnx(controller, args.onnx)
    dims, delay = controller.model.dims, controller.delay_steps
    print(
        f"{args.model} ({made_for}): Controller.step as one ONNX graph, x_t and x_next ({dims.state} numbers "
        f"each) -> u ({dims.inputs} inputs) and outside"
        + (f"; the rig moves {delay} periods after an input is sent (metadata delay_steps)" if delay else "")
    )
    print(path)


def _export_loop(args):
    """A model of recorded runs' whole period as one graph, with the recordings' limits unless given."""
    if not args.loop:
        raise ValueError("--watchdog and --rest are options of the loop's graph; they need --loop")
    if args.onnx is None or args.recordings is None:
        raise ValueError(
            "--loop writes the period of a model of recorded runs: it needs --onnx FILE.onnx and --recordings DIR"
        )
    if given := [f"--{option}" for option in ("shape", "size", "out") if getattr(args, option) is not None]:
        raise ValueError(f"{', '.join(given)}: options of a command file; --loop writes the loop's graph alone")
    controller, dataset = _recorded_controller(args)
    safe = _numbers(args.safe_input, "--safe-input")
    m = dataset.dims.inputs
    options = dict(
        u_range=_input_range(args.input_range), safe_input=None if safe is None else np.broadcast_to(safe, (m,))
    )
    if args.watchdog is not None:
        options["watchdog"] = args.watchdog
    if args.rest is not None:
        if not dataset.resting_files:
            raise ValueError(
                f"--rest: {args.recordings} holds no rest run (a recording whose inputs never change) to anchor "
                "today's to; record one in the session of the recordings"
            )
        own = args.recordings / dataset.resting_files[0]
        options["anchor"] = recordings.rest_offset(args.rest, own, tip=list(dataset.tip_columns))
    loop = control.loop_of(controller, dataset, **options)
    path = control.export_loop(loop, args.onnx)
    period = loop.period
    print(
        f"{args.model} (recordings {args.recordings}): the loop's period as one ONNX graph, every "
        f"{dataset.dt:g} s: a frame of {', '.join(dataset.tip_columns)} and the reference now, {period.delay} and "
        f"{period.delay + 1} periods ahead -> u ({', '.join(loop.input_columns)}); delay {period.delay} periods, "
        f"safe input after {period.watchdog} periods without a fresh frame"
    )
    print(path)


def _evaluate(args):
    controller, sim = _controller(args)
    controller.workspace_margin = None  # the package's own references: extrapolation is scored, as in the studies
    references = reference_set(sim, args.references)
    results, _ = control.evaluate(controller, references, sim)
    means = results.groupby("family", sort=False).rmse_mm.mean().reset_index().assign(reference="mean")
    table = pd.concat([results[["reference", "family", "rmse_mm"]], means[["reference", "family", "rmse_mm"]]])
    print(
        f"{args.model} ({args.profile} profile, {args.robot} rod, {args.gravity}): open-loop tracking RMSE (mm), "
        f"{len(references)} references"
    )
    print(table.to_string(index=False, float_format="%.2f"))
    paper_rod = (args.robot, args.gravity, args.profile) == (SIM_ROBOT.name, "vertical", "paper")
    if paper_rod and args.references == "table1" and args.model in tables.MODELS:
        row = tables.table1(get_profile("paper")).loc[args.model]
        print(
            f"Table I (figures/table1_tracking.csv): shape {row[('shape_mm', 'ours')]:.2f}, "
            f"random {row[('random_mm', 'ours')]:.2f}"
        )


if __name__ == "__main__":
    main()
