"""The committed notebooks carry results, not run records, and stay small: no execution
timestamps or papermill metadata (tests/strip_notebooks.py removes them), 1.7 MB in all."""

import base64
import io
import re
from pathlib import Path

import nbformat
import numpy as np
import pytest
from nbval.plugin import get_sanitize_patterns
from PIL import Image
from strip_notebooks import INJECTED, committed_notebooks, lossless_png, residue, strip

MAX_TOTAL_BYTES = 1_700_000  # every committed notebook together: 16 notebooks, about 100 kB each
SANITIZE = Path(__file__).resolve().parent / "nbval_sanitize.cfg"  # make test's --nbval-sanitize-with


@pytest.mark.parametrize("path", committed_notebooks(), ids=lambda p: p.name)
def test_a_committed_notebook_has_no_run_metadata(path):
    found = residue(nbformat.read(path, as_version=4))
    assert not found, f"{path.name} carries run metadata ({found[:3]}...): run python tests/strip_notebooks.py {path}"


def test_the_committed_notebooks_total_at_most_1_7_mb():
    sizes = {path.name: path.stat().st_size for path in committed_notebooks()}
    assert len(sizes) >= 11
    assert sum(sizes.values()) <= MAX_TOTAL_BYTES, sizes


def png(pixels: np.ndarray) -> str:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, "PNG")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def pixels(encoded: str) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(encoded))).convert("RGBA"))


def executed_notebook(picture: str):
    """A notebook as papermill leaves it: timestamps on every cell, an injected-parameters cell."""
    stamps = dict(
        execution={"iopub.execute_input": "2026-01-01T00:00:00.1Z", "shell.execute_reply": "2026-01-01T00:00:00.2Z"},
        papermill=dict(
            duration=0.1, start_time="2026-01-01T00:00:00", end_time="2026-01-01T00:00:01", status="completed"
        ),
    )
    figure = nbformat.v4.new_output("display_data", data={"image/png": picture, "text/plain": "<Figure>"})
    result = nbformat.v4.new_output("execute_result", data={"text/plain": "2"}, execution_count=4)
    nb = nbformat.v4.new_notebook(
        cells=[
            nbformat.v4.new_markdown_cell("# title", metadata=dict(papermill=stamps["papermill"], tags=[])),
            nbformat.v4.new_code_cell('profile = "ci"', metadata=dict(stamps, tags=["parameters"]), execution_count=1),
            nbformat.v4.new_code_cell('profile = "ci"', metadata=dict(stamps, tags=[INJECTED]), execution_count=2),
            nbformat.v4.new_code_cell(
                "plot()", metadata=dict(stamps, tags=["nbval-ignore-output"]), outputs=[figure], execution_count=3
            ),
            nbformat.v4.new_code_cell("1 + 1", execution_count=4, outputs=[result]),
        ],
        metadata=dict(papermill=dict(duration=12.0, start_time="2026-01-01T00:00:00", parameters={"profile": "ci"})),
    )
    return nbformat.from_dict(nb)


def test_strip_removes_run_metadata_and_keeps_tags_and_pixels():
    rng = np.random.default_rng(0)
    opaque = rng.integers(0, 256, (30, 40, 4), dtype=np.uint8)
    opaque[..., 3] = 255
    opaque[:, :20, :3] = 200  # a flat half: something to compress
    nb = executed_notebook(png(opaque))
    assert residue(nb) == [
        "metadata.papermill",
        "cell 0: metadata.papermill",
        "cell 1: metadata.execution",
        "cell 1: metadata.papermill",
        "cell 2: metadata.execution",
        "cell 2: metadata.papermill",
        "cell 2: the injected-parameters cell",
        "cell 3: metadata.execution",
        "cell 3: metadata.papermill",
    ]

    clean = strip(nb)
    assert residue(clean) == []
    assert [cell.metadata for cell in clean.cells] == [
        {},
        {"tags": ["parameters"]},
        {"tags": ["nbval-ignore-output"]},
        {},
    ]
    assert [cell.get("execution_count") for cell in clean.cells] == [None, 1, 2, 3]  # as if never injected
    assert clean.cells[-1].outputs[0].execution_count == 3
    assert "papermill" not in clean.metadata
    output = clean.cells[2].outputs[0]
    assert output.data["text/plain"] == "<Figure>"
    np.testing.assert_array_equal(pixels(output.data["image/png"]), opaque)
    assert len(output.data["image/png"]) < len(png(opaque))


def test_a_transparent_png_keeps_its_alpha():
    translucent = np.full((8, 8, 4), 128, dtype=np.uint8)
    np.testing.assert_array_equal(pixels(lossless_png(png(translucent))), translucent)


def test_nbval_compares_a_figures_axes_but_not_its_size_in_pixels():
    """The inline dpi (profiles.setup) sets the pixel size a figure prints; it is no result."""

    def sanitized(text):
        for regex, replace in get_sanitize_patterns(SANITIZE.read_text()):
            text = re.sub(regex, replace, text)
        return text

    at_64_dpi, at_56_dpi = "<Figure size 921.6x230.4 with 4 Axes>", "<Figure size 806.4x201.6 with 4 Axes>"
    assert sanitized(at_64_dpi) == sanitized(at_56_dpi)
    assert sanitized("<Figure size 640x256 with 2 Axes>") != sanitized("<Figure size 640x256 with 3 Axes>")
