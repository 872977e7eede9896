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


def test_a_test_process_killed_outright_leaves_no_x_server_behind() -> None:
    """A worker killed by a signal never runs its ``finally``: its private Xvfb was left running for good (three
    of them after runs stopped by hand). The server now ends with the process that started it, however it ends."""
    import os
    import signal

    from .xserver import x_tools

    x_tools()
    with subprocess.Popen([sys.executable, "-c", textwrap.dedent("""
        import sys, time
        sys.path.insert(0, sys.argv[1])
        from tests.xserver import private_display
        with private_display() as display:
            print(display, flush=True)
            time.sleep(120)
        """), str(ROOT)], stdout=subprocess.PIPE, text=True) as child:
        server = 0
        try:
            assert child.stdout is not None and child.stdout.readline().startswith(":")
            children = Path(f"/proc/{child.pid}/task/{child.pid}/children").read_text().split()
            assert len(children) == 1, children
            server = int(children[0])
            assert "Xvfb" in Path(f"/proc/{server}/cmdline").read_text()
            child.send_signal(signal.SIGKILL)
            child.wait(10)
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline and _running(server):
                time.sleep(0.05)
            assert not _running(server), f"Xvfb {server} outlived the process that started it"
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
            if server and _running(server):  # the bug back: do not leave its server running
                os.kill(server, signal.SIGKILL)


def _running(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie waiting for its new parent to reap it is not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"
