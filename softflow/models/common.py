"""What every inverse model shares: normalisation inside the module, transition features,
and the interface the training loop and the controller rely on."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import torch
from torch import nn


@contextmanager
def one_thread():
    """Run torch on one thread: these models are small, and two OpenMP threads on a
    2-core machine spin against each other (measured: 75x slower when the other core is busy)."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


@dataclass(frozen=True)
class Dims:
    """The sizes a model reads and writes, taken from its training data, never fixed in a model:
    ``inputs`` actuation channels, and a state of ``position`` tip coordinates followed by their
    velocities. The paper's rods: 2 inputs, a 3-D tip (a 6-D state)."""

    inputs: int = 2
    position: int = 3

    def __post_init__(self):
        for name in ("inputs", "position"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be a positive integer; got {value!r}")

    @property
    def state(self) -> int:
        return 2 * self.position

    @classmethod
    def of(cls, u, states) -> Dims:
        """The sizes of episodes u (E, T, m) and states (E, T+1, d): d must be even (positions,
        then their velocities)."""
        if states.shape[-1] % 2:
            raise ValueError(f"a state holds tip positions and their velocities (an even size); got {states.shape[-1]}")
        return cls(inputs=int(u.shape[-1]), position=int(states.shape[-1]) // 2)


PAPER_DIMS = Dims()


class Normalizer(nn.Module):
    """Per-channel affine normalisation fitted on training data; saved in the state_dict."""

    def __init__(self, dim: int, eps: float = 1e-8):
        super().__init__()
        self.eps = eps
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("std", torch.ones(dim))

    def fit(self, x: torch.Tensor):
        x = x.reshape(-1, x.shape[-1]).double()
        self.mean.copy_(x.mean(0).float())
        self.std.copy_(x.std(0).clamp_min(self.eps).float())  # eps guard for constant channels

    def normalize(self, x):
        return (x - self.mean) / self.std

    def unnormalize(self, x):
        return x * self.std + self.mean


class InverseModel(nn.Module):
    """Base of every model. Inputs are state windows (B, context+1, d) in SI units:
    x_{t-context+1} .. x_t, x_{t+1}; outputs are u_t (B, m); d and m are ``dims`` (6 and 2 for
    the paper's rods).

    Each transition in the window becomes the feature [x_tau, x_{tau+1} - x_tau], each
    part normalised on its own: the same information as (x_tau, x_{tau+1}), but the small
    increment that carries the dynamics is not lost next to the large state.

    A model with ``prior`` learns the residual u - u_phys around the static prior u_phys(p_t+1),
    the inverse statics of its training rod (RF-Physical, MLP-Physical): the prior is one more
    per-step input (``extras``), normalised, and the target is the residual.
    """

    context = 1
    prior = False

    def __init__(self, dims: Dims = PAPER_DIMS):
        super().__init__()
        self.dims = dims
        d, m = dims.state, dims.inputs
        self.state_norm, self.delta_norm, self.action_norm = Normalizer(d), Normalizer(d), Normalizer(m)

    def _add_prior(self):
        """Call from a subclass's __init__ to make it a prior (residual) model."""
        self.prior = True
        self.prior_norm, self.residual_norm = Normalizer(self.dims.inputs), Normalizer(self.dims.inputs)

    @property
    def needs_statics(self) -> bool:
        """True: extras() needs the training rod's static table."""
        return self.prior

    def extras(self, states, statics=None) -> dict:
        """Per-step inputs beyond the state window, computed from states (B, T+1, d) as
        {name: (B, T, k) array}; passed to set_normalizer, compute_loss and predict: the
        static prior u_phys(p_{t+1}) of a prior model, the inverse of ``statics`` (the
        training rod's ``StaticTable``)."""
        if not self.prior:
            return {}
        if statics is None:
            raise ValueError(
                f"{type(self).__name__} learns a residual around the static prior of a simulated rod: it needs "
                "that rod's static table, and this data has none (train a model without a prior on it)"
            )
        return {"prior": statics.inverse(states[:, 1:, : self.dims.position])}

    def attach(self, **dependencies):
        """Receive the trained models the registry says this one requires (before training)."""
        if dependencies:
            raise ValueError(f"{type(self).__name__} takes no trained dependencies; got {sorted(dependencies)}")

    def set_normalizer(self, states: torch.Tensor, u: torch.Tensor, prior: torch.Tensor | None = None):
        """Fit the normalisers on training episodes: states (E, T+1, d), u (E, T, m)."""
        self.state_norm.fit(states[:, :-1])
        self.delta_norm.fit(states[:, 1:] - states[:, :-1])
        self.action_norm.fit(u)
        if self.prior:
            self.prior_norm.fit(prior)
            self.residual_norm.fit(u - prior)

    def features(self, window: torch.Tensor) -> torch.Tensor:
        """(B, context+1, d) states -> (B, context, 2d) normalised transition features."""
        return self._normalised_pair(window[:, :-1], window[:, 1:])

    def _normalised_pair(self, now, nxt):
        """[now, nxt - now] (..., 2d), each part normalised by its own normaliser."""
        return torch.cat([self.state_norm.normalize(now), self.delta_norm.normalize(nxt - now)], -1)

    def condition(self, window, prior=None) -> torch.Tensor:
        """What a per-step model conditions on: the last transition's features, and the
        normalised prior of a prior model, (B, 2d or 2d + m)."""
        return self.transition(window[:, -2], window[:, -1], prior)

    def transition(self, x_t, x_next, prior=None) -> torch.Tensor:
        """``condition`` of the transitions x_t -> x_next, (B, d) each: [x_t, x_next - x_t] and the
        prior, each part normalised (``features`` of one transition)."""
        c = self._normalised_pair(x_t, x_next)
        return torch.cat([c, self.prior_norm.normalize(prior)], -1) if self.prior else c

    def target_norm(self) -> Normalizer:
        """The normaliser of what the model outputs: u, or the residual u - u_phys."""
        return self.residual_norm if self.prior else self.action_norm

    def actuation(self, normalised, prior=None) -> torch.Tensor:
        """u (B, m) of the model's normalised output (B, m): unnormalised, plus the prior of a prior model."""
        u = self.target_norm().unnormalize(normalised)
        return u + prior if self.prior else u

    def compute_loss(self, window: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def predict(self, window: torch.Tensor, **kwargs) -> torch.Tensor:
        raise NotImplementedError


def mlp(sizes, activation=nn.SiLU) -> nn.Sequential:
    """Linear layers of the given sizes with an activation between them (none at the end)."""
    layers = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(activation())
    return nn.Sequential(*layers)
