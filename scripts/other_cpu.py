"""Run the test suite as another CPU would: OpenBLAS on another kernel family, numba for a generic CPU.

A test that holds only because of one machine's rounding (a BLAS kernel's
order of operations, an FMA the compiler used) passes on the developer's
machine and fails on a user's (issue 36: six tests failed on an AMD EPYC).
This run makes CI such a user: OpenBLAS is forced to a kernel family other
than the one it picks here (``OPENBLAS_CORETYPE``), and numba compiles our
loops for a generic CPU (``NUMBA_CPU_NAME=generic``: no AVX, no FMA), so
floating-point results differ from the native run in the last bits wherever
they can. The suite must pass both ways.

Usage: ``python scripts/other_cpu.py [pytest arguments]`` (``make test-other-cpu``).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys

#: Families to force, in order of preference, by machine: the first that is not the native one and that this
#: CPU can run (Sandybridge needs AVX, Haswell AVX2 and FMA; Nehalem runs on any x86-64 of the last 15 years).
FAMILIES = {"x86_64": ("Sandybridge", "Haswell", "Nehalem"), "aarch64": ("ARMV8", "NEOVERSEN1")}
_NEEDS = {"Sandybridge": ("avx",), "Haswell": ("avx2", "fma"), "Nehalem": ("sse4_2",),
          "ARMV8": (), "NEOVERSEN1": ("asimddp",)}
_PROBE = ("import numpy\nfrom threadpoolctl import threadpool_info\n"
          "print(next((i.get('architecture') or '') for i in threadpool_info() if i['user_api'] == 'blas'))")


def blas_family(env: dict[str, str]) -> str:
    """The kernel family numpy's OpenBLAS uses under ``env`` (asked of a fresh interpreter)."""
    return subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux's /proc/cpuinfo; empty elsewhere)."""
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith(("flags", "Features")):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def other_family(native: str) -> str | None:
    """A kernel family other than ``native`` that this CPU runs, or None."""
    flags = cpu_flags()
    for family in FAMILIES.get(platform.machine(), ()):
        if family.lower() != native.lower() and all(flag in flags for flag in _NEEDS[family]):
            return family
    return None


def main(argv: list[str]) -> int:
    native = blas_family(dict(os.environ))
    family = other_family(native)
    if family is None:
        print(f"other_cpu: no other OpenBLAS kernel family to force on {platform.machine()} (native {native!r})",
              file=sys.stderr)
        return 1
    env = {**os.environ, "OPENBLAS_CORETYPE": family, "NUMBA_CPU_NAME": "generic"}
    forced = blas_family(env)
    if forced.lower() != family.lower():  # a guard that silently runs the native kernels guards nothing
        print(f"other_cpu: OPENBLAS_CORETYPE={family} was not taken (OpenBLAS reports {forced!r})", file=sys.stderr)
        return 1
    print(f"other_cpu: the suite with OpenBLAS's {family} kernels (native here: {native}) and numba for a generic "
          "CPU", flush=True)
    return subprocess.run([sys.executable, "-m", "pytest", *argv], env=env).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
