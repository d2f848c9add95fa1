"""Checkpoint files: weights as a state dict beside a JSON-able record of what made them
(model, arguments, budget, data), read without unpickling anything, and where they live.
"""

from __future__ import annotations

import pickle
from dataclasses import asdict
from pathlib import Path

import torch

from softflow.models.common import Dims
from softflow.models.specs import build_model, resolved_kwargs
from softflow.profiles import TrainConfig
from softflow.store import DATA_DIR, REPO, atomic_write

SHIPPED = REPO / "checkpoints"  # paper-profile weights, committed; written only with ship=True
TRAINED = DATA_DIR / "checkpoints"  # every other trained model, rebuilt on demand


def save_checkpoint(checkpoint: dict, path: Path):
    """Write a checkpoint atomically: tensors and JSON-able values only, so that it loads with
    ``weights_only=True``."""
    with atomic_write(path) as f:
        torch.save(checkpoint, f)


def load_checkpoint(path: Path) -> dict:
    """A checkpoint dict, or a ValueError naming the file when it is corrupt or foreign."""
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)  # never unpickle what a file hands us
    except pickle.UnpicklingError as error:
        raise ValueError(
            f"checkpoint {path} holds more than weights and plain values (a pickled object); "
            "refusing to load it (delete it to retrain)"
        ) from error
    except Exception as error:
        raise ValueError(
            f"checkpoint {path} is corrupt or unreadable ({type(error).__name__}); delete it to retrain"
        ) from error
    if not isinstance(checkpoint, dict) or not {"name", "model_kwargs", "model", "dims"} <= checkpoint.keys():
        raise ValueError(f"checkpoint {path} is not a softflow model checkpoint; delete it to retrain")
    return checkpoint


def model_from_checkpoint(checkpoint: dict, path: Path | str = "<memory>") -> torch.nn.Module:
    """The trained model a checkpoint holds, sized as its record says."""
    model = build_model(checkpoint["name"], Dims(**checkpoint["dims"]), **checkpoint["model_kwargs"])
    try:
        model.load_state_dict(checkpoint["model"])
    except RuntimeError as error:
        raise ValueError(f"checkpoint {path} does not match the current {checkpoint['name']} model: {error}") from error
    return model.eval()


def identity(name: str, model_kwargs: dict | None, config: TrainConfig, data_key: str) -> dict:
    """What makes two checkpoints the same model: a checkpoint records it, and one whose
    record differs from today's is stale (trained with other arguments, budget or data)."""
    return dict(
        name=name,
        model_kwargs=resolved_kwargs(name, **(model_kwargs or {})),
        train_config=asdict(config),
        data_key=data_key,
    )


def matches(checkpoint: dict, wanted: dict) -> bool:
    return {k: checkpoint.get(k) for k in wanted} == wanted


def checkpoint_path(
    name: str,
    profile: str,
    rod: str = "",
    model_kwargs: dict | None = None,
    *,
    seed: int = 0,
    shipped: bool = False,
    root: Path | None = None,
) -> Path:
    """Where model ``name`` of a profile is trained to, in the sub-folder ``rod`` of its rod and
    gravity (``rod.rod_folder``; "" for the paper's simulation rod). ``shipped``: its committed
    copy in checkpoints/, paper profile and seed 0 only; ``root``: another folder than
    data/checkpoints/<profile>, a sweep's own. Variants with other constructor arguments (a
    size sweep) go to variants/, named after the arguments that differ; other seeds as -seedN."""
    if shipped and (profile != "paper" or seed != 0 or root is not None):
        raise ValueError(
            f"only seed-0 paper-profile models ship in {SHIPPED}; got profile {profile!r}, seed {seed!r}"
            + (f", root {root}" if root is not None else "")
        )
    if not (isinstance(seed, int) and seed >= 0):
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    folder = (SHIPPED if shipped else Path(root) if root is not None else TRAINED / profile) / rod
    default, chosen = resolved_kwargs(name), resolved_kwargs(name, **(model_kwargs or {}))
    changed = "-".join(f"{key}{value}" for key, value in chosen.items() if value != default[key])
    stem = f"{name}-{changed}" if changed else name
    stem += f"-seed{seed}" if seed else ""
    return folder / "variants" / f"{stem}.pt" if changed else folder / f"{stem}.pt"


def find_checkpoint(
    name: str, profile: str, wanted: dict, rod: str = "", model_kwargs: dict | None = None
) -> tuple[Path | None, bool]:
    """The checkpoint to use for model ``name`` and whether it is current (its record
    ``matches`` the ``wanted`` identity): a user-trained one that is current, else the shipped
    one, else whichever exists (stale). (None, False) when there is none."""
    candidates = [checkpoint_path(name, profile, rod, model_kwargs)]
    if profile == "paper":
        candidates.append(checkpoint_path(name, profile, rod, model_kwargs, shipped=True))
    existing = [path for path in candidates if path.exists()]
    for path in existing:
        if matches(load_checkpoint(path), wanted):
            return path, True
    return (existing[0], False) if existing else (None, False)
