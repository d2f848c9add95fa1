"""Which machine computed something: the CPU's model name, which a study row and a benchmark
record (the same sandbox comes with CPUs of very different speeds and vector units)."""

from __future__ import annotations

import os
import platform
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


def description() -> str:
    """One line about the machine: its CPU model named (machines of the same size have run this
    code 2.5x apart in speed), cores, memory, Python and the OS."""
    memory = ""
    if Path("/proc/meminfo").exists():
        kib = int(Path("/proc/meminfo").read_text().split()[1])
        memory = f", {kib / 2**20:.0f} GiB memory"
    cpu = cpu_model() or platform.processor()
    return (
        platform.machine() + (f" ({cpu})" if cpu else "") + f", {os.cpu_count()} cores{memory}, "
        f"Python {platform.python_version()}, {platform.system()}"
    )
