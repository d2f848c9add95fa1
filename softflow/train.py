"""One training loop for every inverse model: AdamW, warm-up + cosine LR, optional EMA,
validation every epoch, early stopping, atomic checkpoints that resume after an interrupt."""
from __future__ import annotations

import copy
import inspect
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from .data import Dataset
from .models.baselines import InverseLSTM, InverseMLP, InverseTransformer
from .models.common import one_thread
from .models.flow import RectifiedFlow
from .models.forward import ForwardModel
from .profiles import TrainConfig

MODELS = {  # name -> (class, keyword arguments)
    "mlp": (InverseMLP, {}),
    "lstm": (InverseLSTM, {"context": 10}),
    "transformer": (InverseTransformer, {"context": 10}),
    "forward": (ForwardModel, {}),
    "rf": (RectifiedFlow, {}),
    "rf-physical": (RectifiedFlow, {"prior": "vertical"}),
    "rf-fwd": (RectifiedFlow, {"consistency": 1.0}),
}


def resolved_kwargs(name: str, **overrides) -> dict:
    """Every constructor argument of model ``name``: its class defaults, then the registry's,
    then ``overrides``. A checkpoint records these, so changing any default makes it stale."""
    if name not in MODELS:
        raise ValueError(f"model must be one of {sorted(MODELS)}; got {name!r}")
    cls, kwargs = MODELS[name]
    try:
        arguments = inspect.signature(cls).bind(**{**kwargs, **overrides})
    except TypeError as error:
        raise ValueError(f"bad arguments for model {name!r}: {error}") from error
    arguments.apply_defaults()
    return dict(arguments.arguments)


def build_model(name: str, **overrides) -> torch.nn.Module:
    return MODELS[name][0](**resolved_kwargs(name, **overrides))


def gather_windows(states: np.ndarray, episodes, steps, context: int) -> np.ndarray:
    """States x_{t-context+1} .. x_{t+1} for each (episode, t): (B, context+1, 6). Before the
    first sample the window repeats x_0, the rest pose the robot held before it moved."""
    index = np.clip(np.asarray(steps)[:, None] + np.arange(-context + 1, 2), 0, None)
    return states[np.asarray(episodes)[:, None], index]


class Sampler:
    """Random (episode, t) training pairs of a split, gathered into tensors per batch:
    (window, u, extras) with extras {name: (B, k)} from per-step arrays (E, T, k)."""

    def __init__(self, dataset: Dataset, episodes, context: int, rng: np.random.Generator, extras: dict | None = None):
        self.states, self.u, self.episodes, self.context, self.rng = dataset.states, dataset.u, np.asarray(episodes), context, rng
        self.extras = extras or {}
        self.n_steps = dataset.u.shape[1]

    def batch(self, size: int):
        episodes = self.episodes[self.rng.integers(0, len(self.episodes), size)]
        steps = self.rng.integers(0, self.n_steps, size)
        return self.tensors(episodes, steps)

    def tensors(self, episodes, steps):
        window = gather_windows(self.states, episodes, steps, self.context)
        extras = {k: torch.as_tensor(v[episodes, steps], dtype=torch.float32) for k, v in self.extras.items()}
        return (torch.as_tensor(window, dtype=torch.float32), torch.as_tensor(self.u[episodes, steps], dtype=torch.float32),
                extras)

    def fixed(self, n: int, seed: int):
        """A fixed, seeded set of n pairs (for validation)."""
        rng = np.random.default_rng(seed)
        return self.tensors(self.episodes[rng.integers(0, len(self.episodes), n)], rng.integers(0, self.n_steps, n))


def get_lr(step: int, config: TrainConfig) -> float:
    """Linear warm-up, then cosine decay to a tenth of the peak at the last planned step."""
    total = config.epochs * config.steps_per_epoch
    if step < config.warmup_steps:
        return config.lr * (step + 1) / config.warmup_steps
    progress = min(1.0, (step - config.warmup_steps) / max(1, total - config.warmup_steps))
    return config.lr * (0.1 + 0.9 * 0.5 * (1 + np.cos(np.pi * progress)))


def _update_ema(ema, model, step: int, decay: float):
    """Exponential moving average with warm-up (decay grows from 0.1 towards ``decay``)."""
    d = min(decay, (1 + step) / (10 + step))
    with torch.no_grad():
        for pe, p in zip(ema.parameters(), model.parameters()):
            pe.mul_(d).add_(p.detach(), alpha=1 - d)


def save_atomic(obj, path: Path):
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def load_checkpoint(path: Path) -> dict:
    """A checkpoint dict, or a ValueError naming the file when it is corrupt or foreign."""
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as error:
        raise ValueError(f"checkpoint {path} is corrupt or unreadable ({type(error).__name__}); delete it to retrain") from error
    if not isinstance(checkpoint, dict) or not {"name", "model_kwargs", "model"} <= checkpoint.keys():
        raise ValueError(f"checkpoint {path} is not a softflow model checkpoint; delete it to retrain")
    return checkpoint


def model_from_checkpoint(checkpoint: dict, path: Path | str = "<memory>") -> torch.nn.Module:
    model = build_model(checkpoint["name"], **checkpoint["model_kwargs"])
    try:
        model.load_state_dict(checkpoint["model"])
    except RuntimeError as error:
        raise ValueError(f"checkpoint {path} does not match the current {checkpoint['name']} model: {error}") from error
    return model.eval()


def _evaluate(model, window, u, extras, batch: int = 4096) -> float:
    """Validation loss; seeded, so a flow's random tau and z are the same every epoch."""
    with torch.no_grad(), torch.random.fork_rng():
        torch.manual_seed(0)
        losses = [model.compute_loss(window[i:i + batch], u[i:i + batch], **{k: v[i:i + batch] for k, v in extras.items()})
                  .item() * len(window[i:i + batch]) for i in range(0, len(window), batch)]
    return float(sum(losses) / len(window))


def train(name: str, dataset: Dataset, config: TrainConfig, path: Path, *, model_kwargs: dict | None = None,
          progress: bool = True) -> tuple[torch.nn.Module, dict]:
    """Train model ``name`` on the dataset's train split; validate on its val split.

    ``path`` receives the final checkpoint (best validation weights, EMA if enabled);
    ``path``.latest holds the state to resume from after an interrupt. A finished
    checkpoint with the same configuration is returned without training.
    """
    with one_thread():
        return _train(name, dataset, config, Path(path), resolved_kwargs(name, **(model_kwargs or {})), progress)


def _train(name: str, dataset: Dataset, config: TrainConfig, path: Path, model_kwargs: dict, progress: bool):
    path.parent.mkdir(parents=True, exist_ok=True)
    identity = dict(name=name, model_kwargs=model_kwargs, train_config=asdict(config), data_key=dataset.key)
    if path.exists():
        finished = load_checkpoint(path)
        if {k: finished.get(k) for k in identity} == identity:
            return model_from_checkpoint(finished, path), finished

    torch.manual_seed(config.seed)
    model = build_model(name, **model_kwargs)
    extras = model.extras(dataset.states)
    as_tensor = lambda a: torch.as_tensor(a[dataset.train], dtype=torch.float32)  # noqa: E731
    model.set_normalizer(as_tensor(dataset.states), as_tensor(dataset.u), **{k: as_tensor(v) for k, v in extras.items()})
    model.prepare(dataset, config, path)
    torch.manual_seed(config.seed + 1)  # the same stream whether prepare trained something or read a cache
    ema = copy.deepcopy(model) if config.ema_decay else None
    optimizer = torch.optim.AdamW([p for p in model.parameters() if p.requires_grad], lr=config.lr,
                                  weight_decay=config.weight_decay)
    rng = np.random.default_rng(config.seed)
    sampler = Sampler(dataset, dataset.train, model.context, rng, extras)
    val_window, val_u, val_extras = Sampler(dataset, dataset.val, model.context, rng, extras).fixed(config.val_samples,
                                                                                                    config.seed + 1)
    state = dict(epoch=0, step=0, best_val=float("inf"), best_model=None, stale=0, history=[], wall_seconds=0.0)

    latest = path.with_name(path.name + ".latest")
    if latest.exists():
        resumed = load_checkpoint(latest)
        if {k: resumed.get(k) for k in identity} == identity:
            model.load_state_dict(resumed["model"])
            if ema is not None:
                ema.load_state_dict(resumed["ema"])
            optimizer.load_state_dict(resumed["optimizer"])
            rng.bit_generator.state = resumed["numpy_rng"]
            torch.set_rng_state(resumed["torch_rng"])
            state = resumed["state"]

    bar = tqdm(total=config.epochs, initial=state["epoch"], disable=not progress, desc=f"training {name}", unit="epoch")
    while state["epoch"] < config.epochs and state["stale"] < config.patience:
        start = time.perf_counter()
        model.train()
        for _ in range(config.steps_per_epoch):
            for group in optimizer.param_groups:
                group["lr"] = get_lr(state["step"], config)
            window, u, batch_extras = sampler.batch(config.batch_size)
            loss = model.compute_loss(window, u, **batch_extras)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            if ema is not None:
                _update_ema(ema, model, state["step"], config.ema_decay)
            state["step"] += 1
        evaluated = (ema if ema is not None else model).eval()
        val = _evaluate(evaluated, val_window, val_u, val_extras)
        state["epoch"] += 1
        state["history"].append(dict(epoch=state["epoch"], train_loss=loss.item(), val_loss=val))
        if val < state["best_val"]:
            state.update(best_val=val, best_model=copy.deepcopy(evaluated.state_dict()), stale=0)
        else:
            state["stale"] += 1
        state["wall_seconds"] += time.perf_counter() - start
        save_atomic(dict(identity, model=model.state_dict(), ema=ema.state_dict() if ema is not None else None,
                         optimizer=optimizer.state_dict(), numpy_rng=rng.bit_generator.state,
                         torch_rng=torch.get_rng_state(), state=state), latest)
        bar.update(1)
        bar.set_postfix(val=f"{val:.4f}")
    bar.close()

    final = dict(identity, model=state["best_model"], best_val=state["best_val"], history=state["history"],
                 epochs_run=state["epoch"], wall_seconds=state["wall_seconds"])
    save_atomic(final, path)
    latest.unlink(missing_ok=True)
    return model_from_checkpoint(final, path), final
