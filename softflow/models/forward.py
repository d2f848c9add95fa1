"""Forward-dynamics surrogate f_phi(x_t, u_t) -> x_{t+1} of RF-FWD (paper: 2 layers, 128 ReLU)."""

from __future__ import annotations

import torch
from torch import nn

from .common import InverseModel, mlp


class ForwardModel(InverseModel):
    """Predicts the normalised state increment; trained through the same loop as the
    inverse models (its ``compute_loss`` takes the same (window, u) batches)."""

    def __init__(self, hidden: int = 128):
        super().__init__()
        self.net = mlp([6 + 2, hidden, hidden, 6], activation=nn.ReLU)

    def increment(self, x, u):
        """Normalised x_{t+1} - x_t for x (B, 6), u (B, 2) in SI units."""
        return self.net(torch.cat([self.state_norm.normalize(x), self.action_norm.normalize(u)], -1))

    def compute_loss(self, window, u, **extras):
        x, x_next = window[:, -2], window[:, -1]
        return torch.mean((self.increment(x, u) - self.delta_norm.normalize(x_next - x)) ** 2)

    def predict_next(self, x, u):
        return x + self.delta_norm.unnormalize(self.increment(x, u))
