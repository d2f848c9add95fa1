"""Checkpoints are found by content: every shipped one loads current, and a model trained
for another rod, even one that keeps the name of a shipped rod, never touches checkpoints/."""

import dataclasses
import functools
import hashlib
import warnings

import numpy as np
import pytest
import torch

from softflow import control, data, training
from softflow.models import checkpoints
from softflow.models.specs import resolved_kwargs
from softflow.profiles import Profile, TrainConfig
from softflow.rod import rod_folder
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT, SIM_ROBOT, TWO_SEGMENT_ROD

RODS = [(SIM_ROBOT, "vertical"), (HW_ROBOT, "vertical"), (HW_ROBOT, "horizontal"), (TWO_SEGMENT_ROD, "vertical")]
TINY = TrainConfig(epochs=1, steps_per_epoch=5, batch_size=32, warmup_steps=2, val_samples=100, patience=1)


def shipped_files():
    return sorted(p for p in checkpoints.SHIPPED.rglob("*.pt"))


def tree_digest(folder):
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def rod_of(path):
    folder = path.parent.parent if path.parent.name == "variants" else path.parent
    matches = [
        (robot, gravity) for robot, gravity in RODS if checkpoints.SHIPPED / rod_folder(robot, gravity) == folder
    ]
    assert len(matches) == 1, f"{path} is in no known rod's folder"
    return matches[0]


@functools.cache
def gentle_motion(robot, gravity):
    """0.4 s of the rod from rest under a slow ramp of every input to 1 N (40 states): a
    reference each of its models can plan, one short rollout per rod."""
    ramp = np.linspace(0.0, 1.0, 39)[None, :, None] * np.ones(robot.n_inputs)  # (1, 39, m) N
    return Simulator(robot, gravity).rollout(ramp)[0]


@pytest.mark.parametrize("path", shipped_files(), ids=lambda p: str(p.relative_to(checkpoints.SHIPPED)))
def test_every_shipped_checkpoint_is_current_and_plans(path):
    checkpoint = checkpoints.load_checkpoint(path)
    robot, gravity = rod_of(path)
    name = checkpoint["name"]
    default = resolved_kwargs(name)
    variant = {k: v for k, v in checkpoint["model_kwargs"].items() if v != default[k]}
    assert control.find_trained(name, "paper", robot, gravity, variant) == (path, True)
    if name == "forward":
        return
    reference = gentle_motion(robot, gravity)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no staleness warning, no saturation
        controller = (
            control.load_controller(name, "paper", robot, gravity)
            if not variant
            else control.Controller(
                checkpoints.model_from_checkpoint(checkpoint, path), name, robot=robot, gravity=gravity
            )
        )
        u = controller.plan(reference)
    assert u.shape == (39, robot.n_inputs) and np.isfinite(u).all()


def test_a_calibrated_rod_with_a_shipped_name_trains_outside_checkpoints(tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path / "trained")
    before = tree_digest(checkpoints.SHIPPED)
    calibrated = dataclasses.replace(HW_ROBOT, youngs_modulus=0.85 * HW_ROBOT.youngs_modulus)  # still named "hw"
    paper_sized = Profile("paper", n_episodes=10, episode_seconds=0.3, train=TINY)
    dataset = data.load_dataset(paper_sized, calibrated, "horizontal", data_dir=tmp_path / "data", progress=False)
    training.ensure_trained("rf-fwd", paper_sized, dataset, calibrated, "horizontal")
    assert tree_digest(checkpoints.SHIPPED) == before
    folder = tmp_path / "trained" / "paper" / rod_folder(calibrated, "horizontal")
    assert sorted(p.name for p in folder.iterdir()) == ["forward.pt", "rf-fwd.pt"]
    assert rod_folder(calibrated, "horizontal") != rod_folder(HW_ROBOT, "horizontal")


def test_only_ship_writes_the_shipped_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoints, "SHIPPED", tmp_path / "shipped")
    monkeypatch.setattr(checkpoints, "TRAINED", tmp_path / "trained")
    paper_sized = Profile("paper", n_episodes=10, episode_seconds=0.3, train=TINY)
    dataset = data.load_dataset(paper_sized, data_dir=tmp_path / "data", progress=False)
    training.ensure_trained("mlp", paper_sized, dataset)
    assert not (tmp_path / "shipped").exists() and (tmp_path / "trained" / "paper" / "mlp.pt").exists()
    training.ensure_trained("mlp", paper_sized, dataset, ship=True)
    assert (tmp_path / "shipped" / "mlp.pt").exists()
    with pytest.raises(ValueError, match="only seed-0 paper-profile models ship"):
        checkpoints.checkpoint_path("mlp", "ci", shipped=True)
    with pytest.raises(ValueError, match="dataset was made for 'sim' / 'vertical', not 'hw' / 'vertical'"):
        training.ensure_trained("mlp", paper_sized, dataset, HW_ROBOT)


def test_other_seeds_train_apart_from_the_shipped_model(tmp_path, monkeypatch):
    """Seed 0 of the paper profile is the shipped model; seed 1 trains (with its surrogate, on
    the same seed) into the folder it is given, with other weights."""
    monkeypatch.setattr(checkpoints, "SHIPPED", tmp_path / "shipped")
    paper_sized = Profile("paper", n_episodes=10, episode_seconds=0.3, train=TINY)
    dataset = data.load_dataset(paper_sized, data_dir=tmp_path / "data", progress=False)
    shipped_model, _ = training.ensure_trained("rf-fwd", paper_sized, dataset, ship=True)
    reused, _ = training.ensure_trained("rf-fwd", paper_sized, dataset, root=tmp_path / "sweep")
    assert not (tmp_path / "sweep").exists()  # seed 0 is the shipped model
    other, checkpoint = training.ensure_trained("rf-fwd", paper_sized, dataset, seed=1, root=tmp_path / "sweep")
    assert sorted(p.name for p in (tmp_path / "sweep").iterdir()) == ["forward-seed1.pt", "rf-fwd-seed1.pt"]
    assert checkpoint["train_config"]["seed"] == 1
    weights = [dict(m.named_parameters())["net.0.weight"] for m in (shipped_model, reused, other)]
    assert torch.equal(weights[0], weights[1]) and not torch.equal(weights[0], weights[2])
    assert checkpoints.checkpoint_path("mlp", "ci", seed=2) == checkpoints.TRAINED / "ci" / "mlp-seed2.pt"
    with pytest.raises(ValueError, match="only seed-0 paper-profile models ship"):
        checkpoints.checkpoint_path("mlp", "paper", seed=1, shipped=True)
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        checkpoints.checkpoint_path("mlp", "paper", seed=-1)


class _Payload:
    """An object a checkpoint file could smuggle in: unpickling it would run its code."""

    def __reduce__(self):
        return (print, ("unpickled!",))


def test_a_checkpoint_carrying_a_pickled_object_is_refused(tmp_path, capsys):
    path = tmp_path / "evil.pt"
    torch.save({"name": "mlp", "model_kwargs": {}, "model": {}, "payload": _Payload()}, path)
    with pytest.raises(ValueError, match="pickled object"):
        checkpoints.load_checkpoint(path)
    assert "unpickled!" not in capsys.readouterr().out  # nothing ran
    plain = tmp_path / "plain.pt"
    record = {"name": "mlp", "model_kwargs": {}, "model": {"w": torch.ones(2)}, "dims": {"inputs": 2, "position": 3}}
    checkpoints.save_checkpoint(record, plain)
    assert checkpoints.load_checkpoint(plain)["model"]["w"].tolist() == [1.0, 1.0]


def test_the_two_segment_study_ships_its_seed_0_models_and_never_overwrites(tmp_path, monkeypatch):
    from softflow.studies import two_segment

    monkeypatch.setattr(checkpoints, "SHIPPED", tmp_path / "shipped")
    rod = rod_folder(TWO_SEGMENT_ROD, "vertical")
    trained = checkpoints.checkpoint_path("mlp", "paper", rod, root=tmp_path / "study" / "models" / "paper" / "tip")
    trained.parent.mkdir(parents=True)
    trained.write_bytes(b"weights of seed 0")
    checkpoints.checkpoint_path("mlp", "paper", rod, seed=1, root=trained.parent.parent).write_bytes(b"seed 1")
    shipped = two_segment.ship_models(tmp_path / "study")  # every model the study has trained so far
    assert shipped == [tmp_path / "shipped" / rod / "mlp.pt"] and shipped[0].read_bytes() == b"weights of seed 0"
    assert two_segment.ship_models(tmp_path / "study", ["mlp"]) == shipped  # the same bytes again: nothing lost
    trained.write_bytes(b"retrained")
    with pytest.raises(ValueError, match="is shipped and differs"):
        two_segment.ship_models(tmp_path / "study", ["mlp"])
    assert shipped[0].read_bytes() == b"weights of seed 0"
    with pytest.raises(ValueError, match="no seed-0 'forward' of the study"):
        two_segment.ship_models(tmp_path / "study", ["rf-fwd"])  # its surrogate first: not trained either
    surrogate = tmp_path / "shipped" / rod / "forward.pt"
    surrogate.write_bytes(b"the shipped surrogate")  # already shipped, so the study trained RF-FWD against it
    checkpoints.checkpoint_path("rf-fwd", "paper", rod, root=trained.parent.parent).write_bytes(b"rf-fwd of seed 0")
    assert two_segment.ship_models(tmp_path / "study", ["rf-fwd"]) == [tmp_path / "shipped" / rod / "rf-fwd.pt"]
    assert surrogate.read_bytes() == b"the shipped surrogate"
