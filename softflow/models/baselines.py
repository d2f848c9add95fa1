"""Deterministic inverse models of the paper: MLP on (x_t, x_{t+1}); LSTM and Transformer
over the last K transitions. All regress u_t with a mean-squared error in normalised units.
MLP-Physical (not in the paper) regresses the residual around RF-Physical's static prior:
the prior without the generative model, to tell their benefits apart."""

from __future__ import annotations

import torch
from torch import nn

from .common import PAPER_DIMS, Dims, InverseModel, mlp


class _Regression(InverseModel):
    def compute_loss(self, window, u, prior=None):
        target = u - prior if self.prior else u
        return torch.mean((self.forward(window, prior) - self.target_norm().normalize(target)) ** 2)

    def predict(self, window, prior=None):
        return self.actuation(self.forward(window, prior), prior)


class InverseMLP(_Regression):
    """u_t = MLP(x_t, x_{t+1})."""

    def __init__(self, hidden: int = 256, layers: int = 3, *, dims: Dims = PAPER_DIMS):
        super().__init__(dims)
        m = dims.inputs
        self.net = mlp([2 * dims.state + (m if self.prior else 0)] + [hidden] * layers + [m])

    def forward(self, window, prior=None):
        return self.net(self.condition(window, prior))

    def act(self, condition, prior=None):
        """``predict`` from the condition (B, c) it computes from the states."""
        return self.actuation(self.net(condition), prior)


class PhysicalMLP(InverseMLP):
    """u_t = u_phys(p_t+1) + MLP(x_t, x_{t+1}, u_phys): MLP-Physical."""

    prior = True

    def __init__(self, hidden: int = 256, layers: int = 3, *, dims: Dims = PAPER_DIMS):
        super().__init__(hidden, layers, dims=dims)
        self._add_prior()


class InverseLSTM(_Regression):
    """u_t from an LSTM run over the last ``context`` transitions of the reference."""

    def __init__(self, context: int = 10, hidden: int = 128, layers: int = 2, *, dims: Dims = PAPER_DIMS):
        super().__init__(dims)
        self.context = context
        self.lstm = nn.LSTM(2 * dims.state, hidden, num_layers=layers, batch_first=True)
        self.head = nn.Linear(hidden, dims.inputs)

    def forward(self, window, prior=None):
        out, _ = self.lstm(self.features(window))
        return self.head(out[:, -1])


class InverseTransformer(_Regression):
    """u_t from a Transformer encoder over the last ``context`` transitions (last token read out)."""

    def __init__(
        self, context: int = 10, d_model: int = 64, heads: int = 4, layers: int = 2, *, dims: Dims = PAPER_DIMS
    ):
        super().__init__(dims)
        self.context = context
        self.embed = nn.Linear(2 * dims.state, d_model)
        self.position = nn.Parameter(torch.zeros(context, d_model))
        layer = nn.TransformerEncoderLayer(d_model, heads, 4 * d_model, dropout=0.0, batch_first=True)
        self.encoder = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.head = nn.Linear(d_model, dims.inputs)

    def forward(self, window, prior=None):
        tokens = self.embed(self.features(window)) + self.position
        return self.head(self.encoder(tokens)[:, -1])
