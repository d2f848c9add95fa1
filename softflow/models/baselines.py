"""Deterministic inverse models of the paper: MLP on (x_t, x_{t+1}); LSTM and Transformer
over the last K transitions. All regress u_t with a mean-squared error in normalised units."""
from __future__ import annotations

import torch
from torch import nn

from .common import InverseModel, LeanModel, mlp


class _Regression(InverseModel):
    def compute_loss(self, window, u, **extras):
        return torch.mean((self.forward(window) - self.action_norm.normalize(u)) ** 2)

    def predict(self, window, **kwargs):
        return self.action_norm.unnormalize(self.forward(window))


class InverseMLP(_Regression):
    """u_t = MLP(x_t, x_{t+1})."""

    def __init__(self, hidden: int = 256, layers: int = 3):
        super().__init__()
        self.net = mlp([12] + [hidden] * layers + [2])

    def forward(self, window):
        return self.net(self.features(window[:, -2:])[:, 0])


class LeanMLP(LeanModel):
    """``InverseMLP.predict`` in plain numpy float32, for the real-time step (same u to ~1e-6 N)."""

    def __init__(self, model: InverseMLP):
        super().__init__(model, model.net)

    def predict(self, window):
        """u (B, 2) for state windows (B, 2, 6) [x_t, x_{t+1}]."""
        h = self.features(window)
        for k, (w, b) in enumerate(self.weights):
            h = (self.silu(h) if k else h) @ w + b
        return h * self.buffers["action_norm.std"] + self.buffers["action_norm.mean"]


class InverseLSTM(_Regression):
    """u_t from an LSTM run over the last ``context`` transitions of the reference."""

    def __init__(self, context: int = 10, hidden: int = 128, layers: int = 2):
        super().__init__()
        self.context = context
        self.lstm = nn.LSTM(12, hidden, num_layers=layers, batch_first=True)
        self.head = nn.Linear(hidden, 2)

    def forward(self, window):
        out, _ = self.lstm(self.features(window))
        return self.head(out[:, -1])


class InverseTransformer(_Regression):
    """u_t from a Transformer encoder over the last ``context`` transitions (last token read out)."""

    def __init__(self, context: int = 10, d_model: int = 64, heads: int = 4, layers: int = 2):
        super().__init__()
        self.context = context
        self.embed = nn.Linear(12, d_model)
        self.position = nn.Parameter(torch.zeros(context, d_model))
        layer = nn.TransformerEncoderLayer(d_model, heads, 4 * d_model, dropout=0.0, batch_first=True)
        self.encoder = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.head = nn.Linear(d_model, 2)

    def forward(self, window):
        tokens = self.embed(self.features(window)) + self.position
        return self.head(self.encoder(tokens)[:, -1])
