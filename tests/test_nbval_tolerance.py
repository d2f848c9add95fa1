"""The notebooks' tolerance for numbers computed on the user's machine (notebooks/conftest.py): a
last-digit flip from another CPU's kernels passes, a result that moved by more fails, and exact
cells stay exact."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import pandas as pd
import pytest

CONFTEST = Path(__file__).resolve().parent.parent / "notebooks" / "conftest.py"
spec = importlib.util.spec_from_file_location("notebook_tolerance", CONFTEST)
tolerance = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tolerance)


@pytest.mark.parametrize(
    "token, unit", [("11.6", 0.1), ("18.199", 1e-3), ("-0.004", 1e-3), ("1.5e-04", 1e-5), ("653", 0.0), ("2.", 1.0)]
)
def test_one_unit_of_the_last_printed_digit(token, unit):
    assert tolerance.last_digit(token) == pytest.approx(unit)


@pytest.mark.parametrize(
    "ran, committed",
    [
        ("Rand4      14.4  19.1         11.7", "Rand4      14.4  19.1         11.6"),  # the AVX-512 flip
        ("| Transformer | 0.015 | 18.198 |", "| Transformer | 0.015 | 18.199 |"),
        ("x     9.99\ny    12.00", "x    10.00\ny    12.00"),  # a wider number shifts the columns
        ("-0.000 [-0.000, 0.000]", "0.000 [-0.000, -0.000]"),
    ],
)
def test_a_last_digit_from_another_cpu_agrees(ran, committed):
    assert tolerance.agree(ran, committed)


@pytest.mark.parametrize(
    "ran, committed",
    [
        ("Rand4      14.4  19.1         11.8", "Rand4      14.4  19.1         11.6"),  # two digits: a real change
        ("Rand2  1.4", "Rand1  1.4"),  # a name's digit is text
        ("53 steps", "54 steps"),  # an integer moves only by RTOL of itself
        ("lower: lstm", "lower: rf-fwd"),
        ("1.4  2.2", "1.4"),
        ("mean 1000.0", "mean 1010.0"),  # 1 %: beyond the last digit and RTOL
    ],
)
def test_a_real_change_does_not_agree(ran, committed):
    assert not tolerance.agree(ran, committed)


def test_rtol_admits_a_relative_change_below_it_on_a_large_number():
    assert tolerance.agree("40000.0", str(40000.0 * (1 + 0.9 * tolerance.RTOL)))
    assert not tolerance.agree("40000.0", str(40000.0 * (1 + 1.5 * tolerance.RTOL)))


# ---------------------------------------------------------------------------- through nbval
ROWS = pd.DataFrame(
    {"reference": ["circle", "Rand4"], "mlp": [1.4123, 14.4321], "transformer": [2.8012, 11.6499]}
)  # Rand4's transformer a hair below a rounding edge, as the committed 11.6 of notebook 03


def notebook_printing(rows: pd.DataFrame, folder: Path, tags: list[str]) -> Path:
    """A notebook that prints result rows as notebook 03 prints its RMSE pivot, its stored output
    that of ``ROWS``; the rows it reads are ``rows``; beside it the project's notebooks/conftest.py."""
    rows.to_csv(folder / "rows.csv", index=False)
    source = "import pandas as pd\nprint(pd.read_csv('rows.csv').set_index('reference').round(1).to_string())"
    cell = nbformat.v4.new_code_cell(source, execution_count=1, metadata={"tags": tags})
    stored = ROWS.set_index("reference").round(1).to_string() + "\n"
    cell.outputs = [nbformat.v4.new_output("stream", name="stdout", text=stored)]
    path = folder / "results.ipynb"
    nbformat.write(nbformat.v4.new_notebook(cells=[cell]), path)
    shutil.copy(CONFTEST, folder / "conftest.py")
    return path


def nbval(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--nbval", "--nbval-current-env", path.name],
        capture_output=True,
        text=True,
        cwd=path.parent,
    )


def perturbed(row: str, column: str, factor: float) -> pd.DataFrame:
    rows = ROWS.copy()
    rows.loc[rows.reference == row, column] *= factor
    return rows


def test_a_kernel_path_spread_across_a_rounding_edge_passes_a_tagged_cell(tmp_path):
    across_the_edge = perturbed("Rand4", "transformer", 1 + 2e-5)  # 11.6499 -> 11.6501: prints 11.7
    assert nbval(notebook_printing(across_the_edge, tmp_path, [tolerance.TAG])).returncode == 0


def test_the_same_spread_fails_an_exact_cell(tmp_path):
    across_the_edge = perturbed("Rand4", "transformer", 1 + 2e-5)
    result = nbval(notebook_printing(across_the_edge, tmp_path, []))
    assert result.returncode != 0 and "11.7" in result.stdout


def test_a_result_row_moved_by_more_than_the_tolerance_fails_a_tagged_cell(tmp_path):
    moved = perturbed("Rand4", "mlp", 1.01)  # 14.43 -> 14.58: 14.6 against the committed 14.4
    result = nbval(notebook_printing(moved, tmp_path, [tolerance.TAG]))
    assert result.returncode != 0 and "14.6" in result.stdout  # nbval's own diff, with both values


def test_an_images_payload_is_not_read_for_numbers():
    """A figure's base64 PNG differs in its digits from CPU to CPU (nbval skips it): the share of
    the tolerance comes from its text alone."""
    figure = dict(output_type="display_data", metadata={})
    ran = [dict(figure, data={"image/png": "iVBOR 172 xyz", "text/plain": "<Figure size 640x480 with 1 Axes>"})]
    committed = [dict(figure, data={"image/png": "iVBOR 171 xyz", "text/plain": "<Figure size 640x480 with 1 Axes>"})]
    _, largest = tolerance.within_tolerance(ran, committed)
    assert largest == 0.0
