"""closed_loop: Table III extended, the twin's RF-FWD open and in closed loop."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from softflow import data, hardware, training
from softflow.control import closed_loop as loop
from softflow.control.planning import WORKSPACE_MARGIN, Controller
from softflow.data.references import (
    hardware_references,
)
from softflow.hardware import identification
from softflow.hardware.calibration import Calibration
from softflow.profiles import get_profile
from softflow.rod.dynamics import Simulator
from softflow.rod.robots import HW_ROBOT
from softflow.store import cached_arrays
from softflow.studies.study import Grid, training_spec

LOOP_MODES = {  # mode -> hardware.run_twin options (repetitions: the profile's)
    "open": dict(loop="open"),
    "open-calibrated": dict(loop="open", calibrated=True),
    "closed": dict(loop="closed"),
    "closed-calibrated": dict(loop="closed", calibrated=True),
    "closed-estimate": dict(loop="closed", condition="estimate"),
    "closed-ilc": dict(loop="closed", repetitions=None),
    "closed-ilc-calibrated": dict(loop="closed", repetitions=None, calibrated=True),
}
GAP_MODES = ("open", "open-calibrated", "closed", "closed-calibrated")  # under each doubled gap term


@dataclass(frozen=True, kw_only=True)
class LoopGrid(Grid):
    configs: tuple[str, ...]  # gravity configurations of the twin
    modes: tuple[str, ...]  # of LOOP_MODES
    references: int  # the first of hardware_references
    repetitions: int  # of a mode that learns across repetitions
    latencies: tuple[float, ...]  # s: the closed loop's extra cells at these camera latencies
    dropped: bool  # a closed-loop cell with 10 % of the frames lost
    gaps: tuple[str, ...]  # terms of the typical gap doubled, one cell each


LOOP_GRID = {
    "ci": LoopGrid(
        configs=("vertical",),
        modes=("open", "closed", "closed-ilc-calibrated"),
        references=1,
        repetitions=2,
        latencies=(),
        dropped=False,
        gaps=(),
    ),
    "paper": LoopGrid(
        configs=("vertical", "horizontal"),
        modes=tuple(LOOP_MODES),
        references=5,
        repetitions=5,
        latencies=(0.0, 0.066),
        dropped=True,
        gaps=hardware.GAP_TERMS,
    ),
}
CAMERA_LATENCY = 0.033  # s: one frame at 30 fps


def cells(profile_name: str) -> list[dict]:
    grid = LOOP_GRID[profile_name]
    cell = dict(study="closed_loop", model="rf-fwd", seed=0, latency=CAMERA_LATENCY, dropped=0.0, gap="typical")
    cells = [dict(cell, gravity=g, mode=mode, **learning_options(mode)) for g in grid.configs for mode in grid.modes]
    cells += [dict(cell, gravity=g, mode="closed", latency=latency) for g in grid.configs for latency in grid.latencies]
    cells += [dict(cell, gravity=g, mode="closed", dropped=0.1) for g in grid.configs if grid.dropped]
    cells += [
        dict(cell, gravity=g, mode=mode, gap=f"2x {term}")
        for term in grid.gaps
        for g in grid.configs
        for mode in GAP_MODES
    ]
    return cells + [dict(cell, gravity=g, mode="open", gap="none") for g in grid.configs]  # what the gap costs


def learning_options(mode: str) -> dict:
    """The cell field that names the learning law's revision in modes that learn across
    repetitions (``loop.SETTLE``: the first revision also learnt the start transient)."""
    return dict(settle=list(loop.SETTLE)) if "repetitions" in LOOP_MODES[mode] else {}


def _gap(name: str) -> hardware.RealityGap:
    """ "typical", "none" (the plant is the model rod) or "2x <term>": TYPICAL_GAP with that term
    doubled (notebook 06's sensitivity table reads the open-loop cells of each)."""
    if name in ("typical", "none"):
        return hardware.TYPICAL_GAP if name == "typical" else hardware.NO_GAP
    return hardware.TYPICAL_GAP.doubled(name.removeprefix("2x "))


def twin_setup(cell: dict, profile_name: str, device: str, workdir: Path):
    """The twin model of the cell's configuration, its simulator, the gap, the run_twin options
    of the cell's loop mode, and the identified terms (empty unless calibrated)."""
    profile, gravity = get_profile(profile_name), cell["gravity"]
    sim = Simulator(HW_ROBOT, gravity)
    dataset = data.DatasetOnDemand(profile, HW_ROBOT, gravity, progress=False)  # made only to train
    model, _ = training.ensure_trained(cell["model"], profile, dataset, HW_ROBOT, gravity, device=device)
    gap = _gap(cell["gap"])
    options, identified = mode_options(cell["mode"], profile_name, sim, gap, workdir)
    # closed-estimate conditions the model on the measured state of a rod it sets swinging, out
    # of the training workspace within the run: measured, not refused (docs/assumptions.md)
    margin = None if options.get("condition") == "estimate" else WORKSPACE_MARGIN
    controller = Controller(model, cell["model"], robot=HW_ROBOT, gravity=gravity, workspace_margin=margin)
    return controller, sim, gap, dict(options, camera_latency=cell["latency"], dropped=cell["dropped"]), identified


def mode_options(mode: str, profile_name: str, sim: Simulator, gap: hardware.RealityGap, workdir: Path):
    """``run_twin``'s options of a loop mode in a profile, and the identified terms as row
    columns (empty unless calibrated: then an identification run on this rig comes first, as on
    a real one, cached in ``workdir``)."""
    options = dict(LOOP_MODES[mode])
    if "repetitions" in options:
        options["repetitions"] = LOOP_GRID[profile_name].repetitions
    identified = {}
    if options.pop("calibrated", False):
        fit = identified_twin(sim, gap, get_profile(profile_name).identification_seconds, workdir)
        options["calibration"] = Calibration.identified(sim, fit)
        identified = {f"identified_{term}": getattr(fit.gap, term) for term in identification.FITTED}
    return options, identified


def run(cell: dict, profile_name: str, device: str, workdir: Path, key: str) -> list[dict]:
    """The twin model of one configuration on Table III's references under the cell's gap, in
    one loop mode; one row per reference."""
    controller, sim, gap, options, identified = twin_setup(cell, profile_name, device, workdir)
    references = hardware_references(sim)[: LOOP_GRID[profile_name].references]
    rows, _ = hardware.run_twin(controller, references, sim, gap, **options)
    return [dict(row, **identified) for row in rows.drop(columns=["gravity", "loop"]).to_dict("records")]


def identified_spec(sim: Simulator, gap: hardware.RealityGap, seconds: float) -> dict:
    """What a cached identification is keyed by: the model rod, the gap it is run across and the
    excitation's length."""
    return dict(simulator=sim.spec(), gap=gap.parameters(), seconds=seconds)


def identified_twin(sim: Simulator, gap: hardware.RealityGap, seconds: float, workdir: Path):
    """``identification.identify_twin``, cached in the sweep's workdir: the calibrated cells of
    one configuration and gap share the same identification run (deterministic, ~2 min)."""

    def compute():
        fit = identification.identify_twin(sim, gap, seconds=seconds)
        return dict(
            {term: getattr(fit.gap, term) for term in identification.FITTED},
            rmse_mm=fit.rmse_mm,
            evaluations=fit.evaluations,
        )

    cached = cached_arrays(workdir, "identified", identified_spec(sim, gap, seconds), compute)
    fitted = hardware.RealityGap(**{term: float(cached[term]) for term in identification.FITTED})
    return identification.Identified(fitted, float(cached["rmse_mm"]), int(cached["evaluations"]))


def models(cell: dict, profile_name: str) -> dict:
    return training_spec(cell["model"], get_profile(profile_name))
