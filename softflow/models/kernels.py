"""The real-time step in compiled calls (numba): a lean sampler's layers in one call, without a
dispatch per operation (``network``), and the step's range checks (``inside``).

At batch 1 a numpy step is bound by its calls, not its arithmetic: about 15 array operations of
about 1 us each per Euler step, so a 4-step flow took about 0.08 ms. Here every layer of every Euler
step runs in one loop nest, and a step is bound by reading the weights (two 256 x 256 float32
matrices a step, from the L2 cache).

The loops fix every sum's order and run each output's sum in that order whatever the vector
width, and multiply-adds may fuse (``fastmath={"contract"}``, nothing else): a step gives the
same bits on every CPU with fused multiply-add (every x86-64 of the last decade and every arm64), so
that a CPU with wider vectors does not print another last digit. Compiled once per machine and
cached beside this file (numba's ``cache=True``)."""

from __future__ import annotations

import numpy as np
from numba import njit

LANES = 16  # partial sums of the output layer: enough independent chains for any vector width


@njit(cache=True, fastmath={"contract"})
def network(
    window,
    prior,
    first_weight,
    first_bias,
    time_weights,
    xi_weight,
    hidden,
    hidden_bias,
    out_weight,
    out_bias,
    u_std,
    u_mean,
    xi,
):
    """u (B, m) float64 of a lean model for state windows (B, 2, d) float64 [x_t, x_{t+1}] and
    its prior (B, k) float64 (k = m for a prior model, else 0). The layers: the first, folded
    over the features [x_t, x_{t+1} - x_t, prior] (``first_weight`` (F, H), ``first_bias`` (H,),
    float64); then, for each of the n rows of ``time_weights`` (n, H), one Euler step of the
    network from the normalised actuation ``xi`` (B, m) float32 (updated in place): the time's
    share of the first layer, xi @ ``xi_weight`` (m, H), the hidden layers (L, H, H) with a
    SiLU before each, the output layer (m, H) and xi += output / n. A regression model is
    one step with zero time and xi weights from xi = 0. The result is xi * u_std + u_mean,
    plus the prior (its residual's)."""
    B, d = window.shape[0], window.shape[2]
    F, H = first_weight.shape
    n, L, m, k = time_weights.shape[0], hidden.shape[0], out_weight.shape[0], prior.shape[1]
    features = np.empty(F)  # (F,) float64: x_{t+1} - x_t keeps the digits its two states share
    first = np.empty(H)  # (H,) float64
    start, h, g = np.empty(H, np.float32), np.empty(H, np.float32), np.empty(H, np.float32)
    partial, scale_bits = np.empty(LANES, np.float32), np.empty(H, np.int32)
    u = np.empty((B, m))
    whole = H - H % LANES
    for b in range(B):
        for i in range(d):
            features[i] = window[b, 0, i]
            features[d + i] = window[b, 1, i] - window[b, 0, i]
        for i in range(k):
            features[2 * d + i] = prior[b, i]
        first[:] = first_bias
        for f in range(F):
            for j in range(H):
                first[j] += features[f] * first_weight[f, j]
        for j in range(H):
            start[j] = np.float32(first[j])
        for step in range(n):
            for j in range(H):
                h[j] = start[j] + time_weights[step, j]
            for i in range(m):
                for j in range(H):
                    h[j] += xi[b, i] * xi_weight[i, j]
            for layer in range(L):
                _silu(h, g, scale_bits)
                w = hidden[layer]
                h[:] = hidden_bias[layer]
                for i in range(0, H - H % 8, 8):  # eight rows a pass: an eighth of the loads and stores of h
                    a0, a1, a2, a3, a4, a5, a6, a7 = g[i : i + 8]
                    for j in range(H):  # summed left to right: the order of one row a pass
                        h[j] = (
                            h[j]
                            + a0 * w[i, j]
                            + a1 * w[i + 1, j]
                            + a2 * w[i + 2, j]
                            + a3 * w[i + 3, j]
                            + a4 * w[i + 4, j]
                            + a5 * w[i + 5, j]
                            + a6 * w[i + 6, j]
                            + a7 * w[i + 7, j]
                        )
                for i in range(H - H % 8, H):
                    for j in range(H):
                        h[j] += g[i] * w[i, j]
            _silu(h, g, scale_bits)
            for o in range(m):
                partial[:] = 0
                for i in range(0, whole, LANES):
                    for lane in range(LANES):
                        partial[lane] += g[i + lane] * out_weight[o, i + lane]
                for i in range(whole, H):
                    partial[0] += g[i] * out_weight[o, i]
                total = out_bias[o]
                for lane in range(LANES):
                    total += partial[lane]
                xi[b, o] += total / np.float32(n)
        for o in range(m):
            u[b, o] = np.float64(xi[b, o] * u_std[o] + u_mean[o]) + (prior[b, o] if k else 0.0)
    return u


@njit(cache=True)
def inside(values, low, high) -> bool:
    """Whether every row of ``values`` (N, k) lies in the box [low, high] ((k,) each): finite
    bounds make it a finiteness check too (NaN compares False). One compiled call in place of
    a few array operations, which after the network's weights have passed through the caches
    cost a step several microseconds."""
    for n in range(values.shape[0]):
        for i in range(values.shape[1]):
            if not low[i] <= values[n, i] <= high[i]:
                return False
    return True


@njit(cache=True, fastmath={"contract"})
def _silu(h, out, scale_bits):
    """out = h sigmoid(h) = h / (1 + exp(-h)), (H,) float32, with exp in lines that vectorise
    (libm's exp is one call per value, 2.5x the time): exp(x) = 2^k exp(r), k = round(x / ln 2),
    r = x - k ln 2 in two parts (Cody and Waite), exp(r) by Cephes' ``expf`` polynomial and 2^k
    written into a float's exponent bits (``scale_bits`` (H,) int32 scratch). Within 3e-7 of the
    exact value relatively (tests/test_kernels.py); x is clamped to +-87, where exp leaves
    float32, so far below zero the result is near 0 (under 1e-7 even at h = -1e30), not 0."""
    scale = scale_bits.view(np.float32)
    for j in range(h.shape[0]):
        x = min(max(-h[j], np.float32(-87.0)), np.float32(87.0))
        k = np.floor(x * np.float32(1.44269504088896341) + np.float32(0.5))
        r = x - k * np.float32(0.693359375) - k * np.float32(-2.12194440e-4)
        p = np.float32(1.9875691500e-4)
        p = p * r + np.float32(1.3981999507e-3)
        p = p * r + np.float32(8.3334519073e-3)
        p = p * r + np.float32(4.1665795894e-2)
        p = p * r + np.float32(1.6666665459e-1)
        p = p * r + np.float32(5.0000001201e-1)
        out[j] = p * (r * r) + r + np.float32(1.0)  # exp(r)
        scale_bits[j] = (np.int32(k) + np.int32(127)) << np.int32(23)  # 2^k
    for j in range(h.shape[0]):
        out[j] = h[j] / (np.float32(1.0) + out[j] * scale[j])
