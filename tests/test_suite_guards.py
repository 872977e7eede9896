"""The suite's own guards (issue 43): a test that crashes its process or hangs in compiled code ends the run with a
failure that names it, in bounded time; it never leaves the run waiting until CI's limit."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _make_flags() -> list[str]:
    """The pytest-xdist options `make test` runs with (its XDIST line), with two workers."""
    line = next(line for line in (ROOT / "Makefile").read_text().splitlines() if line.startswith("XDIST :="))
    return line.split(":=", 1)[1].replace("$(TEST_WORKERS)", "2").split()


def test_a_crashed_worker_ends_the_run_with_a_failure_naming_its_test(tmp_path: Path) -> None:
    """CI's run hung for 90 minutes: a worker died of a segmentation fault, pytest-xdist's loadgroup scheduler gave
    the worker started in its place nothing to do, and every worker waited for ever. With `make test`'s options a
    crash ends the run at once, a failure naming the test (a run that goes on after a crash is what hung)."""
    (tmp_path / "test_crash.py").write_text(textwrap.dedent("""
        import os, signal
        import pytest

        pytestmark = pytest.mark.xdist_group("together")

        @pytest.mark.parametrize("k", range(6))
        def test_before(k):
            pass

        def test_that_crashes():
            os.kill(os.getpid(), signal.SIGSEGV)

        @pytest.mark.parametrize("k", range(6))
        def test_after(k):
            pass
        """))
    (tmp_path / "test_others.py").write_text("import pytest\n\n@pytest.mark.parametrize('k', range(20))\n"
                                             "def test_other(k):\n    pass\n")
    started = time.monotonic()
    run = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:randomly",
                          *_make_flags(), str(tmp_path)], cwd=tmp_path, capture_output=True, text=True, timeout=240)
    assert run.returncode == 1, run.stdout[-3000:] + run.stderr[-2000:]
    assert time.monotonic() - started < 120
    assert re.search(r"crashed while running '.*test_crash.py::test_that_crashes'", run.stdout), run.stdout[-3000:]
    assert re.search(r"worker gw\d crashed and worker restarting disabled", run.stdout)
    assert re.search(r"=+ 1 failed, \d+ passed[ ,]", run.stdout), run.stdout[-3000:]  # (", 3 warnings": CI's dash)
