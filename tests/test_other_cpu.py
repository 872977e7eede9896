"""The guard against tests that hold only by one machine's rounding (issue 36): ``scripts/other_cpu.py``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
import other_cpu  # noqa: E402


@pytest.fixture(scope="module")
def families() -> tuple[str, str]:
    native = other_cpu.blas_family(dict(os.environ))
    forced = other_cpu.other_family(native)
    if forced is None:
        pytest.skip(f"no other OpenBLAS kernel family on this machine (native {native!r})")
    return native, forced


def test_the_guard_forces_another_kernel_family_that_openblas_takes(families: tuple[str, str]) -> None:
    native, forced = families
    assert forced.lower() != native.lower()
    assert other_cpu.blas_family({**os.environ, "OPENBLAS_CORETYPE": forced}).lower() == forced.lower()


def test_the_risley_stream_is_the_same_however_cut_under_another_kernel_family(families: tuple[str, str]) -> None:
    """The cut-invariance test, bit for bit, with OpenBLAS on the other family and numba for a generic CPU."""
    _, forced = families
    env = {**os.environ, "OPENBLAS_CORETYPE": forced, "NUMBA_CPU_NAME": "generic"}
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                             "tests/test_speed.py::test_risley_blocks_are_the_series_and_the_same_however_cut"],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "4 passed" in result.stdout
