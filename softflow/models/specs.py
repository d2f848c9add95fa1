"""Inverse models u_t = g(x_{t-K+1}, ..., x_t, x_{t+1}): deterministic baselines and the RF
family, and the registry that names them.

The registry is the one place that says which class and arguments a name means and which
models must be trained first (RF-FWD's frozen forward surrogate): the training loop
trains those and hands them to ``model.attach``, so no model module imports the loop.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field

from torch import nn

from .baselines import InverseLSTM, InverseMLP, InverseTransformer, PhysicalMLP
from .common import PAPER_DIMS, Dims
from .flow import MeanFlow, RectifiedFlow
from .forward import ForwardModel


@dataclass(frozen=True)
class ModelSpec:
    cls: type
    label: str  # the name tables and verdicts print ("" for RF-FWD's surrogate, never one of theirs)
    kwargs: dict = field(default_factory=dict)
    requires: tuple[str, ...] = ()  # models trained first and passed to ``attach`` by name
    group: str = ""  # the studies' sides: "regression" (the baselines) or "flow" ("": neither)


MODELS = {
    "mlp": ModelSpec(InverseMLP, "MLP", group="regression"),
    "mlp-physical": ModelSpec(PhysicalMLP, "MLP-Physical", group="regression"),
    "lstm": ModelSpec(InverseLSTM, "LSTM", {"context": 10}, group="regression"),
    "transformer": ModelSpec(InverseTransformer, "Transformer", {"context": 10}, group="regression"),
    "forward": ModelSpec(ForwardModel, ""),
    "rf": ModelSpec(RectifiedFlow, "RF", group="flow"),
    "rf-physical": ModelSpec(RectifiedFlow, "RF-Physical", {"prior": True}, group="flow"),
    "rf-fwd": ModelSpec(RectifiedFlow, "RF-FWD", {"consistency": 1.0}, requires=("forward",), group="flow"),
    "rf-1": ModelSpec(MeanFlow, "RF-1", {"steps": 1}, group="flow"),
    "rf-fwd-1": ModelSpec(MeanFlow, "RF-FWD-1", {"steps": 1, "consistency": 1.0}, requires=("forward",), group="flow"),
    "rf-physical-1": ModelSpec(MeanFlow, "RF-Physical-1", {"steps": 1, "prior": True}, group="flow"),
}
# The studies' two sides: each model's group, in this order (best flow against best baseline).
FLOWS = tuple(name for name, spec in MODELS.items() if spec.group == "flow")
BASELINES = tuple(name for name, spec in MODELS.items() if spec.group == "regression")
# What load_controller loads: every inverse model, not RF-FWD's forward surrogate.
CONTROLLERS = tuple(name for name, spec in MODELS.items() if spec.cls is not ForwardModel)


def label(name: str) -> str:
    """The printed name of model ``name`` (``MODELS``); a plan of it at k steps, ``name@k``, is
    ``label@k`` (k = 0: a regression, which has no steps)."""
    model, _, steps = name.partition("@")
    return model_spec(model).label + (f"@{steps}" if steps not in ("", "0") else "")


def model_spec(name: str) -> ModelSpec:
    if name not in MODELS:
        raise ValueError(f"model must be one of {sorted(MODELS)}; got {name!r}")
    return MODELS[name]


def resolved_kwargs(name: str, **overrides) -> dict:
    """Every constructor argument of model ``name``: its class defaults, then the registry's,
    then ``overrides``. A checkpoint records these, so changing any default makes it stale. The
    sizes (``dims``) are not among them: they come from the data, which the record names."""
    spec = model_spec(name)
    if "dims" in overrides:
        raise ValueError("the sizes are not a model argument: pass dims= to build_model")
    try:
        arguments = inspect.signature(spec.cls).bind(**{**spec.kwargs, **overrides})
    except TypeError as error:
        raise ValueError(f"bad arguments for model {name!r}: {error}") from error
    arguments.apply_defaults()
    return {key: value for key, value in arguments.arguments.items() if key != "dims"}


def build_model(name: str, dims: Dims = PAPER_DIMS, **overrides) -> nn.Module:
    """Model ``name`` with the registry's arguments and ``overrides``, sized by ``dims``."""
    return model_spec(name).cls(**resolved_kwargs(name, **overrides), dims=dims)
