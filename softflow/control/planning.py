"""Open-loop control: plan u_t = g(x*_t, x*_{t+1}) for a whole reference in one batched call,
run the plan in the simulator from rest, and score it."""

from __future__ import annotations

import copy
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from softflow.checks import as_real_array, check_choice
from softflow.control.metrics import actuation_mae, fitting_lag, input_energy, phase_lag, tracking_rmse
from softflow.control.step import BoundGraph, Step
from softflow.data.dataset import Dataset, dataset_path, gather_windows
from softflow.data.recordings import load_dataset as load_recordings
from softflow.models.checkpoints import find_checkpoint, identity, load_checkpoint, model_from_checkpoint
from softflow.models.common import one_thread
from softflow.models.flow import RectifiedFlow
from softflow.models.specs import CONTROLLERS
from softflow.profiles import get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import DT, SIM_ROBOT, U_MAX, Robot, rod_folder
from softflow.rod.statics import InverseGrid

NOISE = ("zero", "seeded", "fresh")
# A reference tip position farther than this many training standard deviations from the
# training mean, on any axis, is refused: millimetres for metres, or another rod's
# references. The paper's references (shapes, random, burst, complex 3D) reach at most 5.4,
# the simulation rod's references on a hardware-twin model 11 to 61 (docs/assumptions.md).
WORKSPACE_MARGIN = 8.0


class SaturationWarning(UserWarning):
    """A plan asked for more than the actuator range and was clipped."""


def input_box(u_range, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(low, high), (m,) each, from ``u_range`` (low, high), each a number or one per input; a
    ValueError unless both are finite with low <= high for each input."""
    low, high = (np.broadcast_to(np.asarray(b, np.float64), (m,)).copy() for b in u_range)
    if not (np.isfinite(low).all() and np.isfinite(high).all() and (low <= high).all()):
        raise ValueError(f"u_range must be (low, high) with low <= high for each input; got {u_range!r}")
    return low, high


class Controller:
    """A trained inverse model used open loop: ``plan`` maps references to actuation.

    A generative model starts every step from noise z: by default z = 0, the centre of the
    noise, which plans like the mean of many draws (notebook 05) and is deterministic;
    ``noise="seeded"`` draws one z per trajectory from ``seed`` and uses it at every step,
    ``noise="fresh"`` draws a new z for every step; ``sample`` gives independent draws.
    ``robot`` and ``gravity``: the rod the model was trained for (RF-Physical's prior is
    its statics, tabulated once per controller; None for a model of recorded runs, which has
    none). ``u_limit``: the actuator range (N) plans are clipped to, +-u_limit; ``u_range``:
    (low, high), each a number or one per input, clips to that box instead (a recording's
    inputs, e.g. motor positions from 0 to 30 mm, need not be symmetric about 0).
    ``observe``: what the model was shown of a tip path, applied to every reference ``plan``
    and ``sample`` get (e.g. ``variants.Variant.observe``: velocities
    hidden, or by finite differences, which need the path); None: the full state. ``step``
    takes its two states as the model sees them. ``workspace_margin``: references, and
    states given to ``step``, farther than this many training standard deviations are
    refused (``check_workspace``); None plans anything, for studies that measure
    extrapolation on purpose. ``delay_steps``: the rig's input-to-motion delay in periods (a
    model of recorded runs learnt the input sent that many periods before each step): ``plan``
    returns inputs already advanced by it, so row k is sent at period k (``advance``).
    ``tip_columns``: the observed columns a model of recorded runs reads, named in errors.
    ``dt``: the sample period (s) a step spans: by default the rod's, ``DT``, and unknown (None)
    without a rod; a model of recorded runs gets its recordings'. ``safe_input``: what the step
    sends for a transition it refuses (m,), by default the centre of the input range (0 N on
    the rods; 0 clipped into a range that is not finite)."""

    def __init__(
        self,
        model: torch.nn.Module,
        name: str,
        seed: int = 0,
        *,
        robot: Robot = SIM_ROBOT,
        gravity: str = "vertical",
        u_limit: float = U_MAX,
        u_range=None,
        observe=None,
        workspace_margin: float | None = WORKSPACE_MARGIN,
        delay_steps: int = 0,
        tip_columns: tuple[str, ...] = (),
        dt: float | None = None,
        safe_input=None,
    ):
        if not (isinstance(delay_steps, int) and delay_steps >= 0):
            raise ValueError(f"delay_steps must be a whole number of periods >= 0; got {delay_steps!r}")
        if not u_limit > 0:
            raise ValueError(f"u_limit must be a positive actuator range in N; got {u_limit!r}")
        if dt is not None and not dt > 0:
            raise ValueError(f"dt must be a positive sample period in s or None; got {dt!r}")
        if model.needs_statics and robot is None:
            raise ValueError(
                f"{name} learns a residual around the static prior of a simulated rod: it needs that rod "
                "(robot=), and a model of recorded runs has none"
            )
        self.model, self.name, self.seed, self.robot, self.gravity = model, name, seed, robot, gravity
        self._rng = np.random.default_rng(seed)  # sample_step's draws
        norm, p = model.state_norm, model.dims.position
        self._mean, self._std = (b.numpy()[:p].astype(np.float64) for b in (norm.mean, norm.std))  # tip position
        self.u_limit, self.observe, self.workspace_margin = float(u_limit), observe, workspace_margin
        self.delay_steps, self.tip_columns = delay_steps, tuple(tip_columns)
        self.dt = dt if dt is not None else DT if robot is not None else None
        self._limit(u_range, safe_input)
        self.generative = isinstance(model, RectifiedFlow)
        self.statics = Simulator(robot, gravity).static_table() if model.needs_statics else None
        self.statics_grid = InverseGrid(self.statics) if self.statics is not None else None  # step's prior

    @property
    def model(self) -> torch.nn.Module:
        return self._model

    @property
    def has_step(self) -> bool:
        """Whether the model reads one transition (a window of past states only plans)."""
        return self.model.context == 1

    @model.setter
    def model(self, model: torch.nn.Module):
        """The inverse model (in eval mode); another model makes its step again when next used."""
        self._model, self._step_module, self._graph = model.eval(), None, None

    def _limit(self, u_range, safe_input):
        """Set the box u is clipped to, (low, high) (m,) each (None: +-``u_limit``), and the safe input."""
        m = self.model.dims.inputs
        self._low, self._high = np.full(m, -self.u_limit), np.full(m, self.u_limit)  # (m,) each
        self._range = f"the actuator range +-{self.u_limit:g} N"
        if u_range is not None:
            low, high = input_box(u_range, m)
            self._low, self._high, self.u_limit = low, high, float(np.abs([low, high]).max())
            symmetric = (low == -high).all() and (high == high[0]).all()
            bounds = [f"{a:g} to {b:g}" for a, b in zip(low, high)]
            self._range = f"the input range +-{high[0]:g}" if symmetric else f"the input ranges {', '.join(bounds)}"
        finite = np.isfinite(self._low) & np.isfinite(self._high)
        default = np.where(finite, (self._low + self._high) / 2, np.clip(0.0, self._low, self._high))
        safe = default if safe_input is None else np.broadcast_to(np.asarray(safe_input, np.float64), (m,)).copy()
        if not ((self._low <= safe) & (safe <= self._high)).all():
            raise ValueError(f"safe_input must be one value per input inside {self._range}; got {safe_input!r}")
        self.safe_input, self._step_module, self._graph = safe, None, None

    def limited(self, u_range=None, safe_input=None) -> Controller:
        """This controller with another input box ``u_range`` (low, high), each a number or one per
        input (None: the same), and another safe input (None: the new box's default); for a rig whose
        actuators must stay inside narrower limits than the data took."""
        other = copy.copy(self)
        other._limit((self._low, self._high) if u_range is None else u_range, safe_input)
        return other

    @property
    def step_module(self) -> Step:
        """The step, defined once (``control.step.Step``): the model with this controller's input
        range, safe input, workspace box and, for a prior model, its rod's inverse-statics grid."""
        if not self.has_step:
            raise ValueError(
                f"{self.name} reads a window of {self.model.context} past transitions: it has no "
                "one-transition step; use plan"
            )
        if self._step_module is None:
            self._step_module = Step(
                self.model,
                low=self._low,
                high=self._high,
                safe=self.safe_input,
                box_low=self._state_box[0],
                box_high=self._state_box[1],
                grid=self.statics_grid,
            )
        return self._step_module

    @property
    def bound_graph(self) -> BoundGraph:
        """``step_module``'s graph in onnxruntime, what ``step`` runs (made at its first use)."""
        if self._graph is None:
            self._graph = BoundGraph(self.step_module)
        return self._graph

    def step(self, x_t, x_next, *, clip: bool = True) -> np.ndarray:
        """u_t for one transition, (d,), (d,) -> (m,), or a batch, (B, d), (B, d) -> (B, m): the
        real-time path, ``step_module`` exported as one ONNX graph and run by onnxruntime (the
        graph ``softflow export`` writes), the same u as ``plan`` to about 1e-5 N. A flow starts
        from z = 0, as ``plan`` does. u beyond the input range is clipped, with a
        ``SaturationWarning`` (``clip=False``: the model's u as it gives it, from the module in
        torch, for a loop that adds its own correction first). A transition the graph flags
        outside (a state not finite or outside the workspace, or RF-Physical's prior off its
        grid) is refused, as ``plan`` refuses a reference: a units slip must not command full
        actuation (a robot's program sends the graph's safe input instead). RF-Physical's prior
        comes from the inverse-statics grid (``InverseGrid``, within 1e-3 N of ``plan``'s table).
        Models that read a window of past states (LSTM, Transformer) have no step: ``plan`` them."""
        d = self.model.dims.state
        if clip and type(x_t) is type(x_next) is np.ndarray and x_t.shape == x_next.shape == (d,):  # real time
            bound = self.bound_graph
            bound.x_t[0], bound.x_next[0] = x_t, x_next  # float32, as the graph reads them
            bound.run()
            if not bound.outside[0]:
                u = bound.u[0].astype(np.float64)
                if bound.saturated():
                    self._warn_clipped(u, "stepped")
                return u
        x, x_next, unbatched = self._pair(x_t, x_next)
        if clip:
            u, outside = self.bound_graph.session.run(None, {"x_t": x, "x_next": x_next})
        else:
            u, outside = self._unclipped(x, x_next)
        if outside.any():
            self._refuse(x, x_next, outside, unbatched)
        u = u.astype(np.float64)
        if clip:
            self._warn_clipped(u, "stepped")
        return u[0] if unbatched else u

    def _refuse(self, x_t, x_next, outside, unbatched: bool):
        """Raise for the transitions (B, d) the step flags outside, naming why."""
        for x, name in ((x_t, "x_t"), (x_next, "x_next")):
            self.check_workspace(x[0] if unbatched else x, name)
        if self.statics_grid is not None:
            raise ValueError(
                f"{self.name}: x_next's tip at index {int(np.argmax(outside))} lies where the static prior's "
                "grid does not reach (off the grid, or beside the static table's clipped edge); plan it instead"
            )
        raise ValueError(f"{self.name}: a state at index {int(np.argmax(outside))} is outside the workspace")

    def sample_step(self, x_t, x_next, n: int, *, seed: int | None = None) -> np.ndarray:
        """``n`` draws of u_t for one transition, (d,), (d,) -> (n, m), or a batch, -> (n, B, m): the
        flow's uncertainty about this step, from independent noise z (numpy's normal; ``seed``
        None: the controller's own generator, so each call draws afresh), not clipped. The draws
        go through ``step_module`` as one batch."""
        if not (isinstance(n, int) and n >= 1):
            raise ValueError(f"n must be a positive integer; got {n!r}")
        if not self.generative:
            raise ValueError(f"{self.name} is a regression model: it has no noise to sample")
        m = self.model.dims.inputs
        x, x_next, unbatched = self._pair(x_t, x_next)
        x, x_next = np.tile(x, (n, 1)), np.tile(x_next, (n, 1))  # (n B, d) each
        rng = self._rng if seed is None else np.random.default_rng(seed)
        noise = torch.as_tensor(rng.standard_normal((len(x), m)), dtype=torch.float32)
        u, outside = self._unclipped(x, x_next, noise=noise)
        if outside.any():
            self._refuse(x, x_next, outside, False)
        u = u.astype(np.float64).reshape(n, -1, m)
        return u[:, 0] if unbatched else u

    def _pair(self, x_t, x_next) -> tuple[np.ndarray, np.ndarray, bool]:
        """``step``'s arguments checked and as the step reads them, (B, d) float32 each, and whether
        they were one transition."""
        d = self.model.dims.state
        x, unbatched = as_real_array(x_t, "x_t", (None, d), allow_unbatched=True)
        x_next, _ = as_real_array(x_next, "x_next", x.shape[1:] if unbatched else x.shape)
        return np.atleast_2d(x).astype(np.float32), np.atleast_2d(x_next).astype(np.float32), unbatched

    def _unclipped(self, x_t, x_next, **options) -> tuple[np.ndarray, np.ndarray]:
        """(u (B, m), outside (B,)) of ``step_module.unclipped`` in torch for states (B, d) float32."""
        with torch.inference_mode(), one_thread():
            u, outside = self.step_module.unclipped(torch.as_tensor(x_t), torch.as_tensor(x_next), **options)
        return u.numpy(), outside.numpy()

    def _clip(self, u, what: str) -> np.ndarray:
        """u (..., m) clipped to the input range, with a ``SaturationWarning`` that counts the
        values clipped (3 levels up: the caller of ``plan``)."""
        kept = np.clip(u, self._low, self._high)
        if (kept != u).any():
            self._warn(int(np.sum(kept != u)), u.size, what)
        return kept

    def _warn_clipped(self, u, what: str):
        """The ``SaturationWarning`` of the step's graph, which clipped u (..., m): a clipped value is
        its input's bound (the step's, in float32) exactly."""
        low, high = (b.numpy() for b in (self.step_module.low, self.step_module.high))
        at_bound = (u == low) | (u == high)
        if at_bound.any():
            self._warn(int(at_bound.sum()), u.size, what)

    def _warn(self, clipped: int, size: int, what: str):
        warnings.warn(
            f"{self.name}: {clipped} of {size} {what} u values exceed {self._range} and were clipped",
            SaturationWarning,
            stacklevel=4,
        )

    def plan(
        self, reference, *, noise: str = "zero", seed: int | None = None, n_samples: int = 1, **options
    ) -> np.ndarray:
        """(T+1, d) or (B, T+1, d) reference -> (T, m) or (B, T, m) actuation, every
        step predicted in one batched call (the plan depends on the reference only).
        ``n_samples`` > 1 plans with the mean of that many noise draws: a Monte-Carlo
        estimate of E[u | x_t, x_t+1], the plan of least squared actuation error.

        Options: ``steps`` (Euler steps of a flow, >= 1). u beyond the actuator range
        (``u_limit`` or ``u_range``) is clipped, with a ``SaturationWarning`` that counts the samples."""
        check_choice(noise, "noise", NOISE)
        if not (isinstance(n_samples, int) and n_samples >= 1):
            raise ValueError(f"n_samples must be a positive integer; got {n_samples!r}")
        if n_samples == 1:
            u = advance(self._plan(reference, noise, seed, options), self.delay_steps)
        elif noise == "zero":
            raise ValueError("n_samples > 1 averages random draws: use noise='seeded' or 'fresh'")
        else:
            u = self.sample(reference, n_samples, noise=noise, seed=seed, **options).mean(0)
        return self._clip(u, "planned")

    def sample(self, reference, n: int, *, noise: str = "seeded", seed: int | None = None, **options) -> np.ndarray:
        """``n`` plans from independent noise draws: (n, T, m) or (n, B, T, m), not clipped,
        advanced by the delay as ``plan``'s. Their spread is the flow's own uncertainty about the
        actuation (a regression model has none: ValueError)."""
        if not (isinstance(n, int) and n >= 1):
            raise ValueError(f"n must be a positive integer; got {n!r}")
        check_choice(noise, "noise", NOISE[1:])
        if not self.generative:
            raise ValueError(f"{self.name} is a regression model: it has no noise to sample")
        self._check_observed(reference)
        X, unbatched = as_real_array(reference, "reference", (None, None, self.model.dims.state), allow_unbatched=True)
        u = self._plan(np.tile(X, (n, 1, 1)), noise, seed, options).reshape(n, len(X), -1, self.model.dims.inputs)
        u = advance(u, self.delay_steps)
        return u[:, 0] if unbatched else u

    def _check_observed(self, reference):
        """A reference of another number of observed coordinates than a model of recorded runs
        reads is refused with the columns it needs, before its shape is (with a bare shape)."""
        d, given = self.model.dims.state, np.shape(reference)
        if self.tip_columns and len(given) >= 2 and given[-1] != d:
            raise ValueError(
                f"{self.name} was trained on the observed columns {', '.join(self.tip_columns)}: a reference "
                f"needs {d} numbers per sample (their positions, then their velocities); got {given[-1]}. Give "
                "every one of those columns, or plan with a model trained on the columns you have "
                "(softflow train MODEL --recordings DIR --tip COLS; in Python recordings.load_dataset(..., tip=[...]))"
            )

    def _check_options(self, noise, options):
        if not self.generative:
            if noise != "zero" or options:
                raise ValueError(
                    f"{self.name} is a regression model: it takes no noise or step options; "
                    f"got noise={noise!r}, options {sorted(options)}"
                )
            return
        unknown = set(options) - {"steps"}
        if unknown:
            raise ValueError(f"unknown plan options {sorted(unknown)}; a flow takes steps=N")
        steps = options.get("steps")
        if steps is not None and not (isinstance(steps, (int, np.integer)) and steps >= 1):
            raise ValueError(f"steps must be a positive integer; got {steps!r}")

    @property
    def workspace_margin(self) -> float | None:
        return self._margin

    @workspace_margin.setter
    def workspace_margin(self, margin: float | None):
        """The margin, and the box of tip positions it sets, mean -+ margin x std, computed here once
        so that a step's check is one compiled call."""
        if margin is not None and not margin > 0:
            raise ValueError(f"workspace_margin must be positive or None; got {margin!r}")
        self._margin = margin
        self._step_module = self._graph = None  # the step's box moves: built again when next used
        d, p = self.model.dims.state, len(self._mean)
        largest = np.finfo(np.float64).max  # any finite value, where nothing is refused
        self._state_box = np.full(d, -largest), np.full(d, largest)  # (d,) each
        if margin is not None:
            self._halfwidth = margin * self._std
            self._state_box[0][:p], self._state_box[1][:p] = self._mean - self._halfwidth, self._mean + self._halfwidth

    @property
    def workspace(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The training mean of the tip position and the half-widths about it beyond which a state
        is refused, (p,) each (m); the half-widths are None when the margin is (nothing is refused)."""
        return self._mean.copy(), None if self._margin is None else self._halfwidth.copy()

    @property
    def input_range(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high), (m,) each: the box ``plan`` and ``step`` clip u to."""
        return self._low.copy(), self._high.copy()

    def _outside(self, X) -> bool:
        """Whether a tip position of states X (..., d) lies beyond the workspace margin."""
        if self._margin is None:
            return False
        (low, high), p = self._state_box, len(self._mean)
        return bool(((X[..., :p] < low[:p]) | (X[..., :p] > high[:p])).any())

    def check_workspace(self, X, name: str = "reference"):
        """Refuse states X (..., d) far outside the training states (unit mistakes, another rod);
        ``name`` says in the message what X is."""
        if not self._outside(X):
            return
        p = len(self._mean)
        score = np.abs(X[..., :p] - self._mean) / self._std
        *where, axis = worst = np.unravel_index(np.argmax(score), score.shape)
        at = f" at index {tuple(int(i) for i in where)}" if where else ""
        raise ValueError(
            f"{name} tip position {'xyz'[axis] if p <= 3 else axis} = {X[worst]:.4g} m{at} is "
            f"{score[worst]:.0f} training standard deviations from the training mean {self._mean[axis]:.3f} m "
            f"(at most {self._margin:g}): is it in metres, and for the rod this model was trained on?"
        )

    def _plan(self, reference, noise, seed, options) -> np.ndarray:
        self._check_options(noise, options)
        dims = self.model.dims
        self._check_observed(reference)
        X, unbatched = as_real_array(reference, "reference", (None, None, dims.state), allow_unbatched=True)
        B, T = X.shape[0], X.shape[1] - 1
        if B == 0:
            raise ValueError("reference must hold at least one trajectory (its batch axis is empty)")
        if T < 1:
            raise ValueError("reference must have at least 2 samples")
        if self.observe is not None:
            X = self.observe(X)
        self.check_workspace(X)
        episodes, steps = np.repeat(np.arange(B), T), np.tile(np.arange(T), B)
        windows = torch.as_tensor(gather_windows(X, episodes, steps, self.model.context), dtype=torch.float32)
        extras = {
            k: torch.as_tensor(v.reshape(B * T, -1), dtype=torch.float32)
            for k, v in self.model.extras(X, self.statics).items()
        }
        if self.generative:
            generator = torch.Generator().manual_seed(self.seed if seed is None else seed)
            z = torch.randn((B, T if noise == "fresh" else 1, dims.inputs), generator=generator)
            start = torch.zeros_like(z) if noise == "zero" else z  # where each step's flow starts
            options["noise"] = start.expand(B, T, dims.inputs).reshape(B * T, dims.inputs)
        with torch.inference_mode(), one_thread():
            if self.has_step:  # the step on a batch, with the static table's prior where the model has one
                u, _ = self.step_module.unclipped(windows[:, 0], windows[:, 1], **extras, **options)
            else:
                u = self.model.predict(windows, **extras, **options)
        u = u.numpy().astype(np.float64).reshape(B, T, dims.inputs)
        return u[0] if unbatched else u


def advance(u: np.ndarray, steps: int) -> np.ndarray:
    """A plan (..., T, m) for a rig that moves ``steps`` periods after an input is sent: row k is
    the input the plan gave step k + steps, so sending row k at period k moves step k + steps as
    planned. The first ``steps`` steps of the reference move under whatever was sent before the
    plan began (hold the rig at the reference's start); the last ``steps`` rows repeat the last
    planned input (the reference says nothing past its end)."""
    if steps == 0:
        return u
    T = u.shape[-2]
    return u[..., np.minimum(np.arange(T) + steps, T - 1), :]


def find_trained(
    name: str,
    profile: str = "paper",
    robot: Robot = SIM_ROBOT,
    gravity: str = "vertical",
    model_kwargs: dict | None = None,
    *,
    recordings: Dataset | None = None,
):
    """The checkpoint of model ``name`` for a profile and rod, and whether it is current (trained
    with today's arguments, budget and data): ``models.checkpoints.find_checkpoint`` with the
    identity the profile asks for. ``recordings``: the Dataset of recorded runs it was trained on
    instead of a rod (its folder is named by the Dataset's key). (None, False) when there is none."""
    wanted, rod = trained_identity(name, profile, robot, gravity, model_kwargs, recordings=recordings)
    return find_checkpoint(name, profile, wanted, rod, model_kwargs)


def trained_identity(
    name: str,
    profile: str = "paper",
    robot: Robot = SIM_ROBOT,
    gravity: str = "vertical",
    model_kwargs: dict | None = None,
    *,
    recordings: Dataset | None = None,
) -> tuple[dict, str]:
    """The identity (``models.checkpoints.identity``) that a current checkpoint of model ``name``
    records for a profile and rod (or the Dataset of recorded runs), and its rod folder."""
    P = get_profile(profile)
    if recordings is not None:
        return identity(name, model_kwargs, P.train_config(name), recordings.key), recordings.key
    data_key = dataset_path(P, robot, gravity).stem
    return identity(name, model_kwargs, P.train_config(name, robot.name), data_key), rod_folder(robot, gravity)


def load_controller(
    name: str | Path,
    profile: str = "paper",
    robot: Robot = SIM_ROBOT,
    gravity: str = "vertical",
    *,
    recordings=None,
) -> Controller:
    """The trained model ``name`` ("mlp", "lstm", "transformer", ...) of a profile, for the rod
    and configuration it was trained on; paper-profile weights ship with the repository, so
    this works right after a clone. A model you trained yourself (data/checkpoints/) is
    preferred when it is current; a stale one is used with a warning.

    ``recordings``: a folder (or list of files) of recorded runs, or their Dataset
    (``recordings.load_dataset`` with your columns): the model trained on them by
    ``softflow train MODEL --recordings DIR``, with no rod. ``name`` may also be the path of a
    checkpoint file (.pt), loaded as it is. A model of recorded runs plans in their inputs and
    units, clipped to the range they took (``recorded_range``)."""
    if isinstance(name, Path) or str(name).endswith(".pt"):
        path = Path(name)
        if not path.is_file():
            raise ValueError(f"no checkpoint file {path}; expected a .pt file written by softflow train")
        checkpoint = load_checkpoint(path)
        _check_controller(checkpoint["name"])
        if recordings is not None:
            given = recordings if isinstance(recordings, Dataset) else load_recordings(recordings)
            if checkpoint.get("data_key") != given.key:
                raise ValueError(
                    f"{path} was trained on other data ({checkpoint.get('data_key')}) than these recordings "
                    f"({given.key}: their files or the options they were read with differ); load it without "
                    "recordings, or train a model on these"
                )
        return _controller(checkpoint, path, robot, gravity)
    _check_controller(name)
    if recordings is None:
        path, current = find_trained(name, profile, robot, gravity)
        what = f"profile {profile!r} and rod {robot.name!r} / {gravity!r}"
        command = f"--profile {profile} --robot {robot.name} --gravity {gravity} {name}"
    else:
        given = recordings if isinstance(recordings, Dataset) else load_recordings(recordings)
        path, current = find_trained(name, profile, recordings=given)
        folder = recordings if isinstance(recordings, (str, Path)) else "DIR"
        what = f"profile {profile!r} and {given.key}"
        command = f"{name} --recordings {folder} --profile {profile}"
    if path is None:
        raise ValueError(f"no trained {name!r} for {what}; train it with: python -m softflow train {command}")
    if not current:
        warnings.warn(
            f"{path} was trained with other arguments, budget, data or simulator version; "
            f"retrain it with: python -m softflow train {command}",
            stacklevel=2,
        )
    return _controller(load_checkpoint(path), path, robot, gravity)


def _check_controller(name: str):
    if name == "forward":
        raise ValueError(
            '"forward" is the forward-dynamics surrogate used by RF-FWD, not a controller; '
            f"load one of {list(CONTROLLERS)}"
        )
    check_choice(name, "controller", CONTROLLERS)


def _controller(checkpoint: dict, path: Path, robot: Robot, gravity: str) -> Controller:
    """The controller of a checkpoint: for ``robot`` and ``gravity``, or, for a model of recorded
    runs, for no rod and clipped to the recorded range."""
    model, name = model_from_checkpoint(checkpoint, path), checkpoint["name"]
    if "recorded" not in checkpoint:
        return Controller(model, name, robot=robot, gravity=gravity)
    recorded = checkpoint["recorded"]
    return Controller(
        model,
        name,
        robot=None,
        gravity=None,
        u_range=recorded_range(recorded),
        delay_steps=int(recorded.get("delay_steps", 0)),
        tip_columns=tuple(recorded.get("tip_columns", ())),
        dt=float(recorded["dt"]),
    )


def recorded_range(recorded: dict) -> tuple:
    """(low, high) a model of recorded runs clips its inputs to, from the range they took
    (a checkpoint's ``recorded`` u_min, u_max): +-the largest |input| when every input took
    both signs (a symmetric actuator, as the rod's +-U_MAX), else per input the [min, max]
    seen (motor positions from 0 to 30 mm must not be planned at -30 mm)."""
    low, high = np.asarray(recorded["u_min"], np.float64), np.asarray(recorded["u_max"], np.float64)  # (m,) each
    if (low < 0).all() and (high > 0).all():
        limit = float(max(-low.min(), high.max()))
        return -limit, limit
    return low, high


def plan_all(controller, references, u_limit: float = U_MAX, **plan_options):
    """Plan every reference and clip to ``u_limit``: the plans, and the same stacked
    (R, T_max, m) with shorter plans padded by holding their last u, ready for one batched run.
    Saturation is part of what an evaluation measures, so it is not warned about here."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)
        plans = [np.clip(controller.plan(r.states, **plan_options), -u_limit, u_limit) for r in references]
    return pad_plans(plans)


def pad_plans(plans):
    longest = max(len(u) for u in plans)
    return plans, np.stack([np.concatenate([u, np.repeat(u[-1:], longest - len(u), 0)]) for u in plans])


def evaluate(controller, references, sim: Simulator, u_limit: float = U_MAX, *, start_q=None, **plan_options):
    """Plan every reference (``plan_options`` go to ``plan``, e.g. steps=N), clip to the
    actuator range, run all plans open loop from rest (the rest pose, or ``start_q``, one
    (nq,) pose per reference) in one batched rollout, and score them. Returns a DataFrame
    (one row per reference) and {name: dict(u, states)}."""
    results, runs = evaluate_many([controller], references, sim, u_limit, start_q=start_q, **plan_options)
    return results, runs[controller.name]


def evaluate_many(
    controllers,
    references,
    sim: Simulator,
    u_limit: float = U_MAX,
    *,
    start_q=None,
    options_of: dict | None = None,
    **plan_options,
):
    """``evaluate`` for several controllers at once: every plan of every controller runs in
    one batched rollout, several times faster than one rollout per controller (the simulator
    is batch-invariant, so the numbers are the same). ``options_of`` {controller name: plan
    options} replaces ``plan_options`` for the controllers it names (e.g. one flow at several
    Euler step counts). Returns one DataFrame (a row per controller and reference) and
    {controller name: {reference name: dict(u, states)}}."""
    names = [c.name for c in controllers]
    if len(set(names)) != len(names):
        raise ValueError(f"controllers must have distinct names; got {names}")
    options_of = options_of or {}
    if unknown := sorted(set(options_of) - set(names)):
        raise ValueError(f"options_of names controllers that are not evaluated: {unknown}; they are {names}")
    planned = [plan_all(c, references, u_limit, **options_of.get(c.name, plan_options))[0] for c in controllers]
    _, padded = pad_plans([u for plans in planned for u in plans])
    start = None if start_q is None else np.tile(np.asarray(start_q, float), (len(controllers), 1))
    achieved = sim.rollout(padded, start_q=start)
    achieved = achieved.reshape(len(controllers), len(references), *achieved.shape[1:])
    rows, runs = [], {name: {} for name in names}
    for name, plans, outcomes in zip(names, planned, achieved):
        for r, u, X in zip(references, plans, outcomes):
            X = X[: r.n_steps + 1]
            rows.append(score(name, r, u, X, sim.dt))
            runs[name][r.name] = dict(u=u, states=X)
    return pd.DataFrame(rows), runs


def score(name: str, reference, u, achieved, dt: float = DT) -> dict:
    """One row of Tables I and II: a plan ``u`` (T, m) of ``name`` that ran to ``achieved``
    (T+1, d) at sample period ``dt`` (s), scored on the reference's masked samples (phase lag in
    the tip's y-z plane)."""
    masked = reference.mask
    row = dict(
        model=name,
        reference=reference.name,
        family=reference.family,
        rmse_mm=1e3 * tracking_rmse(achieved, reference.states, masked),
        phase_lag_s=phase_lag(
            achieved[masked, 1:3], reference.states[masked, 1:3], dt, max_lag=fitting_lag(int(masked.sum()), dt)
        ),
        input_energy=input_energy(u, dt),
    )
    if reference.u_true is not None:
        row.update({f"mae_u{i + 1}": error for i, error in enumerate(actuation_mae(u, reference.u_true))})
    return row
