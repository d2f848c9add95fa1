"""Which machine computed something: the CPU's model name, which a study row and a benchmark
record (the same sandbox comes with CPUs of very different speeds and vector units)."""

from __future__ import annotations

from pathlib import Path


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo ('' where there is none)."""
    if not Path("/proc/cpuinfo").exists():
        return ""
    models = [
        line.split(":", 1)[1].strip()
        for line in Path("/proc/cpuinfo").read_text().splitlines()
        if line.startswith("model name")
    ]
    return models[0] if models else ""
