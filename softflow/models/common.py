"""What every inverse model shares: normalisation inside the module, transition features,
and the interface the training loop and the controller rely on."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from .kernels import network


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
        now, nxt = window[:, :-1], window[:, 1:]
        return torch.cat([self.state_norm.normalize(now), self.delta_norm.normalize(nxt - now)], -1)

    def condition(self, window, prior=None) -> torch.Tensor:
        """What a per-step model conditions on: the last transition's features, and the
        normalised prior of a prior model, (B, 2d or 2d + m)."""
        c = self.features(window[:, -2:])[:, 0]
        return torch.cat([c, self.prior_norm.normalize(prior)], -1) if self.prior else c

    def target_norm(self) -> Normalizer:
        """The normaliser of what the model outputs: u, or the residual u - u_phys."""
        return self.residual_norm if self.prior else self.action_norm

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


def aligned(a, dtype=np.float32) -> np.ndarray:
    """A C-contiguous copy of ``a`` whose data starts on a 64-byte cache line, for the compiled
    step: its vector loads then never straddle two lines (measured: a 4-step flow 25 % slower
    when a matrix started 16 bytes off a line, as numpy's allocator may place it)."""
    a = np.asarray(a, dtype)
    raw = np.empty(a.nbytes + 64, np.uint8)
    start = -raw.ctypes.data % 64
    out = raw[start : start + a.nbytes].view(dtype).reshape(a.shape)
    out[...] = a
    return out


class LeanModel:
    """What the lean samplers share: the trained normalisers and the model's layers as arrays
    for ``kernels.network``, for real-time steps without autograd or dispatch; ``weights``: the
    linear layers as (W^T, b) float32, as the ONNX export reads them.

    The state normalisers are folded into the first layer once (``fold_features``), so a
    step reads [x_t, x_{t+1} - x_t] through one product; the difference is taken in float64,
    because x_{t+1} and x_t agree in their leading digits."""

    def __init__(self, model: InverseModel, net: nn.Sequential):
        self.buffers = {name: b.detach().numpy() for name, b in model.named_buffers()}
        self.weights = [
            (np.ascontiguousarray(m.weight.detach().numpy().T), m.bias.detach().numpy())
            for m in net
            if isinstance(m, nn.Linear)
        ]
        self.prior, self.inputs = model.prior, model.dims.inputs
        H = self.weights[0][0].shape[1]
        self.hidden = aligned(np.reshape([w for w, _ in self.weights[1:-1]], (-1, H, H)))  # (L, H, H)
        self.hidden_bias = aligned(np.reshape([b for _, b in self.weights[1:-1]], (-1, H)))  # (L, H)
        self.out_weight, self.out_bias = aligned(self.weights[-1][0].T), self.weights[-1][1]  # (m, H), (m,)
        target = "residual_norm" if self.prior else "action_norm"
        self.u_std, self.u_mean = (self.buffers[f"{target}.{k}"] for k in ("std", "mean"))

    def fold_features(self, w, b):
        """(W, c), float64, such that [x_t, x_{t+1} - x_t] @ W[:2d] (+ u_phys @ W[2d:]) + c equals the
        normalised features (and prior) times ``w`` (2d or 2d+m, H) plus ``b``."""
        norms = ["state_norm", "delta_norm"] + (["prior_norm"] if self.prior else [])
        mean, std = (np.concatenate([self.buffers[f"{n}.{k}"] for n in norms]).astype(float) for k in ("mean", "std"))
        w = w.astype(np.float64) / std[:, None]
        return aligned(w, np.float64), b.astype(np.float64) - mean @ w

    def run(self, window, prior, first, time_weights, xi_weight, xi) -> np.ndarray:
        """u (B, m) float64 through ``kernels.network`` for state windows (B, 2, d), the prior (B, m)
        or None, the folded first layer ``first`` = (W, c), and the Euler steps' time weights
        (n, H), xi weights (m, H) and starting xi (B, m) float32 (updated in place)."""
        window = np.ascontiguousarray(window, dtype=np.float64)
        prior = np.empty((len(window), 0)) if prior is None else np.ascontiguousarray(prior, dtype=np.float64)
        layers = (self.hidden, self.hidden_bias, self.out_weight, self.out_bias, self.u_std, self.u_mean)
        return network(window, prior, *first, time_weights, xi_weight, *layers, xi)
