"""Every committed file that a run reuses or resumes from, found by one walk of the folders that
hold them, and whether today's code would ask for it: the check each meets at run time, made
without running anything.

- a recording folder's claim (``figures/**/recorder.json``): the settings today's recorder writes
  for the same robot, gravity, gap terms and run choices (a rerun refuses any other);
- a shipped cache file (``cache/*.npz``): the key today's code gives the same choices (the rod's
  parameters, the gap's terms, the set's kind and builder, the sizes), from the spec kept beside
  it (a run would not find a file under another key, and would compute it again);
- a checkpoint (``checkpoints/**/*.pt``): the identity ``find_trained`` asks of its rod's model
  (arguments, budget, data key; a stale one is used with a warning);
- a study's rows (``figures/sweeps/*.csv``): keys of cells of today's grid (rows under another key
  are served to no one).

A file in those folders that none of these knows is a problem too, so a new kind of artefact is
checked before it ships. ``python -m softflow.report.shipped [ROOT]`` prints them for a checkout.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from softflow.control.planning import trained_identity
from softflow.data.references import references_spec
from softflow.hardware import recorder
from softflow.hardware.gap import RealityGap
from softflow.models.checkpoints import checkpoint_path, load_checkpoint, matches
from softflow.models.specs import resolved_kwargs
from softflow.rod.dynamics import GRAVITY_DIRECTIONS, Simulator
from softflow.rod.robots import ROBOTS, Robot, rod_folder
from softflow.rod.statics import table_spec
from softflow.store import REPO, content_key, spec_file
from softflow.studies import STUDIES, closed_loop, sweep


@dataclass(frozen=True)
class Artefact:
    path: Path
    kind: str
    check: Callable[[Path, Path], str | None]  # (path, root) -> what today's code asks otherwise, or None

    def problem(self, root: Path) -> str | None:
        try:
            return self.check(self.path, root)
        except (KeyError, TypeError, ValueError) as error:  # settings today's classes no longer take
            return f"today's code cannot rebuild what made it ({type(error).__name__}: {error})"


def artefacts(root: Path = REPO) -> list[Artefact]:
    """Every file under the folders whose files a run reuses, each with its check."""
    root = Path(root)
    found = [Artefact(path, "recording claim", _claim) for path in sorted((root / "figures").rglob(recorder.SETTINGS))]
    found += [Artefact(path, "study rows", _rows) for path in sorted((root / "figures" / "sweeps").glob("*"))]
    for path in sorted((root / "cache").glob("*")):
        if path.suffix != ".json" or not path.with_suffix(".npz").is_file():  # a spec is checked with its file
            found.append(Artefact(path, "cache", _cache))
    for path in sorted((root / "checkpoints").rglob("*")):
        if path.is_file() and path.name != "README.md":
            found.append(Artefact(path, "checkpoint", _checkpoint))
    return found


def problems(root: Path = REPO) -> dict[str, str]:
    """{path relative to root: what is wrong} for every shipped artefact today's code would not ask for."""
    root = Path(root)
    return {
        str(artefact.path.relative_to(root)): problem
        for artefact in artefacts(root)
        if (problem := artefact.problem(root)) is not None
    }


def _claim(path: Path, root: Path) -> str | None:
    found = json.loads(path.read_text())
    asked = recorder.settings(
        ROBOTS[found["robot"]],
        found["gravity"],
        RealityGap(**found["gap"]),
        found["seconds"],
        found["seed"],
        found["latency"],
        found["dropped"],
    )
    return _differences(found, asked, "claims")


# How today's code makes the spec of each kind of shipped cache file from the choices a stored
# spec names (kind: the file name before its key).
RESPEC = {
    "references": lambda s: references_spec(_simulator(s["simulator"]), s["kind"], s["build"]),
    "static-table": lambda s: table_spec(_simulator(s["simulator"]), s["u_range"], s["step"]),
    "identified": lambda s: closed_loop.identified_spec(
        _simulator(s["simulator"]), RealityGap(**s["gap"]), s["seconds"]
    ),
}


def _cache(path: Path, root: Path) -> str | None:
    if path.suffix != ".npz":
        return f"not a cache file (.npz with its spec beside it, {spec_file(path.with_suffix('.npz')).name})"
    kind, key = path.stem.rsplit("-", 1)
    if not spec_file(path).is_file():
        return f"no {spec_file(path).name} beside it: copy the one the run wrote beside it in data/"
    stored = json.loads(spec_file(path).read_text())
    if content_key(stored) != key:
        return f"its spec's key is {content_key(stored)}, not the {key} in its name"
    family = next((prefix for prefix in RESPEC if kind == prefix or kind.startswith(f"{prefix}-")), None)
    if family is None:
        return f"no check knows how today's code asks for {kind!r} (add it to softflow.report.shipped.RESPEC)"
    asked = json.loads(json.dumps(RESPEC[family](stored), default=str))
    return _differences(stored, asked, "was made with")


def _checkpoint(path: Path, root: Path) -> str | None:
    if path.suffix != ".pt":
        return "not a checkpoint (.pt)"
    folder = path.parent.parent if path.parent.name == "variants" else path.parent
    rods = [
        (robot, gravity)
        for robot in ROBOTS.values()
        for gravity in GRAVITY_DIRECTIONS
        if root / "checkpoints" / rod_folder(robot, gravity) == folder
    ]
    if not rods:
        return f"{folder.relative_to(root)} is the folder of no rod today (its rod's parameters differ)"
    (robot, gravity), checkpoint = rods[0], load_checkpoint(path)
    name, default = checkpoint["name"], resolved_kwargs(checkpoint["name"])
    variant = {k: v for k, v in checkpoint["model_kwargs"].items() if v != default.get(k)}
    wanted, rod = trained_identity(name, "paper", robot, gravity, variant)
    where = checkpoint_path(name, "paper", rod, variant, shipped=True)
    if where.relative_to(REPO) != path.relative_to(root):
        return f"today's code looks for this model at {where.relative_to(REPO)}"
    if not matches(checkpoint, wanted):
        return _differences({k: checkpoint.get(k) for k in wanted}, wanted, "records")
    return None


def _rows(path: Path, root: Path) -> str | None:
    study, _, profile = path.stem.rpartition("-")
    if path.suffix != ".csv" or study not in STUDIES:
        return f"not the rows of a study (<study>-<profile>.csv, a study of {sorted(STUDIES)})"
    table = pd.read_csv(path, dtype={"key": str})
    keys = {
        sweep.cell_key(study, cell, profile, device)
        for cell in STUDIES[study].cells(profile)
        for device in set(table.device)
    }
    stale = table.loc[~table.key.isin(keys)].drop_duplicates("key")
    return f"{len(stale)} cells under keys that no cell of today's grid has" if len(stale) else None


def _simulator(spec: dict) -> Simulator:
    """The simulator a stored ``Simulator.spec()`` describes, built by today's classes (its rod
    from its parameters: a calibrated rod has no name to look up)."""
    parameters = {k: tuple(v) if isinstance(v, list) else v for k, v in spec["robot"].items()}
    options = {k: spec[k] for k in ("order", "n_segments", "substeps", "dt", "damping")}
    return Simulator(Robot(name="stored", **parameters), spec["gravity"], **options)


def _differences(found: dict, asked: dict, verb: str) -> str | None:
    """None when equal; else the fields that differ, dotted, with both values."""

    def walk(a, b, prefix=""):
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(a.keys() | b.keys()):
                yield from walk(a.get(k), b.get(k), f"{prefix}{k}.")
        elif a != b:
            yield f"{prefix[:-1]}: {a!r} there, {b!r} asked today"

    differ = list(walk(found, asked))
    return f"{verb} other settings than today's code asks for ({'; '.join(differ)})" if differ else None


if __name__ == "__main__":
    found = problems(Path(sys.argv[1]) if len(sys.argv) > 1 else REPO)
    for path, problem in found.items():
        print(f"{path}: {problem}")
    print(f"{len(found)} shipped artefacts that today's code would not ask for")
    sys.exit(1 if found else 0)
