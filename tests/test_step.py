"""The step, defined once (softflow/control/step.py): the module gives the model's own u, its
graph in onnxruntime gives the module's, its grid prior interpolates exactly what is linear in the
grid's coordinates and flags what it cannot answer, and a refused transition sends the safe input,
never a clipped command."""

from types import SimpleNamespace

import numpy as np
import onnxruntime as ort
import pytest
import torch

from softflow.control.step import GridPrior, Step, graph
from softflow.models.baselines import InverseMLP
from softflow.models.common import Dims
from softflow.models.flow import MeanFlow, RectifiedFlow

DIMS = Dims(inputs=3, position=2)  # not the paper's sizes: nothing may assume them
PRIOR_DIMS = Dims(inputs=2, position=3)  # a prior is a rod's: its tip is 3-D and it has 2 inputs
TOLERANCE = 1e-5  # N: the graph and torch compute in float32 from the same weights, in other orders


def fitted(model, seed=0):
    """``model`` with normalisers fitted on random episodes."""
    g, dims = torch.Generator().manual_seed(seed), model.dims
    states = 0.3 * torch.randn(4, 21, dims.state, generator=g) + 0.5  # (E, T+1, d)
    u = 2 * torch.randn(4, 20, dims.inputs, generator=g) - 1  # (E, T, m)
    prior = torch.randn(4, 20, dims.inputs, generator=g) if model.prior else None
    model.set_normalizer(states, u, prior)
    return model.eval()


def linear_grid(A, c, kink_at=()):
    """An ``InverseGrid``'s arrays whose prior is linear in the grid coordinates, A @ s + c: over
    [-3, 3] x [-3, 3] (arc actuation, N) x [0.2, 0.4] (chord, m), cells ``kink_at`` marked."""
    low, spacing, shape = np.array([-3.0, -3.0, 0.2]), np.array([0.5, 0.75, 0.05]), np.array([13, 9, 5])
    strides, cell_strides = np.array([9 * 5, 5, 1]), np.array([8 * 4, 4, 1])
    axes = [low[a] + spacing[a] * np.arange(shape[a]) for a in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)  # (N, 3)
    kink = np.zeros(12 * 8 * 4, bool)
    kink[list(kink_at)] = True
    corners = np.array(list(np.ndindex(2, 2, 2))) @ strides
    return SimpleNamespace(
        low=low, spacing=spacing, shape=shape, strides=strides, cell_strides=cell_strides, corners=corners,
        u=nodes @ A.T + c, kink=kink, arc_scale=40.0,
    )  # fmt: skip


def tips(n, seed=0):
    """(n, 3) tip points about a rod of 0.3 m along +x, some beyond the linear grid's range."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.2, 0.35, n), rng.uniform(-0.03, 0.03, (n, 2))]).astype(np.float32)


def coordinates(p, arc_scale=40.0):
    """The grid coordinates of tips p (B, 3), in numpy float64: arc actuation (2) and chord."""
    p = p.astype(np.float64)
    lateral = np.hypot(p[:, 1], p[:, 2])
    scale = arc_scale * np.arctan2(lateral, p[:, 0]) / lateral
    return np.column_stack([scale[:, None] * p[:, 1:], np.hypot(p[:, 0], lateral)])


MODELS = {
    # hidden sizes of no particular alignment; one flow with no hidden-to-hidden layer
    "mlp": lambda: InverseMLP(hidden=37, layers=3, dims=DIMS),
    "rf-physical": lambda: RectifiedFlow(hidden=42, layers=2, steps=3, prior=True, dims=PRIOR_DIMS),
    "one-step": lambda: MeanFlow(hidden=64, layers=3, steps=1, dims=DIMS),
    "rf": lambda: RectifiedFlow(hidden=16, layers=1, steps=2, dims=DIMS),
}
GRID = linear_grid(np.array([[0.3, -1.2, 4.0], [2.0, 0.5, -7.0]]), np.array([0.1, -0.2]))


def step_of(model, margin=np.inf, safe=None):
    """The step of ``model``: inputs clipped to [-1, 1.5], a workspace box of +-``margin`` about 0.5."""
    d, m = model.dims.state, model.dims.inputs
    return Step(
        model,
        low=np.full(m, -1.0),
        high=np.full(m, 1.5),
        safe=np.full(m, 0.25) if safe is None else safe,
        box_low=np.full(d, max(0.5 - margin, -3e38)),
        box_high=np.full(d, min(0.5 + margin, 3e38)),
        grid=GRID if model.prior else None,
    )


def transitions(model, n=200, seed=2):
    rng = np.random.default_rng(seed)
    d = model.dims.state
    if model.prior:  # states whose tips lie on the grid
        x_t = np.concatenate([tips(n, seed), rng.normal(0, 0.1, (n, 3))], 1)
        x_next = x_t + rng.normal(0, 1e-3, (n, d))
    else:
        x_t, x_next = rng.normal(0.5, 0.3, (n, d)), rng.normal(0.5, 0.3, (n, d))
    return torch.as_tensor(x_t, dtype=torch.float32), torch.as_tensor(x_next, dtype=torch.float32)


@pytest.mark.parametrize("name", MODELS)
def test_the_module_gives_the_models_own_u(name):
    """What ``plan`` computes (the model's ``predict`` on windows, with a given prior and noise) is
    the module's, to the bit."""
    torch.manual_seed(1)
    model = fitted(MODELS[name]())
    x_t, x_next = transitions(model)
    m, g = model.dims.inputs, torch.Generator().manual_seed(3)
    noise, prior = torch.randn(len(x_t), m, generator=g), torch.randn(len(x_t), m, generator=g)
    flow = isinstance(model, RectifiedFlow)
    options = dict(noise=noise) if flow else {}
    if model.prior:
        options["prior"] = prior
    with torch.no_grad():
        expected = model.predict(torch.stack([x_t, x_next], 1), **options)
        u, outside = step_of(model).unclipped(x_t, x_next, **options)
    torch.testing.assert_close(u, expected, rtol=0, atol=0)
    assert not outside.any()


@pytest.mark.parametrize("name", MODELS)
def test_the_graph_is_the_module(name):
    """Exported by torch's exporter and run by onnxruntime on one thread: u within float32 rounding
    of the module in torch, the same flags, at any batch size."""
    torch.manual_seed(1)
    model = fitted(MODELS[name]())
    step = step_of(model, margin=1.0)
    x_t, x_next = transitions(model)
    x_t[::7, 0] = 2.0  # beyond the box
    x_next[::11, 1] = float("nan")
    x_t[::13, -1] = float("inf")
    with torch.no_grad():
        u, outside = step(x_t, x_next)
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    session = ort.InferenceSession(graph(step).SerializeToString(), options, providers=["CPUExecutionProvider"])
    for rows in (slice(None), slice(5, 6)):
        got_u, got_outside = session.run(None, {"x_t": x_t[rows].numpy(), "x_next": x_next[rows].numpy()})
        np.testing.assert_array_equal(got_outside, outside[rows].numpy())
        np.testing.assert_allclose(got_u, u[rows].numpy(), rtol=0, atol=TOLERANCE)
    assert 0.2 < outside.float().mean() < 0.8


def test_a_refused_transition_sends_the_safe_input_and_the_rest_are_clipped_per_input():
    torch.manual_seed(1)
    model = fitted(MODELS["mlp"]())
    with torch.no_grad():
        model.action_norm.std.fill_(20.0)  # u far beyond [-1, 1.5] often
    step = step_of(model, margin=1.0, safe=np.array([0.25, -0.5, 1.0]))
    x_t, x_next = transitions(model)
    x_next[::3, 2] = 9.0  # a units slip: far outside
    with torch.no_grad():
        raw, _ = step.unclipped(x_t, x_next)
        u, outside = step(x_t, x_next)
    refused = torch.zeros(len(x_t), dtype=torch.bool)
    refused[::3] = True
    assert torch.equal(outside, refused)
    assert torch.equal(u[refused], torch.tensor([[0.25, -0.5, 1.0]]).expand(int(refused.sum()), 3))
    kept = raw[~refused]
    assert ((kept < -1) | (kept > 1.5)).float().mean() > 0.2  # many would saturate
    assert torch.equal(u[~refused], kept.clamp(-1.0, 1.5))


def test_the_grid_prior_is_exact_for_a_field_linear_in_its_coordinates():
    """Trilinear interpolation reproduces a field linear in the grid's coordinates (the arc's
    actuation, the chord); a point off the grid or in a kink cell is flagged."""
    A, c = np.array([[0.3, -1.2, 4.0], [2.0, 0.5, -7.0]]), np.array([0.1, -0.2])
    p = tips(300)
    s = coordinates(p)
    on = ((s >= GRID.low) & (s <= GRID.low + GRID.spacing * (GRID.shape - 1))).all(-1)
    assert 50 < on.sum() < 300  # points on and off the grid
    with torch.no_grad():
        u, flagged = GridPrior(GRID)(torch.as_tensor(p))
    np.testing.assert_array_equal(flagged.numpy(), ~on)
    np.testing.assert_allclose(u.numpy()[on], s[on] @ A.T + c, rtol=0, atol=2e-5)  # float32 coordinates
    cell = np.minimum(((s[on][0] - GRID.low) / GRID.spacing).astype(int), GRID.shape - 2)
    with torch.no_grad():
        _, flagged = GridPrior(linear_grid(A, c, kink_at=[cell @ GRID.cell_strides]))(torch.as_tensor(p[on][:1]))
    assert flagged.item()


def test_a_step_refuses_a_model_of_a_window_and_a_prior_model_without_its_grid():
    from softflow.models.baselines import InverseLSTM

    with pytest.raises(ValueError, match="a step reads one transition; InverseLSTM reads 10"):
        step_of(InverseLSTM(dims=DIMS))
    model = MODELS["rf-physical"]()
    with pytest.raises(ValueError, match="static prior: give its grid"):
        Step(model, low=[-1, -1], high=[1, 1], safe=[0, 0], box_low=[-1] * 6, box_high=[1] * 6)
