"""Files on disk: content keys for caches and one atomic writer for everything we save.

A cache entry is named by a hash of the *numbers* that made it (parameters and explicit
version constants), never of source text, so a comment edit invalidates nothing. Every
file is written to a temporary file in its own directory, synced and renamed over the
destination, so a reader never sees half a file and an interrupted run corrupts nothing.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
# Generated datasets, caches and user-trained models (git-ignored): the one cache root, which
# every layer writes under; $SOFTFLOW_DATA moves it (e.g. for an installed package).
DATA_DIR = Path(os.environ.get("SOFTFLOW_DATA", REPO / "data"))
# Committed copies of small caches that cost minutes to compute and depend on nothing but their
# key (reference trajectories and static tables: thousands of static solves; the ci twin's
# identification fit): read when the cache itself lacks the file, so a fresh clone plans at once;
# a run never writes here.
SHIPPED_CACHE = REPO / "cache"


def content_key(spec: dict, length: int = 16) -> str:
    """Hex digest of ``spec`` as canonical JSON (sorted keys): equal specs, equal keys."""
    text = json.dumps(spec, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:length]


@contextmanager
def atomic_write(path, mode: str = "wb"):
    """Open a temporary file beside ``path`` for writing; on success it replaces ``path``,
    on any error it is removed and ``path`` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text(path, text: str):
    with atomic_write(path, "w") as f:
        f.write(text)


def write_npz(path, **arrays):
    with atomic_write(path) as f:
        np.savez(f, **arrays)


def read_npz(path) -> dict | None:
    """All arrays of an npz file, or None when it is missing, truncated or corrupt (zip CRC)."""
    try:
        with np.load(path) as f:
            return {k: f[k] for k in f.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return None


def cached_arrays(directory, kind: str, spec: dict, compute, valid=None) -> dict:
    """The arrays cached as ``cache_file(directory, kind, spec)``, else its committed copy in
    ``SHIPPED_CACHE`` (same name, so the same content key); when both are missing, corrupt or
    fail ``valid``, those of ``compute()`` (a dict of arrays), saved first and read back, so every
    way returns the same. The spec is saved beside the arrays (``spec_file``): a shipped copy then
    says what made it, so a check can ask today's code whether it still asks for that file."""
    path = cache_file(directory, kind, spec)
    for source in (path, SHIPPED_CACHE / path.name):
        arrays = read_npz(source)
        if arrays is not None and (valid is None or valid(arrays)):
            return arrays
    arrays = compute()
    write_text(spec_file(path), json.dumps(spec, sort_keys=True, indent=1, default=str) + "\n")
    write_npz(path, **arrays)
    return read_npz(path)


def spec_file(path) -> Path:
    """Where the spec of the cache file ``path`` is kept: beside it, as JSON."""
    return Path(path).with_suffix(".json")


def cache_file(directory, kind: str, spec: dict) -> Path:
    """``directory``/<kind>-<content key of spec>.npz"""
    return Path(directory) / f"{kind}-{content_key(spec)}.npz"
