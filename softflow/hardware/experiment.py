"""The hardware experiment on the twin: plan, command, replay and film every reference, open
or closed loop; or replay motor commands planned as such (a model of recorded runs).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from softflow.checks import as_real_array, check_choice
from softflow.control.closed_loop import PI, learn_by_repetition
from softflow.control.metrics import peak_speed, tracking_rmse
from softflow.control.planning import pad_plans, plan_all
from softflow.hardware.commands import cable_commands, write_commands
from softflow.hardware.gap import RealityGap
from softflow.hardware.plant import CablePlant
from softflow.hardware.twin import TwinRig, observe_run, tracked_rmse, twin_camera
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import U_MAX

LOOPS = ("open", "closed")


def run_twin(
    controller,
    references,
    sim: Simulator,
    gap: RealityGap,
    *,
    loop: str = "open",
    correction=None,
    condition: str = "reference",
    repetitions: int = 1,
    camera_latency: float = 0.0,
    dropped: float = 0.0,
    calibration=None,
    command_dir=None,
    u_limit: float = U_MAX,
    seed: int = 0,
):
    """The hardware experiment on the twin, for every reference: ``loop="open"`` plans it with
    ``controller`` (trained on the model ``sim``), turns the plan into motor commands through
    ``sim``, replays them on the plant across ``gap`` (all references in one batch) and films
    the run; ``loop="closed"`` runs ``loop.run_loop`` against a ``TwinRig`` (the camera in the
    loop, ``camera_latency`` s late, a share ``dropped`` of frames lost; ``correction`` and
    ``condition`` as in ``run_loop``, its default gains if None; ``repetitions`` > 1 learns a
    feedforward across that many runs, ``loop.learn_by_repetition``, and scores the run the
    camera saw track best, the feedforward a user would keep, as the ILC floor keeps its best).
    ``calibration`` (``calibration.Calibration``, e.g. from an identification run): plans
    are mapped to the identified rod and made into motor commands through it, in both loops.
    Commands go to ``command_dir`` as CSV if given.
    Returns a DataFrame (one row per reference: RMSE through the camera and of the true tip,
    clipped commands and watchdog events) and {name: dict(u, commands, states, q, frame_times,
    tracked)}."""
    check_choice(loop, "loop", LOOPS)
    runs = (
        _open_runs(controller, references, sim, gap, u_limit, seed, calibration)
        if loop == "open"
        else {
            r.name: _closed_run(
                controller,
                r,
                sim,
                gap,
                dict(correction=correction or PI(), condition=condition, u_limit=u_limit, calibration=calibration),
                repetitions,
                camera_latency,
                dropped,
                seed + k,
            )
            for k, r in enumerate(references)
        }
    )
    return _rows(references, runs, sim, loop, command_dir), runs


def run_commands(
    commands, references, sim: Simulator, gap: RealityGap, *, clipped=None, seed: int = 0, command_dir=None
):
    """The open-loop experiment for plans that are motor commands already (a model of recorded
    runs trained on what the motors were sent, ``recorder.motor_columns``): ``commands[k]``
    (T_k, C) in m for reference k, replayed from rest on the plant across ``gap`` as they are,
    with no model rod and no calibration between (all in one batch, a shorter plan holding its
    last command), and filmed by ``run_twin``'s open-loop camera with the same seed per
    reference (``seed`` + k), so the two are scored alike. ``clipped``: per reference, how many
    planned values were clipped to the recorded range (0 if None). Returns what ``run_twin``
    returns (``u`` of a run: its commands)."""
    commands = list(commands)
    if len(commands) != len(references):
        raise ValueError(f"commands must hold one (T, C) plan per reference ({len(references)}); got {len(commands)}")
    clipped = [0] * len(references) if clipped is None else [int(c) for c in clipped]
    if len(clipped) != len(references):
        raise ValueError(f"clipped must give one count per reference ({len(references)}); got {len(clipped)}")
    n_cables = sim.robot.n_cables
    plans = [as_real_array(c, f"commands[{k}]", (None, n_cables))[0] for k, c in enumerate(commands)]  # (T_k, C) each
    for r, plan in zip(references, plans):
        if len(plan) != r.n_steps:
            raise ValueError(f"commands for {r.name!r} must have one row per step of it ({r.n_steps}); got {len(plan)}")
    _, padded = pad_plans(plans)  # (R, T_max, C)
    runs = _replayed(references, plans, padded, sim, gap, seed)
    for r, count in zip(references, clipped):
        runs[r.name]["clipped"] = count
    return _rows(references, runs, sim, "open", command_dir), runs


def _rows(references, runs: dict, sim: Simulator, loop: str, command_dir) -> pd.DataFrame:
    """One scored row per reference of its run (commands written to ``command_dir`` if given)."""
    rows = []
    for r in references:
        run = runs[r.name]
        if command_dir is not None:
            write_commands(Path(command_dir) / f"{r.name}.csv", run["commands"])
        rows.append(
            dict(
                reference=r.name,
                family=r.family,
                gravity=sim.gravity,
                loop=loop,
                rmse_mm=1e3 * tracked_rmse(run["frame_times"], run["tracked"], r),
                rmse_true_mm=1e3 * tracking_rmse(run["states"], r.states, r.mask),
                peak_speed=peak_speed(run["states"], r.mask),
                lost_frames=int(np.isnan(run["tracked"]).any(1).sum()),
                clipped=run["clipped"],
                watchdog_events=run["watchdog_events"],
                repetition=run.get("repetition", 1),
            )
        )
    return pd.DataFrame(rows)


def _open_runs(controller, references, sim, gap, u_limit, seed, calibration) -> dict:
    plans, padded = plan_all(controller, references, u_limit)
    if calibration is None:
        commands = cable_commands(padded, sim)
    else:
        padded = np.clip(calibration.actuation(padded), -u_limit, u_limit)
        plans, commands = [padded[k, : len(u)] for k, u in enumerate(plans)], calibration.commands(padded)
    return _replayed(references, plans, commands, sim, gap, seed)


def _replayed(references, plans, commands, sim, gap, seed) -> dict:
    """Motor commands (R, T_max, C) in m replayed on the plant across ``gap`` in one batch and
    each reference's run filmed (seed + k): {name: dict(u, commands, states, q, frame_times,
    tracked, clipped, watchdog_events)}, ``u`` the reference's plan (T_k, m)."""
    plant = CablePlant(sim.robot, sim.gravity, gap)
    replayed = plant.replay(commands)
    camera = twin_camera(sim, gap)
    runs = {}
    for k, (r, u) in enumerate(zip(references, plans)):
        n = len(u)
        run = dict(
            u=u,
            commands=commands[k, :n],
            states=replayed["states"][k, : n + 1],
            q=replayed["q"][k, : n + 1],
            clipped=0,
            watchdog_events=0,
        )
        run["frame_times"], run["tracked"] = observe_run(plant.sim, run["q"], camera, seed=seed + k)
        runs[r.name] = run
    return runs


def _closed_run(controller, reference, sim, gap, loop_options, repetitions, latency, dropped, seed) -> dict:
    def make_rig():
        return TwinRig(sim, gap, latency=latency, dropped=dropped, seed=seed, calibration=loop_options["calibration"])

    runs = learn_by_repetition(controller, reference, make_rig, repetitions=repetitions, **loop_options)
    kept = int(np.argmin([tracked_rmse(rig.frame_times, rig.tracked, reference) for _, rig in runs]))
    result, rig = runs[kept]
    return dict(
        u=result.u,
        commands=np.array(rig.commands),
        states=np.array(rig.states),
        q=np.array(rig.q),
        frame_times=np.array(rig.frame_times),
        tracked=np.array(rig.tracked),
        clipped=result.clipped,
        watchdog_events=result.watchdog_events,
        estimates=result.estimates,
        repetition=kept + 1,
    )
