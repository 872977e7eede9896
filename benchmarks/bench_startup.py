"""Start-up of the model-only commands (issue 19: <= 0.5 s).

Each of ``livox-viz info``, ``presets`` and ``coverage`` runs in a fresh
interpreter (``python -m livox_viz``, wall clock to exit), interleaved with two
references in the same run: the bare interpreter, and the interpreter importing
numpy alone (which every command needs). Best of nine each: the machine is
shared and its speed drifts.
"""

from __future__ import annotations

import subprocess
import sys
import time

RUNS = 9
COMMANDS: dict[str, list[str]] = {
    "python -c pass": ["-c", "pass"],
    "python -c 'import numpy'": ["-c", "import numpy"],
    "livox-viz info": ["-m", "livox_viz", "info"],
    "livox-viz presets": ["-m", "livox_viz", "presets"],
    "livox-viz coverage": ["-m", "livox_viz", "coverage"],
}


def wall(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, *argv], check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    best = dict.fromkeys(COMMANDS, float("inf"))
    for _ in range(RUNS):
        for name, argv in COMMANDS.items():
            best[name] = min(best[name], wall(argv))
    numpy_s = best["python -c 'import numpy'"]
    print(f"start-up, fresh interpreter, best of {RUNS} interleaved runs:")
    for name, seconds in best.items():
        extra = "" if name.startswith("python") else (
            f"  = numpy's import + {(seconds - numpy_s) * 1e3:.0f} ms (target <= 500 ms in all)")
        print(f"  {name:<26} {seconds * 1e3:6.0f} ms{extra}")


if __name__ == "__main__":
    main()
