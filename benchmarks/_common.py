"""Timing helpers shared by the benchmark scripts."""

from __future__ import annotations

import time
from collections.abc import Callable


def best_of(function: Callable[[], object], repeats: int = 5) -> float:
    """The fastest of ``repeats`` wall-clock timings of ``function()``, seconds."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def rss_mib() -> float:
    """Resident set size of this process now, MiB (Linux)."""
    with open("/proc/self/statm") as handle:
        pages = int(handle.read().split()[1])
    import os

    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


#: Runs the livox-viz command line in a child and prints the child's own peak RSS (VmHWM, kB) as its last line.
_PEAK_CHILD = ("import sys\nfrom livox_viz.cli import main\n"
               "assert main(sys.argv[1:]) == 0\n"
               "print([line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM')][0])\n")


def command_peak_mib(argv: list[str]) -> tuple[float, float]:
    """Run ``livox-viz argv`` in a child process: its own peak resident set (MiB) and its wall time (s).

    The child reads its VmHWM itself: getrusage's ``ru_maxrss`` (and ``RUSAGE_CHILDREN``) keeps the larger
    peak of the process it was forked from across fork and exec, so every child would report the parent's.
    """
    import subprocess
    import sys

    start = time.perf_counter()
    result = subprocess.run([sys.executable, "-c", _PEAK_CHILD, *argv], check=True, capture_output=True, text=True)
    return int(result.stdout.strip().splitlines()[-1]) / 1024, time.perf_counter() - start
