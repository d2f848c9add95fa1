"""nbval must really compare outputs: a notebook whose stored number was altered fails."""

import subprocess
import sys
from pathlib import Path

import nbformat

NOTEBOOK = Path(__file__).resolve().parent.parent / "notebooks" / "01_simulator.ipynb"
STORED = "EI=0.02513 N m^2"  # printed by the robot-parameters cell of notebook 01


def run_nbval(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--nbval", "--nbval-current-env", str(path)],
        capture_output=True,
        text=True,
        cwd=path.parent,
    )


def first_cells_through(marker: str):
    """Notebook 01 cut after the first cell whose stored output contains ``marker``."""
    nb = nbformat.read(NOTEBOOK, as_version=4)
    for end, cell in enumerate(nb.cells):
        if any(marker in output.get("text", "") for output in cell.get("outputs", [])):
            nb.cells = nb.cells[: end + 1]
            return nb
    raise AssertionError(f"notebook 01 no longer prints {marker!r}")


def test_nbval_passes_the_stored_output_and_fails_an_altered_one(tmp_path):
    nb = first_cells_through(STORED)
    intact = tmp_path / "intact.ipynb"
    nbformat.write(nb, intact)
    assert run_nbval(intact).returncode == 0

    outputs = nb.cells[-1]["outputs"]
    for output in outputs:
        if "text" in output:
            output["text"] = output["text"].replace(STORED, "EI=0.02514 N m^2")
    altered = tmp_path / "altered.ipynb"
    nbformat.write(nb, altered)
    result = run_nbval(altered)
    assert result.returncode != 0
    assert "0.02514" in result.stdout  # the failure is the comparison, reported with both values
