"""How many cores this process may use: the one count every pool of the model starts from."""

from __future__ import annotations

import os


def usable_cores() -> int:
    """The CPUs this process may run on, at least 1.

    ``os.process_cpu_count()`` where Python has it (3.13: it honours ``-X cpu_count`` and
    ``PYTHON_CPU_COUNT``), else the scheduler's affinity mask (``taskset``, a batch system's
    CPU set), else every CPU of the machine. A container's CPU quota (``docker --cpus``) is
    not a mask and is not seen; ``--workers`` sets the count by hand there.
    """
    counted = getattr(os, "process_cpu_count", None)
    if counted is not None:
        return max(1, counted() or 1)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity on this platform (macOS, Windows)
        return max(1, os.cpu_count() or 1)
