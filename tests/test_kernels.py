"""The compiled step (models/kernels.py) and the grid's compiled interpolation: held to the torch
models they stand for, to closed forms, and to the same bits on another CPU's vector width."""

import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from softflow.models.baselines import InverseMLP, LeanMLP
from softflow.models.common import Dims
from softflow.models.flow import LeanFlow, MeanFlow, RectifiedFlow
from softflow.models.kernels import _silu, inside
from softflow.rod.statics import _trilinear

DIMS = Dims(inputs=3, position=2)  # not the paper's sizes: nothing may assume them
REPO = Path(__file__).resolve().parents[1]


def fitted(model, seed=0):
    """``model`` with normalisers fitted on random episodes (so that the folding is exercised)."""
    g = torch.Generator().manual_seed(seed)
    states = 0.3 * torch.randn(4, 21, DIMS.state, generator=g) + 0.5  # (E, T+1, d)
    u = 2 * torch.randn(4, 20, DIMS.inputs, generator=g) - 1  # (E, T, m)
    prior = torch.randn(4, 20, DIMS.inputs, generator=g) if model.prior else None
    model.set_normalizer(states, u, prior)
    return model.eval()


@pytest.mark.parametrize(
    "model, lean",
    [
        # hidden sizes that are not multiples of the kernel's 4 rows a pass or 16 output lanes
        (lambda: InverseMLP(hidden=37, layers=3, dims=DIMS), LeanMLP),
        (lambda: RectifiedFlow(hidden=42, layers=2, steps=3, prior=True, dims=DIMS), LeanFlow),
        (lambda: MeanFlow(hidden=64, layers=3, steps=1, dims=DIMS), LeanFlow),
        (lambda: RectifiedFlow(hidden=16, layers=1, steps=2, dims=DIMS), LeanFlow),  # no hidden-to-hidden layer
    ],
)
def test_the_compiled_step_gives_the_torch_models_u(model, lean):
    torch.manual_seed(1)
    model = fitted(model())
    rng = np.random.default_rng(2)
    window = rng.normal(0.5, 0.3, (50, 2, DIMS.state))  # (B, 2, d)
    prior = rng.standard_normal((50, DIMS.inputs)) if model.prior else None
    noise = rng.standard_normal((50, DIMS.inputs))
    as_tensor = lambda a: None if a is None else torch.as_tensor(a, dtype=torch.float32)  # noqa: E731
    with torch.no_grad():
        if isinstance(model, RectifiedFlow):
            expected = model.predict(as_tensor(window), prior=as_tensor(prior), noise=as_tensor(noise))
            got = lean(model).predict(window, noise, prior)
        else:
            expected = model.predict(as_tensor(window), prior=as_tensor(prior))
            got = lean(model).predict(window, prior)
    assert got.dtype == np.float64 and got.shape == (50, DIMS.inputs)
    np.testing.assert_allclose(got, expected.double().numpy(), rtol=0, atol=2e-5)  # float32 rounding, unit-size u


def test_silu_is_within_float32_of_the_exact_value():
    h = np.concatenate([np.linspace(-100, 100, 400_001), [-1e30, 1e30, 0.0, -0.0]]).astype(np.float32)
    out, scratch = np.empty_like(h), np.empty(len(h), np.int32)
    _silu(h, out, scratch)
    exact = h / (1 + np.exp(-np.maximum(h.astype(np.float64), -700)))  # float64, no overflow
    assert np.isfinite(out).all()
    usual = np.abs(h) <= 80  # where the hidden layers' values lie, with room
    relative = np.abs(out - exact)[usual] / np.maximum(np.abs(exact[usual]), 1e-300)
    assert relative[np.abs(exact[usual]) > 1e-30].max() < 3e-7  # libm's expf: 1.5e-7 here
    assert np.abs(out - exact).max() < 1e-5  # and nowhere off by more than a float32 step of a unit value
    assert abs(out[-4]) < 1e-7 and out[-3] == h[-3] and out[-2] == 0  # far below zero ~0, far above h


def test_inside_refuses_a_value_outside_the_box_or_not_finite():
    low, high = np.array([-1.0, -np.finfo(float).max]), np.array([1.0, np.finfo(float).max])
    assert inside(np.array([[1.0, -5.0], [-1.0, 1e300]]), low, high)  # on the bound is inside
    for bad in ([1.0 + 1e-12, 0.0], [np.nan, 0.0], [0.0, np.inf], [0.0, np.nan]):
        assert not inside(np.array([[0.0, 0.0], bad]), low, high), bad


def test_the_grid_interpolation_is_exact_for_a_linear_field():
    """Trilinear interpolation reproduces a field linear in the grid's coordinates; off the grid
    and in a kink cell the point goes to the table (u left 0)."""
    low, spacing, shape = np.array([-3.0, -3.0, 0.2]), np.array([0.5, 0.75, 0.05]), np.array([13, 9, 5])
    strides, cell_strides = np.array([9 * 5, 5, 1]), np.array([8 * 4, 4, 1])
    corners = np.array(list(np.ndindex(2, 2, 2))) @ strides
    axes = [low[a] + spacing[a] * np.arange(shape[a]) for a in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    A, c = np.array([[0.3, -1.2, 4.0], [2.0, 0.5, -7.0]]), np.array([0.1, -0.2])
    u = nodes @ A.T + c  # (N, 2)
    kink = np.zeros(12 * 8 * 4, bool)
    arc_scale = 40.0
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(0.2, 0.35, 200), rng.uniform(-0.03, 0.03, (200, 2))])  # (200, 3) tips
    lateral = np.hypot(p[:, 1], p[:, 2])
    scale = arc_scale * np.arctan2(lateral, p[:, 0]) / lateral
    coordinates = np.column_stack([scale[:, None] * p[:, 1:], np.hypot(p[:, 0], lateral)])  # InverseGrid.coordinates
    inside = ((coordinates >= low) & (coordinates <= low + spacing * (shape - 1))).all(-1)
    assert 50 < inside.sum() < 200  # points on and off the grid
    got, exact = _trilinear(p, low, spacing, shape, strides, cell_strides, corners, kink, u, arc_scale)
    np.testing.assert_array_equal(exact, ~inside)
    np.testing.assert_allclose(got[inside], coordinates[inside] @ A.T + c, rtol=0, atol=1e-12)
    assert (got[~inside] == 0).all()
    cell = np.minimum(((coordinates[inside][0] - low) / spacing).astype(int), shape - 2)
    kink[cell @ cell_strides] = True
    _, exact = _trilinear(p[inside][:1], low, spacing, shape, strides, cell_strides, corners, kink, u, arc_scale)
    assert exact[0]


STEP = """
import sys
import numpy as np, torch
from softflow.models.common import Dims
from softflow.models.flow import LeanFlow, RectifiedFlow
torch.manual_seed(0)
model = RectifiedFlow(hidden=256, layers=3, steps=4, dims=Dims())
rng = np.random.default_rng(0)
np.save(sys.argv[1], LeanFlow(model).predict(rng.standard_normal((64, 2, 6)), rng.standard_normal((64, 2))))
"""


def has_avx2() -> bool:
    cpuinfo = Path("/proc/cpuinfo")
    return platform.machine() == "x86_64" and cpuinfo.exists() and " avx2 " in cpuinfo.read_text()


@pytest.mark.skipif(not has_avx2(), reason="needs an x86-64 with AVX2 (and Linux's /proc/cpuinfo)")
def test_the_step_gives_the_same_bits_with_another_vector_width(tmp_path):
    """numba compiles for the CPU it runs on: the step compiled for AVX2 (256-bit vectors, as on an
    AMD EPYC without AVX-512) gives the host's bits (AVX-512 here), as the fixed sums promise."""
    runs = {}
    for name, cpu in (("host", {}), ("avx2", {"NUMBA_CPU_NAME": "haswell", "NUMBA_CACHE_DIR": str(tmp_path)})):
        runs[name] = tmp_path / f"{name}.npy"
        env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")} | cpu
        subprocess.run([sys.executable, "-c", STEP, str(runs[name])], env=env, check=True, cwd=REPO)
    np.testing.assert_array_equal(np.load(runs["avx2"]), np.load(runs["host"]))
