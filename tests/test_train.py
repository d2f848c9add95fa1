"""The training loop's schedule, EMA and model selection, against hand-worked values."""

import math

import numpy as np
import pytest
import torch
from small_runs import SMALL

from softflow import data, training
from softflow.profiles import TrainConfig
from softflow.training import trainer

CONFIG = TrainConfig(epochs=2, steps_per_epoch=10, lr=1e-3, warmup_steps=4)  # 20 planned steps


def test_learning_rate_warms_up_linearly_then_decays_by_cosine_to_a_tenth():
    lr = [training.get_lr(step, CONFIG) for step in range(25)]
    np.testing.assert_allclose(lr[:4], [2.5e-4, 5e-4, 7.5e-4, 1e-3], rtol=1e-12)  # (step + 1) / warmup
    middle = 4 + (20 - 4) // 2  # half-way through the decay: 0.1 + 0.9 * 0.5 * (1 + cos(pi / 2)) = 0.55
    assert lr[middle] == pytest.approx(0.55e-3, rel=1e-12)
    assert lr[20] == pytest.approx(1e-4, rel=1e-12) and lr[24] == pytest.approx(1e-4, rel=1e-12)  # stays at 10 %
    assert all(a >= b for a, b in zip(lr[4:21], lr[5:21]))  # monotone after the warm-up


def test_ema_follows_the_hand_worked_warm_up_of_its_decay():
    model, ema = torch.nn.Linear(1, 1, bias=False), torch.nn.Linear(1, 1, bias=False)
    with torch.no_grad():
        ema.weight.fill_(0.0)
        model.weight.fill_(1.0)
    trainer._update_ema(ema, model, step=0, decay=0.999)  # d = min(0.999, 1 / 10) = 0.1: 0.1 * 0 + 0.9 * 1
    assert ema.weight.item() == pytest.approx(0.9, rel=1e-6)
    with torch.no_grad():
        model.weight.fill_(3.0)
    trainer._update_ema(ema, model, step=1, decay=0.999)  # d = 2 / 11
    assert ema.weight.item() == pytest.approx(2 / 11 * 0.9 + 9 / 11 * 3.0, rel=1e-6)
    trainer._update_ema(ema, model, step=10**6, decay=0.5)  # late: d = decay
    assert ema.weight.item() == pytest.approx(0.5 * (2 / 11 * 0.9 + 9 / 11 * 3.0) + 0.5 * 3.0, rel=1e-6)


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    return data.load_dataset(SMALL, data_dir=tmp_path_factory.mktemp("data"), progress=False)


def scripted(monkeypatch, losses):
    """Make the validation return ``losses`` in turn; record the weights it was shown."""
    shown = []

    def fake_evaluate(model, *args):
        shown.append({k: v.clone() for k, v in model.state_dict().items()})
        return losses[len(shown) - 1]

    monkeypatch.setattr(trainer, "_evaluate", fake_evaluate)
    return shown


def test_the_checkpoint_holds_the_weights_of_the_best_validation_epoch(tiny_dataset, tmp_path, monkeypatch):
    shown = scripted(monkeypatch, [3.0, 1.0, 2.0, 2.5])
    config = TrainConfig(epochs=4, steps_per_epoch=5, batch_size=64, warmup_steps=2, val_samples=200, patience=10)
    model, checkpoint = training.train(
        "mlp", tiny_dataset, config, tmp_path / "mlp.pt", model_kwargs={"hidden": 16}, progress=False
    )
    assert checkpoint["epochs_run"] == 4 and checkpoint["best_val"] == 1.0
    assert [h["val_loss"] for h in checkpoint["history"]] == [3.0, 1.0, 2.0, 2.5]
    for key, value in model.state_dict().items():
        torch.testing.assert_close(value, shown[1][key], rtol=0, atol=0)  # epoch 2's weights, not the last
    assert not all(torch.equal(shown[1][k], shown[3][k]) for k in shown[1])  # training did move on


def test_training_stops_after_patience_epochs_without_improvement(tiny_dataset, tmp_path, monkeypatch):
    scripted(monkeypatch, [1.0, 2.0, 3.0, 4.0, 5.0])
    config = TrainConfig(epochs=5, steps_per_epoch=5, batch_size=64, warmup_steps=2, val_samples=200, patience=2)
    _, checkpoint = training.train(
        "mlp", tiny_dataset, config, tmp_path / "mlp.pt", model_kwargs={"hidden": 16}, progress=False
    )
    assert checkpoint["epochs_run"] == 3 and checkpoint["best_val"] == 1.0
    assert math.isclose(checkpoint["history"][-1]["val_loss"], 3.0)
