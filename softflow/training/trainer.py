"""One training loop for every inverse model (AdamW, warm-up + cosine LR, optional EMA,
validation every epoch, early stopping, atomic checkpoints that resume after an
interrupt), and ``ensure_trained``: the current checkpoint of a model, or train it.

Checkpoints are found by content, never by a rod's name: a model's folder is keyed by
the parameters of the rod and the gravity it was trained for. The paper-profile weights
in ``checkpoints/`` ship with the repository and are only read; a model trained by a
user, a notebook or a sweep goes to ``data/checkpoints/``. Only ``ship=True`` (the
``--ship`` flag of ``python -m softflow train``) writes ``checkpoints/``.
"""

from __future__ import annotations

import copy
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from softflow.data.dataset import Dataset, gather_windows
from softflow.models.checkpoints import (
    checkpoint_path,
    identity,
    load_checkpoint,
    matches,
    model_from_checkpoint,
    save_checkpoint,
)
from softflow.models.common import one_thread
from softflow.models.specs import build_model, model_spec
from softflow.profiles import Profile, TrainConfig
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import SIM_ROBOT, Robot, rod_folder


class Sampler:
    """Random (episode, t) training pairs of a split, gathered into tensors per batch:
    (window, u, extras) with extras {name: (B, k)} from per-step arrays (E, T, k)."""

    def __init__(self, dataset: Dataset, episodes, context: int, rng: np.random.Generator, extras: dict | None = None):
        self.states, self.u, self.episodes, self.context, self.rng = (
            dataset.states,
            dataset.u,
            np.asarray(episodes),
            context,
            rng,
        )
        self.extras = extras or {}
        self.n_steps = dataset.u.shape[1]

    def batch(self, size: int):
        episodes = self.episodes[self.rng.integers(0, len(self.episodes), size)]
        steps = self.rng.integers(0, self.n_steps, size)
        return self.tensors(episodes, steps)

    def tensors(self, episodes, steps):
        window = gather_windows(self.states, episodes, steps, self.context)
        extras = {k: torch.as_tensor(v[episodes, steps], dtype=torch.float32) for k, v in self.extras.items()}
        return (
            torch.as_tensor(window, dtype=torch.float32),
            torch.as_tensor(self.u[episodes, steps], dtype=torch.float32),
            extras,
        )

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
    return float(
        config.lr * (0.1 + 0.9 * 0.5 * (1 + np.cos(np.pi * progress)))
    )  # a plain float: checkpoints hold no numpy objects


def _update_ema(ema, model, step: int, decay: float):
    """Exponential moving average with warm-up (decay grows from 0.1 towards ``decay``)."""
    d = min(decay, (1 + step) / (10 + step))
    with torch.no_grad():
        for pe, p in zip(ema.parameters(), model.parameters()):
            pe.mul_(d).add_(p.detach(), alpha=1 - d)


def _evaluate(model, window, u, extras, batch: int = 4096) -> float:
    """Validation loss; seeded, so a flow's random tau and z are the same every epoch."""
    with torch.no_grad(), torch.random.fork_rng():
        torch.manual_seed(0)
        losses = [
            model.compute_loss(
                window[i : i + batch], u[i : i + batch], **{k: v[i : i + batch] for k, v in extras.items()}
            ).item()
            * len(window[i : i + batch])
            for i in range(0, len(window), batch)
        ]
    return float(sum(losses) / len(window))


def train(
    name: str,
    dataset: Dataset,
    config: TrainConfig,
    path: Path,
    *,
    model_kwargs: dict | None = None,
    dependencies: dict | None = None,
    device: str = "cpu",
    progress: bool = True,
) -> tuple[torch.nn.Module, dict]:
    """Train model ``name`` on the dataset's train split; validate on its val split.

    ``path`` receives the final checkpoint (best validation weights, EMA if enabled);
    ``path``.latest holds the state to resume from after an interrupt. A finished
    checkpoint with the same identity is returned without training. ``dependencies``:
    the trained models the registry says ``name`` requires, by name (``ensure_trained``
    trains them). ``device``: where to train ("cpu", "cuda", "mps"); checkpoints hold CPU tensors.
    """
    required, given = set(model_spec(name).requires), set(dependencies or {})
    if required != given:
        raise ValueError(
            f"model {name!r} requires trained {sorted(required) or 'nothing'}; got {sorted(given) or 'nothing'}"
        )
    with one_thread():
        return _train(
            name,
            dataset,
            config,
            Path(path),
            identity(name, model_kwargs, config, dataset.key),
            dependencies or {},
            torch.device(device),
            progress,
        )


def _on_cpu(state_dict: dict) -> dict:
    """A copy of the weights on the CPU: what checkpoints hold, whatever trained them."""
    return {k: v.detach().to("cpu", copy=True) for k, v in state_dict.items()}


def _to(device, window, u, extras):
    return window.to(device), u.to(device), {k: v.to(device) for k, v in extras.items()}


def _train(
    name: str,
    dataset: Dataset,
    config: TrainConfig,
    path: Path,
    identity: dict,
    dependencies: dict,
    device: torch.device,
    progress: bool,
):
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists():
        finished = load_checkpoint(path)
        if matches(finished, identity):
            return model_from_checkpoint(finished, path), finished

    torch.manual_seed(config.seed)
    dims = dataset.dims
    model = build_model(name, dims, **identity["model_kwargs"])
    simulated = dataset.robot is not None  # recorded or synthetic data has no statics
    statics = Simulator(dataset.robot, dataset.gravity).static_table() if model.needs_statics and simulated else None
    extras = model.extras(dataset.states, statics)
    as_tensor = lambda a: torch.as_tensor(a[dataset.train], dtype=torch.float32)  # noqa: E731
    model.set_normalizer(
        as_tensor(dataset.states), as_tensor(dataset.u), **{k: as_tensor(v) for k, v in extras.items()}
    )
    model.attach(**dependencies)
    model.to(device)
    torch.manual_seed(config.seed + 1)  # the stream after set-up, whatever the set-up drew
    ema = copy.deepcopy(model) if config.ema_decay else None
    optimizer = torch.optim.AdamW(
        [p for p in model.parameters() if p.requires_grad], lr=config.lr, weight_decay=config.weight_decay
    )
    rng = np.random.default_rng(config.seed)
    sampler = Sampler(dataset, dataset.train, model.context, rng, extras)
    val_window, val_u, val_extras = _to(
        device, *Sampler(dataset, dataset.val, model.context, rng, extras).fixed(config.val_samples, config.seed + 1)
    )
    state = dict(epoch=0, step=0, best_val=float("inf"), best_model=None, stale=0, history=[], wall_seconds=0.0)

    latest = path.with_name(path.name + ".latest")
    if latest.exists():
        resumed = load_checkpoint(latest)
        if matches(resumed, identity):
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
            window, u, batch_extras = _to(device, *sampler.batch(config.batch_size))
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
            state.update(best_val=val, best_model=_on_cpu(evaluated.state_dict()), stale=0)
        else:
            state["stale"] += 1
        state["wall_seconds"] += time.perf_counter() - start
        save_checkpoint(
            dict(
                identity,
                dims=asdict(dims),
                model=_on_cpu(model.state_dict()),
                ema=_on_cpu(ema.state_dict()) if ema is not None else None,
                optimizer=optimizer.state_dict(),
                numpy_rng=rng.bit_generator.state,
                torch_rng=torch.get_rng_state(),
                state=state,
            ),
            latest,
        )
        bar.update(1)
        bar.set_postfix(val=f"{val:.4f}")
    bar.close()

    final = dict(
        identity,
        dims=asdict(dims),
        model=state["best_model"],
        best_val=state["best_val"],
        history=state["history"],
        epochs_run=state["epoch"],
        wall_seconds=state["wall_seconds"],
    )
    if dataset.robot is None:  # no rod says what the inputs may be: the range they took, to clip plans to
        final["recorded"] = dict(
            dt=float(dataset.dt),
            u_min=dataset.u.min((0, 1)).tolist(),
            u_max=dataset.u.max((0, 1)).tolist(),
            delay_steps=int(dataset.delay_steps),  # plans come advanced by it
            input_columns=list(dataset.input_columns),
            tip_columns=list(dataset.tip_columns),
        )
    save_checkpoint(final, path)
    latest.unlink(missing_ok=True)
    return model_from_checkpoint(final, path), final


def ensure_trained(
    name: str,
    profile: Profile,
    dataset: Dataset,
    robot: Robot | None = SIM_ROBOT,
    gravity: str | None = "vertical",
    *,
    model_kwargs: dict | None = None,
    seed: int = 0,
    root: Path | None = None,
    ship: bool = False,
    device: str = "cpu",
    progress: bool = False,
):
    """Model ``name`` trained on ``dataset`` with the profile's budget for it and training seed
    ``seed``: the shipped checkpoint when it is current (seed 0), else a finished one in
    data/checkpoints/ (or ``root``), else trained there now (``ship=True``: into checkpoints/
    instead, the only way to write it). The models it requires (RF-FWD's surrogate) are
    ensured first, each with its own budget and the same seed. Recorded runs (``robot`` and
    ``gravity`` None, as the dataset's) are trained in a folder named by the dataset's key,
    never shipped."""
    if dataset.robot != robot or dataset.gravity != gravity:
        raise ValueError(
            f"dataset was made for {getattr(dataset.robot, 'name', None)!r} / {dataset.gravity!r}, "
            f"not {getattr(robot, 'name', None)!r} / {gravity!r}"
        )
    if robot is None and ship:
        raise ValueError("only models of the simulated rods ship; a model of recorded runs cannot (ship=False)")
    rod = rod_folder(robot, gravity) if robot is not None else dataset.key
    path = checkpoint_path(name, profile.name, rod, model_kwargs, seed=seed, shipped=ship, root=root)
    config = replace(profile.train_config(name, getattr(robot, "name", None)), seed=seed)
    if profile.ships and not ship and seed == 0:
        shipped = checkpoint_path(name, profile.name, rod, model_kwargs, shipped=True)
        if shipped.exists():
            checkpoint = load_checkpoint(shipped)
            if matches(checkpoint, identity(name, model_kwargs, config, dataset.key)):
                return model_from_checkpoint(checkpoint, shipped), checkpoint
    dependencies = {
        dep: ensure_trained(
            dep, profile, dataset, robot, gravity, seed=seed, root=root, ship=ship, device=device, progress=progress
        )[0]
        for dep in model_spec(name).requires
    }
    return train(
        name,
        dataset,
        config,
        path,
        model_kwargs=model_kwargs,
        dependencies=dependencies,
        device=device,
        progress=progress,
    )
