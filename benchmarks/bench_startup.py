"""Start-up of the model-only commands (issue 19: <= 0.5 s).

Each of ``livox-viz info``, ``presets`` and ``coverage`` runs in a fresh
interpreter (``python -m livox_viz``, wall clock to exit), interleaved with two
references in the same run: the bare interpreter, and the interpreter importing
numpy alone (which every command needs). Best of nine each: the machine is
shared and its speed drifts.

As a user runs them, with the modules' bytecode already compiled (written to a
temporary ``PYTHONPYCACHEPREFIX``, so the tree stays clean), and, for
comparison, compiling every module from source on each start (what
``PYTHONDONTWRITEBYTECODE=1`` does, as on the development machine).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

RUNS = 9
COMMANDS: dict[str, list[str]] = {
    "python -c pass": ["-c", "pass"],
    "python -c 'import numpy'": ["-c", "import numpy"],
    "livox-viz info": ["-m", "livox_viz", "info"],
    "livox-viz presets": ["-m", "livox_viz", "presets"],
    "livox-viz coverage": ["-m", "livox_viz", "coverage"],
}


def wall(argv: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, *argv], check=True, capture_output=True, env=env)
    return time.perf_counter() - start


def measure(env: dict[str, str], title: str) -> None:
    for argv in COMMANDS.values():  # once first: the bytecode is written (when it may be)
        wall(argv, env)
    best = dict.fromkeys(COMMANDS, float("inf"))
    for _ in range(RUNS):
        for name, argv in COMMANDS.items():
            best[name] = min(best[name], wall(argv, env))
    numpy_s = best["python -c 'import numpy'"]
    print(f"start-up, fresh interpreter, {title}, best of {RUNS} interleaved runs:")
    for name, seconds in best.items():
        extra = "" if name.startswith("python") else (
            f"  = numpy's import + {(seconds - numpy_s) * 1e3:.0f} ms (target <= 500 ms in all)")
        print(f"  {name:<26} {seconds * 1e3:6.0f} ms{extra}")


def main() -> None:
    with tempfile.TemporaryDirectory() as cache:
        compiled = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        compiled["PYTHONPYCACHEPREFIX"] = cache
        measure(compiled, "bytecode compiled (as installed)")
    measure(dict(os.environ, PYTHONDONTWRITEBYTECODE="1"), "every module compiled from source each time")


if __name__ == "__main__":
    main()
