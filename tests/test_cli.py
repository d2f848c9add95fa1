"""The `softflow` command line: one verb per job with its own help, bad arguments exit 2, and
each verb's output is what the package computes (shipped models only: nothing is trained here)."""

import runpy
import sys

import numpy as np
import pandas as pd
import pytest

from softflow import cli, control, data
from softflow.data import references
from softflow.models import checkpoints
from softflow.report import model_cards
from softflow.rod import rod_folder
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT
from softflow.store import REPO

VERBS = ["data", "check", "train", "sweep", "models", "plan", "evaluate", "export"]


def run(capsys, *argv) -> list[str]:
    """stdout lines of one call."""
    cli.main(argv)
    return capsys.readouterr().out.strip().splitlines()


def exit_code(capsys, *argv) -> tuple[int, str]:
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    return stop.value.code, capsys.readouterr().err


@pytest.fixture
def references_cache(tmp_path, monkeypatch):
    """References are cached in a test folder, not in data/."""
    monkeypatch.setattr(references, "DATA_DIR", tmp_path / "cache")


@pytest.mark.parametrize("verb", VERBS)
def test_each_verb_has_its_own_help(verb, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main([verb, "--help"])
    out = capsys.readouterr().out
    assert stop.value.code == 0
    assert out.startswith(f"usage: softflow {verb}")
    assert "verbs:" not in out  # not the global help


def test_global_help_lists_every_verb(capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["--help"])
    out = capsys.readouterr().out
    assert stop.value.code == 0
    assert all(f"\n    {verb} " in out for verb in VERBS)


# argparse's own refusals come with the usage block; the verbs' checks after parsing without it
PARSE_ERRORS = ("required", "invalid choice", "argument ", "expected a positive", "unrecognized")


@pytest.mark.parametrize(
    "argv, message",
    [
        ([], "required: VERB"),
        (["nosuch"], "invalid choice: 'nosuch'"),
        (["plan", "rf-fwd", "--shape", "nosuch", "--out", "u.csv"], "argument --shape: invalid choice"),
        (["plan", "rf-fwd", "--shape", "circle"], "required: --out"),
        (["plan", "forward", "--shape", "circle", "--out", "u.csv"], "argument MODEL: invalid choice: 'forward'"),
        (["plan", "mlp", "--shape", "circle", "--size", "-0.1", "--out", "u.csv"], "expected a positive number"),
        (["plan", "mlp", "--shape", "circle", "--size", "inf", "--out", "u.csv"], "expected a positive number"),
        (["evaluate", "rf-fwd", "--references", "burst"], "argument --references: invalid choice"),
        (["export", "rf-fwd", "--out", "c.csv"], "--shape is needed"),
        (["export", "rf-fwd", "--shape", "circle"], "--out FILE.csv is needed (or --onnx FILE.onnx"),
        (["export", "rf-fwd", "--onnx", "f.onnx", "--shape", "circle"], "--shape: options of a command file"),
        (["export", "rf-fwd", "--onnx", "f.onnx", "--tip", "x_m,y_m"], "--tip describe recordings; they need"),
        (["export", "mlp", "--recordings", "runs", "--out", "c.csv"], "--recordings: a model of recorded runs has no"),
        (["plan", "mlp", "--out", "u.csv"], "--shape is needed (or, for a model of recorded runs, --recordings"),
        (["train"], "required: MODEL"),
        (["train", "nosuch"], "argument MODEL: invalid choice"),
        (["train", "--profile", "ci", "--ship", "mlp"], "--ship writes the paper profile's checkpoints"),
        (["sweep", "smoke"], "required: --profile"),
        (["models", "--robot", "hw"], "unrecognized arguments"),
        # bad input found after parsing exits 2 the same way, with the package's message and no usage block
        (["plan", "rf", "--robot", "hw", "--shape", "circle", "--out", "u.csv"], "no trained 'rf'"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(argv, message, capsys):
    code, err = exit_code(capsys, *argv)
    assert code == 2
    parsed = "usage: softflow" if message.startswith(PARSE_ERRORS) else f"softflow {argv[0]}: error: "
    assert message in err and err.startswith(parsed)


def test_a_refused_recording_names_the_flags_that_help(tmp_path, capsys):
    """The loader's message in the command line's words: --max-gap and --split-at-gaps, not keywords."""
    frames = np.arange(0, 3, 0.01)
    table = pd.DataFrame(dict(time_s=frames, u1=np.sin(frames), x_m=np.sin(frames), y_m=np.cos(frames)))
    table.loc[(frames > 1) & (frames < 1.5), ["x_m", "y_m"]] = np.nan  # half a second without a frame
    for i in range(3):
        table.to_csv(tmp_path / f"run{i}.csv", index=False)
    code, err = exit_code(capsys, "train", "mlp", "--recordings", str(tmp_path), "--profile", "ci")
    assert code == 2 and err.startswith("softflow train: error: ") and "usage" not in err
    assert "the 0.2 s bridged (--max-gap 0.2 s)" in err and "or let --split-at-gaps cut it" in err


def test_an_output_that_is_a_directory_is_refused(tmp_path, capsys):
    code, err = exit_code(capsys, "plan", "mlp", "--shape", "circle", "--out", str(tmp_path))
    assert (code, f"--out {tmp_path} is a directory" in err) == (2, True)


def test_python_dash_m_runs_the_same_cli(capsys, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["softflow", "nosuch"])
    with pytest.raises(SystemExit) as stop:
        runpy.run_module("softflow", run_name="__main__")
    assert stop.value.code == 2 and "invalid choice: 'nosuch'" in capsys.readouterr().err


def test_plan_writes_the_controllers_plan(tmp_path, capsys, references_cache):
    out = tmp_path / "new" / "circle.csv"  # its folder is made
    lines = run(capsys, "plan", "mlp", "--shape", "circle", "--size", "0.02", "--out", str(out))
    assert lines[-1] == str(out)
    sim = Simulator(SIM_ROBOT)
    reference = cli.shape_about_rest_tip(sim, "circle", 0.02)  # from the cache the CLI wrote
    expected = control.load_controller("mlp").plan(reference.states)  # (T, 2)
    table = pd.read_csv(out)
    assert list(table.columns) == ["time_s", "u1_N", "u2_N"]
    assert len(table) == reference.n_steps == len(expected)
    np.testing.assert_allclose(table.time_s, np.arange(len(expected)) * sim.dt, atol=1e-9)
    np.testing.assert_allclose(table[["u1_N", "u2_N"]], expected, atol=5e-7)  # written to 1e-6 N
    assert np.abs(expected).max() > 0.01  # a circle needs actuation: the comparison is not of zeros


def test_export_writes_notebook_06s_command_file(tmp_path, capsys, references_cache):
    """The vertical twin's circle, planned by the shipped twin model and made into motor commands
    as docs/real_robot.md does: the file notebook 06 committed, to its last written digit."""
    out = tmp_path / "circle.csv"
    lines = run(capsys, "export", "rf-fwd", "--robot", "hw", "--shape", "circle", "--out", str(out))
    assert lines[-1] == str(out)
    assert out.read_text().startswith("time_s,l1_mm,l2_mm,l3_mm\n")  # the hardware rod's three cables
    written = pd.read_csv(out)
    shipped = pd.read_csv(REPO / "figures" / "commands" / "vertical" / "circle.csv")
    assert list(written.columns) == list(shipped.columns) and len(written) == len(shipped)
    # Written to 1e-4 mm: float noise across CPUs (AVX2 vs AVX-512 sums) may flip a last digit.
    np.testing.assert_allclose(written.to_numpy(), shipped.to_numpy(), rtol=0, atol=1.01e-4)


def test_evaluate_prints_each_reference_and_the_family_means(capsys, monkeypatch):
    sim = Simulator(SIM_ROBOT)
    short = data.random_references(sim, n=2, seconds=0.4)  # cheap stand-ins for Rand1..Rand4
    monkeypatch.setattr(cli, "reference_set", lambda sim, which: short if which == "random" else [])
    lines = run(capsys, "evaluate", "mlp", "--references", "random")
    expected, _ = control.evaluate(control.load_controller("mlp"), short, sim)
    rows = {tuple(line.split()[:2]): line.split()[2] for line in lines[2:]}
    for reference, rmse in zip(expected.reference, expected.rmse_mm):
        assert rows[(reference, "random")] == f"{rmse:.2f}"
    assert rows[("mean", "random")] == f"{expected.rmse_mm.mean():.2f}"
    assert lines[1].split() == ["reference", "family", "rmse_mm"] and len(lines) == 2 + 2 + 1


def test_models_lists_every_shipped_checkpoint(capsys):
    lines = run(capsys, "models")
    shipped = sorted(str(p.relative_to(REPO)) for p in checkpoints.SHIPPED.rglob("*.pt"))
    listed = sorted(line.split("|")[1].strip() for line in lines[2:])
    assert listed == shipped
    hw = next(line for line in lines if line.startswith("| checkpoints/hw-horizontal-") and "| rf-fwd |" in line)
    assert "| hw | horizontal | paper |" in hw


def test_the_committed_model_cards_are_what_the_generator_writes(capsys):
    printed = run(capsys, "models", "--cards")
    committed = model_cards.README.read_text()
    assert committed == model_cards.model_cards(), (
        "checkpoints/README.md is stale: regenerate it with `softflow models --cards > checkpoints/README.md`"
    )
    assert printed == committed.strip().splitlines()
    assert committed.count("\n### checkpoints/") == len(list(checkpoints.SHIPPED.rglob("*.pt")))


def test_train_prints_the_checkpoint_it_wrote_last(tmp_path, capsys, monkeypatch):
    """The trainer replaced by one that writes a checkpoint record where the real one would."""
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path)

    def fake_trainer(name, profile, dataset, robot, gravity, *, ship, device, progress):
        assert not ship
        assert device == "cpu"  # --device as given, resolved by the sweep's rule
        path = checkpoints.checkpoint_path(name, profile.name, rod_folder(robot, gravity))
        record = checkpoints.identity(name, None, profile.train_config(name), dataset.key)
        record.update(model={}, dims={"inputs": 2, "position": 3}, epochs_run=1, best_val=0.5, wall_seconds=6.0)
        checkpoints.save_checkpoint(record, path)
        return None, record

    monkeypatch.setattr(cli.training, "ensure_trained", fake_trainer)
    lines = run(capsys, "train", "--profile", "ci", "--robot", "hw", "--device", "cpu", "mlp", "rf")
    folder = tmp_path / "ci" / rod_folder(HW_ROBOT, "vertical")
    assert lines[-2:] == [str(folder / "mlp.pt"), str(folder / "rf.pt")]
    assert lines[0].startswith("mlp: 1 epochs")


def test_every_verb_of_a_model_or_a_rod_defaults_to_the_same_rod(tmp_path, capsys):
    """`export rf-fwd-1 --onnx F` finds the model `train rf-fwd-1` makes: a verb with a rod of its
    own would look for a checkpoint that no default command trains."""
    verbs = cli.build_parser()._subparsers._group_actions[0].choices
    defaults = {
        name: (verb.get_default("robot"), verb.get_default("gravity"))
        for name, verb in verbs.items()
        if any(action.dest == "robot" for action in verb._actions)
    }
    assert {"data", "train", "plan", "evaluate", "export"} <= set(defaults)
    # train's is None (not given, so --recordings can refuse a rod), and then the paper's rod
    assert set(defaults.values()) - {(None, None)} == {(SIM_ROBOT.name, "vertical")}
    out = tmp_path / "rf-fwd-1.onnx"
    assert run(capsys, "export", "rf-fwd-1", "--onnx", str(out))[-1] == str(out) and out.stat().st_size > 0


def test_a_missing_model_names_the_train_command_of_its_rod(capsys):
    code, err = exit_code(capsys, "export", "rf-fwd-1", "--robot", "hw", "--onnx", "f.onnx")
    assert code == 2
    assert "train it with: python -m softflow train --profile paper --robot hw --gravity vertical rf-fwd-1" in err
