"""Clean executed notebooks before they are committed: python tests/strip_notebooks.py [NOTEBOOK ...]
(default: every notebooks/NN_*.ipynb; `make strip`).

A papermill or Jupyter run stamps every cell with its execution times, adds a cell of injected
parameters and its own run record; none of it is a result, and it changes on every run, so a
regenerated notebook would differ in every cell. Stripped: cell ``metadata.execution``
(iopub/shell timestamps), cell ``metadata.papermill`` (start, end, duration, status), empty tag
lists, the ``injected-parameters`` cell (the committed notebooks are the ci run, the default of the
``parameters`` cell, which is kept), and the top-level ``metadata.papermill`` run record. Execution
counts are renumbered 1, 2, ... as a run without the injected cell numbers them.

Inline figures are re-encoded losslessly: matplotlib writes RGBA PNGs whose alpha is opaque
everywhere; the same pixels as RGB, at zlib's best compression, take about 13 % fewer bytes. The
pixels are unchanged (nbval does not compare images anyway).
"""

from __future__ import annotations

import base64
import io
import sys
from pathlib import Path

import nbformat
import numpy as np

NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"
CELL_KEYS = ("execution", "papermill")  # per-cell run metadata: timestamps, durations, status
INJECTED = "injected-parameters"


def committed_notebooks() -> list[Path]:
    return sorted(NOTEBOOKS.glob("[0-9]*.ipynb"))


def residue(nb) -> list[str]:
    """What ``strip`` would remove from ``nb``, one line each (empty: clean)."""
    found = [f"metadata.{key}" for key in ("papermill",) if key in nb.metadata]
    for k, cell in enumerate(nb.cells):
        found += [f"cell {k}: metadata.{key}" for key in CELL_KEYS if key in cell.metadata]
        if INJECTED in cell.metadata.get("tags", []):
            found.append(f"cell {k}: the {INJECTED} cell")
    return found


def lossless_png(encoded: str) -> str:
    """A base64 PNG re-encoded as RGB when its alpha is opaque everywhere, at the best zlib
    compression; the original when that is not smaller. The pixels are the same."""
    from PIL import Image

    raw = base64.b64decode(encoded)
    image = Image.open(io.BytesIO(raw))
    image.load()
    if image.mode == "RGBA" and np.asarray(image)[..., 3].min() == 255:
        image = image.convert("RGB")
    buffer = io.BytesIO()
    image.save(buffer, "PNG", optimize=True)
    if len(buffer.getvalue()) >= len(raw):
        return encoded
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def strip(nb):
    """``nb`` without run metadata (see the module docstring) and with its PNGs re-encoded losslessly."""
    nb.metadata.pop("papermill", None)
    nb.cells = [cell for cell in nb.cells if INJECTED not in cell.metadata.get("tags", [])]
    count = 0
    for cell in nb.cells:
        if cell.get("execution_count") is not None:
            count += 1
            cell.execution_count = count
            for output in cell.outputs:
                if output.get("execution_count") is not None:
                    output.execution_count = count
        for key in CELL_KEYS:
            cell.metadata.pop(key, None)
        if cell.metadata.get("tags") == []:
            del cell.metadata["tags"]
        for output in cell.get("outputs", []):
            if "image/png" in output.get("data", {}):
                output.data["image/png"] = lossless_png(output.data["image/png"])
    return nb


def strip_file(path: Path) -> tuple[int, int]:
    """Strip the notebook at ``path`` in place; its size in bytes before and after."""
    before = path.stat().st_size
    nb = strip(nbformat.read(path, as_version=4))
    nbformat.write(nb, path)
    return before, path.stat().st_size


def main(argv: list[str]) -> int:
    paths = [Path(a) for a in argv] or committed_notebooks()
    total = 0
    for path in paths:
        before, after = strip_file(path)
        total += after
        print(f"{path}: {before} -> {after} bytes")
    print(f"total {total} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
