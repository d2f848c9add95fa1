"""twin_burst: where the twin's loops break on the burst circle."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from softflow import hardware
from softflow.data.references import (
    hardware_burst_reference,
)
from softflow.profiles import get_profile
from softflow.studies import stress
from softflow.studies.closed_loop import CAMERA_LATENCY, LOOP_GRID, learning_options, twin_setup
from softflow.studies.study import Grid, training_spec


@dataclass(frozen=True, kw_only=True)
class BurstGrid(Grid):
    modes: tuple[str, ...]  # of closed_loop.LOOP_MODES
    periods: tuple[float, float]  # s: the burst circle's first and last
    duration: float  # s


# Fixed before any ran: the burst circle continued to a 0.2 s period (paper profile; the ci
# profile a short, steep one) under TYPICAL_GAP with 33 ms latency, in the open loop, the
# integral-corrected closed loop and learning across repetitions; broken as in notebook 05.
BURST_GRID = {
    "ci": BurstGrid(modes=("open", "closed"), periods=(2.0, 0.3), duration=4.0),
    "paper": BurstGrid(modes=("open", "closed", "closed-ilc"), periods=(5.0, 0.2), duration=12.0 * 4.8 / 3.8),
}


def cells(profile_name: str) -> list[dict]:
    cell = dict(study="twin_burst", model="rf-fwd", seed=0, latency=CAMERA_LATENCY, dropped=0.0, gap="typical")
    return [
        dict(cell, gravity=g, mode=mode, **learning_options(mode))
        for g in LOOP_GRID[profile_name].configs
        for mode in BURST_GRID[profile_name].modes
    ]


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """One loop mode on the twin's speeding-up burst circle; one row per complete revolution
    (its period, reference speed and y-z RMSE of the true tip, as notebook 05 scores the burst)."""
    controller, sim, gap, options, _ = twin_setup(cell, profile_name, device, workdir)
    grid = BURST_GRID[profile_name]
    reference = hardware_burst_reference(sim, grid.periods, grid.duration)
    rows, runs = hardware.run_twin(controller, [reference], sim, gap, **options)
    centre = sim.tip_positions(sim.rest_q()[None])[0, 1:]
    breakdown = stress.burst_breakdown(reference, {cell["mode"]: runs[reference.name]}, sim.robot.length, centre)
    counts = rows.iloc[0][["rmse_mm", "clipped", "watchdog_events", "repetition"]].to_dict()
    return [
        dict(row, reference=reference.name, **{f"whole_{k}": v for k, v in counts.items()})
        for row in breakdown.drop(columns="model").to_dict("records")
    ]


def models(cell: dict, profile_name: str) -> dict:
    return training_spec(cell["model"], get_profile(profile_name))
