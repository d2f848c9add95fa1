"""Conditional rectified flow for inverse dynamics (paper Sec. III): RF, RF-Physical, RF-FWD.

A velocity field v_theta(xi_tau, tau, c) transports noise z ~ N(0, I) to the normalised
actuation along the straight path xi_tau = (1 - tau) z + tau xi, trained with
||v - (xi - z)||^2 and integrated with N Euler steps at inference.
  RF:          xi = u,             c = (x_t, x_{t+1})
  RF-Physical: xi = u - u_phys,    c = (x_t, x_{t+1}, u_phys), u_phys = inverse statics of p_{t+1}
  RF-FWD:      RF + lambda ||f_phi(x_t, u_hat) - x_{t+1}||^2 with a frozen forward surrogate f_phi.
A one-step flow (``MeanFlow``: RF-1, RF-FWD-1) learns the average velocity over a span of the
path instead, and crosses it in one network call.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from .common import PAPER_DIMS, Dims, InverseModel, mlp
from .forward import ForwardModel


class RectifiedFlow(InverseModel):
    """The velocity field and its sampler. ``prior``: learn the residual around the static
    prior u_phys of the training rod (RF-Physical). ``consistency``: lambda_cons of RF-FWD
    (0 for RF); its frozen forward surrogate is trained first and given to ``attach``."""

    times = 1  # time inputs of the network: tau

    def __init__(
        self,
        hidden: int = 256,
        layers: int = 3,
        steps: int = 4,
        tau_sampling: str = "logit-normal",
        prior: bool = False,
        consistency: float = 0.0,
        *,
        dims: Dims = PAPER_DIMS,
    ):
        super().__init__(dims)
        if tau_sampling not in ("uniform", "logit-normal"):
            raise ValueError(f"tau_sampling must be 'uniform' or 'logit-normal'; got {tau_sampling!r}")
        if not isinstance(prior, bool):
            raise ValueError(f"prior must be True or False; got {prior!r}")
        if not (isinstance(steps, int) and steps >= 1):
            raise ValueError(f"steps must be a positive integer; got {steps!r}")
        self.steps, self.tau_sampling, self.consistency = steps, tau_sampling, consistency
        m = dims.inputs
        self.net = mlp([m + self.times + 2 * dims.state + (m if prior else 0)] + [hidden] * layers + [m])
        if prior:
            self._add_prior()
        if consistency:
            self.forward_model = ForwardModel(dims=dims).requires_grad_(False)

    # -- data-side hooks used by the training loop and the controller
    def attach(self, forward: ForwardModel | None = None):
        """RF-FWD: take the trained forward surrogate's weights; they stay frozen."""
        if self.consistency and forward is None:
            raise ValueError("RF-FWD (consistency > 0) needs a trained forward surrogate: attach(forward=...)")
        if forward is not None:
            self.forward_model.load_state_dict(forward.state_dict())

    # -- the flow
    def velocity(self, xi, tau, condition):
        return self.net(torch.cat([xi, tau[:, None], condition], -1))

    def mean_velocity(self, xi, tau, span, condition):
        """What a step of length ``span`` (B,) from xi at tau moves along: here the velocity at
        its start (Euler); ``MeanFlow`` learns the average over the span."""
        return self.velocity(xi, tau, condition)

    def endpoint(self, xi_tau, tau, condition):
        """The one-step estimate of where the flow ends from xi_tau at tau,
        xi_tau + (1 - tau) v (normalised, (B, m)): what RF-FWD's consistency term judges."""
        return xi_tau + (1 - tau[:, None]) * self.mean_velocity(xi_tau, tau, 1 - tau, condition)

    def integrate(self, xi, condition, steps: int, start: float = 0.0):
        """The flow from xi at tau = ``start`` to tau = 1 in ``steps`` equal steps (normalised,
        (B, m)); ``act`` starts it from noise at 0. The network is linear in its inputs up to its
        first activation, so the condition's share of the first layer is computed once, not at
        every step, and the time's share is a constant of each step; the Euler update xi + length v
        is one product with the output layer."""
        first, hidden, last = self.net[0], self.net[1:-1], self.net[-1]
        m, n, length = self.dims.inputs, self.times, (1.0 - start) / steps
        w_xi, w_time, w_condition = first.weight[:, :m], first.weight[:, m : m + n], first.weight[:, m + n :]
        shared = F.linear(condition, w_condition, first.bias)  # (B, H)
        for k in range(steps):
            time = w_time @ torch.tensor(self.time_inputs(start + length * k, length))  # (H,)
            h = hidden(torch.addmm(time, xi, w_xi.T) + shared)  # (B, H)
            xi = torch.addmm(xi + length * last.bias, h, last.weight.T, alpha=length)  # xi + length v
        return xi

    def time_inputs(self, tau: float, span: float) -> list[float]:
        """The network's time inputs for a step of length ``span`` from ``tau``: tau (Euler's step
        moves along the velocity at its start)."""
        return [tau]

    def _sample_tau(self, n, device):
        if self.tau_sampling == "uniform":
            return torch.rand(n, device=device)
        return torch.sigmoid(torch.randn(n, device=device))  # logit-normal(0, 1): more weight mid-path

    def compute_loss(self, window, u, prior=None):
        condition = self.condition(window, prior)
        xi = self.target_norm().normalize(u - prior if self.prior else u)
        z = torch.randn_like(xi)
        tau = self._sample_tau(len(xi), xi.device)
        xi_tau = (1 - tau[:, None]) * z + tau[:, None] * xi
        v = self.velocity(xi_tau, tau, condition)
        loss = torch.mean((v - (xi - z)) ** 2)
        if self.consistency:  # the one-step estimate of the endpoint (``endpoint``, with the v already computed)
            loss = loss + self._consistency(window, xi_tau + (1 - tau[:, None]) * v, prior)
        return loss

    def _consistency(self, window, xi_hat, prior):
        """RF-FWD's term: lambda ||f_phi(x_t, u_hat) - x_{t+1}||^2 (normalised) at the estimate xi_hat."""
        u_hat = self.actuation(xi_hat, prior)
        return self.consistency * torch.mean(self.forward_model.residual(window, u_hat) ** 2)

    def predict(self, window, prior=None, noise=None, steps: int | None = None):
        """u (B, m): Euler integration of the flow from ``noise`` (default: fresh N(0, I))."""
        return self.act(self.condition(window, prior), prior, noise, steps)

    def act(self, condition, prior=None, noise=None, steps: int | None = None):
        """``predict`` from the condition (B, c) it computes from the states."""
        xi = torch.randn(len(condition), self.dims.inputs, device=condition.device) if noise is None else noise
        return self.actuation(self.integrate(xi, condition, self.steps if steps is None else steps), prior)


class MeanFlow(RectifiedFlow):
    """A flow in one step (MeanFlow: Geng et al. 2025, arXiv:2505.13447): the network learns the
    average velocity u(xi_s, s, h) = (1/h) int_s^{s+h} v dtau over a span h of the path, so a
    step of any length lands where the flow would, xi_{s+h} = xi_s + h u. Trained through the
    identity u = v + h du/ds (the derivative along the path at fixed end s + h: one
    Jacobian-vector product), with h = 0, plain flow matching, on the rest of the pairs.
    ``steps`` = 1 (the registry's rf-1 and rf-fwd-1) samples xi = z + u(z, 0, 1), the transport in
    one call; the sources and every choice are in docs/assumptions.md ("One-step flows")."""

    times = 2  # tau and the span h
    SPANNED = 0.25  # share of training pairs with a span h > 0 (the reference's default)

    def velocity(self, xi, tau, condition):
        return self.mean_velocity(xi, tau, torch.zeros_like(tau), condition)

    def mean_velocity(self, xi, tau, span, condition):
        return self.net(torch.cat([xi, tau[:, None], span[:, None], condition], -1))

    def time_inputs(self, tau: float, span: float) -> list[float]:
        """tau and the span the step crosses."""
        return [tau, span]

    def compute_loss(self, window, u, prior=None):
        condition = self.condition(window, prior)
        xi = self.target_norm().normalize(u - prior if self.prior else u)
        z = torch.randn_like(xi)
        a, b = self._sample_tau(len(xi), xi.device), self._sample_tau(len(xi), xi.device)
        start, end = torch.minimum(a, b), torch.maximum(a, b)
        end = torch.where(torch.rand(len(xi), device=xi.device) < self.SPANNED, end, start)
        xi_s = (1 - start[:, None]) * z + start[:, None] * xi
        v = xi - z  # the conditional velocity, constant along the straight path
        average, along = torch.func.jvp(
            lambda x, s: self.mean_velocity(x, s, end - s, condition), (xi_s, start), (v, torch.ones_like(start))
        )
        target = (v + (end - start)[:, None] * along).detach()
        loss = torch.mean((average - target) ** 2)
        if self.consistency:  # judged at the one-step estimate from the same point
            loss = loss + self._consistency(window, self.endpoint(xi_s, start, condition), prior)
        return loss
