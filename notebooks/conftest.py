"""How nbval compares the committed notebooks' outputs with a run's (pytest loads this for every
notebook here; docs/assumptions.md, "Numbers across CPUs").

Two kinds of printed numbers. Exact ones (closed forms, shipped rows, shipped caches) are compared
to the last character, as nbval does. Numbers computed from models trained or data simulated on
the machine that runs the notebook follow its CPU's kernels in their last bits (numpy's AVX-512
``exp`` and ``log``, torch's vector width, the BLAS), and training carries those bits on; a cell
that prints such numbers is tagged ``trained-here``. There a printed number agrees with the
committed one when

    |ran - committed| <= one unit of the committed number's last printed digit + RTOL * |committed|

and every other character agrees (runs of white space count as one, so a wider number may shift a
table's columns). RTOL is about 2.4 times the largest relative spread of a trained ci result measured
across kernel paths (2.1e-3, stress_complex3d.csv on the generic x86-64 path of an Intel Xeon; 5.9e-4
on an AMD EPYC: ``make portability``, figures/bench/portability_spread.csv), a margin for CPUs not
measured; a result that moves by more still fails.
"""

from __future__ import annotations

import copy
import json
import os
import re

TAG = "trained-here"
RTOL = 5e-3  # about 2.4 times the largest relative spread of a trained ci result across kernel paths
# A number standing alone: not part of a name such as Rand1, tau0.05 or u1.
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
SPREAD_LOG = "SOFTFLOW_NBVAL_SPREAD"  # a file: each tagged cell's largest deviation, one JSON line


def last_digit(token: str) -> float:
    """One unit of the last printed digit of a number as printed: 0.1 for "11.6", 1e-5 for
    "1.5e-04"; 0 for an integer, which only RTOL lets move."""
    mantissa, _, exponent = token.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    if "." not in mantissa and not exponent:
        return 0.0
    return 10.0 ** (int(exponent or 0) - decimals)


def skeleton(text: str) -> str:
    """The text with every number a placeholder and every run of white space one space."""
    return re.sub(r"\s+", " ", NUMBER.sub("#", text)).strip()


def deviation(ran: str, committed: str) -> tuple[float, float] | None:
    """How far the numbers of ``ran`` are from those of ``committed``: the largest
    |difference| / (last digit + RTOL |committed|) (at most 1: within tolerance) and the largest
    relative difference; None where the texts differ in anything but numbers."""
    if skeleton(ran) != skeleton(committed):
        return None
    worst, relative = 0.0, 0.0
    for a, b in zip(NUMBER.findall(ran), NUMBER.findall(committed)):
        x, y = float(a), float(b)
        allowed = last_digit(b) + RTOL * abs(y)
        if x != y:
            worst = max(worst, abs(x - y) / allowed if allowed > 0 else float("inf"))
            relative = max(relative, abs(x - y) / abs(y) if y else float("inf"))
    return worst, relative


def agree(ran: str, committed: str) -> bool:
    found = deviation(ran, committed)
    return found is not None and found[0] <= 1.0


def _texts(output) -> list[tuple[tuple[str, ...], str]]:
    """(where, text) of every text an output carries: a stream's text, each text/* MIME type (not
    an image's base64 payload, whose digits are no numbers: nbval skips PNG and JPEG)."""
    if "text" in output:
        return [(("text",), output["text"])]
    return [
        (("data", kind), value)
        for kind, value in output.get("data", {}).items()
        if kind.startswith("text/") and isinstance(value, str)
    ]


def within_tolerance(outputs, committed, sanitize=lambda text: text) -> tuple[list, float | None]:
    """``outputs`` with each text whose numbers agree with the committed one's replaced by the
    committed text (so nbval then finds them equal, and shows its usual diff where they do not),
    and the largest share of the tolerance a number used (None where the texts did not line up)."""
    snapped, largest = copy.deepcopy(list(outputs)), 0.0
    if len(snapped) != len(committed):
        return snapped, None
    for output, reference in zip(snapped, committed):
        if output.get("output_type") != reference.get("output_type"):
            return snapped, None
        mine, theirs = dict(_texts(output)), dict(_texts(reference))
        for where, text in mine.items():
            if where not in theirs:
                return snapped, None
            found = deviation(sanitize(text), sanitize(theirs[where]))
            if found is None:
                return snapped, None
            largest = max(largest, found[0])
            if found[0] <= 1.0:
                target = output
                for key in where[:-1]:
                    target = target[key]
                target[where[-1]] = theirs[where]
    return snapped, largest


def _tolerant(item):
    compare = item.compare_outputs

    def compare_outputs(test, ref, skip_compare=None):
        snapped, largest = within_tolerance(test, ref, item.sanitize)
        if os.environ.get(SPREAD_LOG):
            with open(os.environ[SPREAD_LOG], "a") as log:
                log.write(json.dumps(dict(cell=item.name, notebook=str(item.fspath), used=largest)) + "\n")
        return compare(snapped, ref, skip_compare)

    return compare_outputs


def pytest_collection_modifyitems(items):
    """Compare every ``trained-here`` cell within tolerance; every other cell as nbval does."""
    for item in items:
        cell = getattr(item, "cell", None)
        if cell is not None and TAG in cell.get("metadata", {}).get("tags", []):
            item.compare_outputs = _tolerant(item)
