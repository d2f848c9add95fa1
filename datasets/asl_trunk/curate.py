"""Rebuild the curated ASL trunk recordings (README.md) from the upstream files.

    python datasets/asl_trunk/curate.py UPSTREAM_DIR [--out DIR] [--record-sums]

UPSTREAM_DIR holds the nine upstream CSV files of StanfordASL/trunk-stack (commit and folder:
README.md), unchanged: each is checked against its SHA-256 below before anything is read. The
curated files (one gzip-compressed CSV per run, in the project's recording format,
docs/recordings.md) are written to DIR (default: this folder) and checked against SHA256SUMS
beside this script; any mismatch exits with status 1 and says which file. ``--record-sums``
writes SHA256SUMS from the outputs instead (only when the conversion changed on purpose).

The bytes are reproducible: fixed number formats, rows in ID order, and a gzip container
written here with no name and mtime 0 around zlib's raw deflate at level 9. zlib 1.2.x gives
the same deflate stream for the same input; should another zlib compress differently, the
check says whether the decompressed tables still agree.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import hashlib
import io
import struct
import sys
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent
SUMS = "SHA256SUMS"
UPSTREAM = {  # file: SHA-256 (commit 8b4b9234b287a0403d1844821bfad79e36e1f66f)
    "control_inputs_controlled_1.csv": "3ad99980da3ad5182f2ff694fad10b2a23d680b90606b665229b2b20cb56ed43",
    "control_inputs_controlled_2.csv": "2980d4647a22bd0a4c5c475213103f5ca1fac781767e62e728865c86b562e62e",
    "control_inputs_controlled_26.csv": "0f885d73d561eaf1d1c2665293a4906e5acddd71d86a5dfde364721cc8a15eda",
    "htest_circles_amp07_hz02.csv": "c2d7db89099a8f3ba44f664ebd778ac6234462cad9f46525d2349c7ff95a9bf4",
    "observations_controlled_1.csv": "bc4c951556c971d8849e556f067bf041c6de359b630a88d70760738abb836541",
    "observations_controlled_1_100g.csv": "790953bd1c715a8d6ddafa3e8dbe5e7781727a164119311a0fec99c6e6e2ffc0",
    "observations_controlled_1_300g.csv": "7153b29b798170b9a4083dd1f7fa9de7ee709df883f272b4af5777f91b7fd9ce",
    "observations_controlled_2.csv": "71d278011a289ba911db18a5299a792673b9ebaf0013ef9f6e423722a282c67f",
    "observations_zeros_0g.csv": "fd9ddb1c95d62ea061701c5923597cf729dfd0019defb4eeda25f4200d3bba27",
}
RUNS = {  # curated run: (upstream inputs file or None for all inputs 0, upstream observations file)
    "random_1": ("control_inputs_controlled_1.csv", "observations_controlled_1.csv"),
    "random_2": ("control_inputs_controlled_2.csv", "observations_controlled_2.csv"),
    "circles": ("control_inputs_controlled_26.csv", "htest_circles_amp07_hz02.csv"),
    "rest": (None, "observations_zeros_0g.csv"),
    "payload_100g": ("control_inputs_controlled_1.csv", "observations_controlled_1_100g.csv"),  # random_1's inputs
    "payload_300g": ("control_inputs_controlled_1.csv", "observations_controlled_1_300g.csv"),  # with a tip mass
}
RATE = 100  # Hz: ID is the sample index at the nominal rate, time_s = ID / RATE
INPUTS = [f"u{i}" for i in range(1, 7)]  # servo angles, degrees
DISKS = (1, 2, 3)  # base outwards; disk 3 is the tip
INPUT_DECIMALS, POSITION_DECIMALS = 3, 6  # 0.001 degree, 1e-6 m


class CurationError(Exception):
    """What went wrong, said for the person running the script."""


def sha256(content: bytes) -> str:
    return hashlib.sha256(content).hexdigest()


def read_upstream(folder: Path) -> dict[str, bytes]:
    """The upstream files' bytes, each checked against its recorded SHA-256."""
    files = {}
    for name, expected in UPSTREAM.items():
        path = folder / name
        try:
            content = path.read_bytes()
        except OSError as error:
            raise CurationError(f"{path}: cannot read the upstream file ({error})") from error
        if sha256(content) != expected:
            raise CurationError(
                f"{path}: SHA-256 {sha256(content)} differs from the upstream file's {expected}; "
                "fetch the unchanged file from the commit in README.md"
            )
        files[name] = content
    return files


def _rows(content: bytes, name: str, columns: list[str]) -> list[list[float]]:
    """The named columns of an upstream CSV as floats, rows in file order, IDs 0, 1, 2, ..."""
    reader = csv.reader(io.StringIO(content.decode("ascii")))
    header = next(reader)
    missing = [c for c in ["ID", *columns] if c not in header]
    if missing:
        raise CurationError(f"{name}: no column {missing[0]!r} (the columns are {header})")
    index = [header.index(c) for c in columns]
    rows = []
    for k, row in enumerate(reader):
        if int(row[header.index("ID")]) != k:
            raise CurationError(f"{name}: row {k} has ID {row[header.index('ID')]}; expected IDs 0, 1, 2, ...")
        rows.append([float(row[i]) for i in index])
    return rows


def _cell(value: float | None, decimals: int) -> str:
    """A number rounded to ``decimals`` places, never '-0.000'; None is an empty cell."""
    if value is None:
        return ""
    text = f"{value:.{decimals}f}"
    return text[1:] if text.lstrip("-0.") == "" and text.startswith("-") else text


def table(files: dict[str, bytes], run: str) -> str:
    """One curated run as CSV text: time_s, u1..u6, x1_m, y1_m, z1_m, ..., z3_m. Observation row
    k was logged just before input k was sent, so they share row k; the last observation has no
    input after it (empty input cells)."""
    inputs_file, observations_file = RUNS[run]
    positions = [f"{axis}{disk}" for disk in DISKS for axis in "xyz"]
    observed = _rows(files[observations_file], observations_file, positions)
    if inputs_file is None:
        sent = [[0.0] * len(INPUTS) for _ in observed[:-1]]
    else:
        sent = _rows(files[inputs_file], inputs_file, INPUTS)
    if len(observed) != len(sent) + 1:
        raise CurationError(
            f"{run}: {len(observed)} observation rows and {len(sent)} input rows; expected one observation more"
        )
    header = ["time_s", *INPUTS, *[f"{axis}{disk}_m" for disk in DISKS for axis in "xyz"]]
    lines = [",".join(header)]
    for k, position in enumerate(observed):
        u = sent[k] if k < len(sent) else [None] * len(INPUTS)
        cells = [_cell(k / RATE, 2)] + [_cell(v, INPUT_DECIMALS) for v in u]
        lines.append(",".join(cells + [_cell(v, POSITION_DECIMALS) for v in position]))
    return "\n".join(lines) + "\n"


def gzip_bytes(text: str) -> bytes:
    """A gzip member (RFC 1952) with no file name and mtime 0 around a level-9 raw deflate:
    the same bytes on every machine with the same zlib."""
    data = text.encode("ascii")
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15, 9)
    body = compressor.compress(data) + compressor.flush()
    header = b"\x1f\x8b\x08\x00" + struct.pack("<I", 0) + b"\x02\xff"  # deflate, no flags, mtime 0, best, OS unknown
    return header + body + struct.pack("<II", zlib.crc32(data), len(data) & 0xFFFFFFFF)


def recorded_sums(path: Path) -> dict[str, str]:
    """{file name: SHA-256} from a sha256sum-style file."""
    try:
        lines = path.read_text().splitlines()
    except OSError as error:
        raise CurationError(f"{path}: cannot read the recorded sums ({error})") from error
    sums = {}
    for line in lines:
        digest, _, name = line.partition("  ")
        if line.strip():
            sums[name.strip()] = digest.strip()
    return sums


def check(outputs: dict[str, bytes], sums_path: Path) -> None:
    """Every output has the SHA-256 recorded in ``sums_path``, and every recorded file was made."""
    sums = recorded_sums(sums_path)
    if set(sums) != set(outputs):
        raise CurationError(f"{sums_path}: records {sorted(sums)}; the script makes {sorted(outputs)}")
    for name, content in outputs.items():
        if sha256(content) != sums[name]:
            committed = sums_path.parent / name
            same_table = committed.is_file() and gzip.decompress(committed.read_bytes()) == gzip.decompress(content)
            why = (
                "the decompressed table agrees with the committed file: only the compression differs (another zlib?)"
                if same_table
                else "the table itself differs from the committed one"
            )
            raise CurationError(f"{name}: SHA-256 {sha256(content)} differs from the recorded {sums[name]}; {why}")


def curate(upstream: Path, out: Path, record_sums: bool = False) -> dict[str, bytes]:
    """Check the upstream files, write the curated ones to ``out`` and check (or record) their sums."""
    files = read_upstream(upstream)
    outputs = {f"{run}.csv.gz": gzip_bytes(table(files, run)) for run in RUNS}
    out.mkdir(parents=True, exist_ok=True)
    for name, content in outputs.items():
        (out / name).write_bytes(content)
    sums_path = HERE / SUMS
    if record_sums:
        sums_path.write_text("".join(f"{sha256(content)}  {name}\n" for name, content in sorted(outputs.items())))
    else:
        check(outputs, sums_path)
    return outputs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("upstream", type=Path, help="folder holding the nine upstream CSV files")
    parser.add_argument("--out", type=Path, default=HERE, help="where to write the curated files (default: here)")
    parser.add_argument("--record-sums", action="store_true", help=f"write {SUMS} from the outputs instead of checking")
    args = parser.parse_args(argv)
    try:
        outputs = curate(args.upstream, args.out, args.record_sums)
    except CurationError as error:
        print(f"curate.py: {error}", file=sys.stderr)
        return 1
    for name, content in outputs.items():
        print(f"{sha256(content)}  {args.out / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
