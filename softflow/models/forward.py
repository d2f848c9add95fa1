"""Forward-dynamics surrogate f_phi(x_t, u_t) -> x_{t+1} of RF-FWD (paper: 2 layers, 128 ReLU)."""

from __future__ import annotations

import torch
from torch import nn

from .common import PAPER_DIMS, Dims, InverseModel, mlp


class ForwardModel(InverseModel):
    """Predicts the normalised state increment; trained through the same loop as the
    inverse models (its ``compute_loss`` takes the same (window, u) batches)."""

    def __init__(self, hidden: int = 128, *, dims: Dims = PAPER_DIMS):
        super().__init__(dims)
        self.net = mlp([dims.state + dims.inputs, hidden, hidden, dims.state], activation=nn.ReLU)

    def increment(self, x, u):
        """Normalised x_{t+1} - x_t for x (B, d), u (B, m) in SI units."""
        return self.net(torch.cat([self.state_norm.normalize(x), self.action_norm.normalize(u)], -1))

    def residual(self, window, u):
        """f_phi(x_t, u) - (x_{t+1} - x_t), normalised, (B, d): the surrogate's error at the true u,
        and what RF-FWD's consistency term penalises at its estimate of u."""
        x, x_next = window[:, -2], window[:, -1]
        return self.increment(x, u) - self.delta_norm.normalize(x_next - x)

    def compute_loss(self, window, u, **extras):
        return torch.mean(self.residual(window, u) ** 2)

    def predict_next(self, x, u):
        return x + self.delta_norm.unnormalize(self.increment(x, u))
