"""A private Xvfb server for the tests that open a real window."""

from __future__ import annotations

import os
import select
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest


def x_tools() -> tuple[str, str]:
    """The paths of Xvfb and xdotool; CI must have them (it installs them), elsewhere the test is skipped."""
    xvfb, xdotool = shutil.which("Xvfb"), shutil.which("xdotool")
    if not (xvfb and xdotool):
        if os.environ.get("CI"):
            pytest.fail("CI must install xvfb and xdotool (see .ci/run)")
        pytest.skip("Xvfb and xdotool are not installed")
    return xvfb, xdotool


def _ends_with_its_parent() -> None:
    """In the server's child, before exec: the kernel sends it SIGTERM when the process that started it ends,
    however it ends. A test worker killed by a signal (SIGTERM, SIGKILL) never reaches the ``finally`` below,
    and its Xvfb was left running for good."""
    import ctypes

    pr_set_pdeathsig = 1
    ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGTERM)


@contextmanager
def private_display(screen: str = "1280x800x24", timeout: float = 30.0) -> Iterator[str]:
    """Run an Xvfb on a display number it picks itself; yield its ``DISPLAY``.

    ``-displayfd`` lets the server take the first free number and say which: a number made from the process
    id collided with another suite's server on the same machine, and the window then went to a server that
    was shutting down.
    """
    xvfb, _ = x_tools()
    read_end, write_end = os.pipe()
    server = subprocess.Popen([xvfb, "-displayfd", str(write_end), "-screen", "0", screen, "-nolisten", "tcp"],
                              pass_fds=(write_end,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              preexec_fn=_ends_with_its_parent)
    os.close(write_end)
    try:
        number = b""
        deadline = time.monotonic() + timeout
        while not number.endswith(b"\n") and time.monotonic() < deadline:
            ready, _, _ = select.select([read_end], [], [], 0.2)
            if ready:
                chunk = os.read(read_end, 16)
                if not chunk:
                    break
                number += chunk
        assert number.strip().isdigit(), f"Xvfb did not start (exit status {server.poll()})"
        yield f":{int(number)}"
    finally:
        os.close(read_end)
        if server.poll() is None:
            server.terminate()
            try:
                server.wait(10)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def find_window(xdotool: str, env: dict[str, str], name: str, program: subprocess.Popen,
                timeout: float = 120.0) -> list[str]:
    """The ids of the visible windows whose title matches ``name``, searched until one shows or ``program`` ends.

    ``xdotool search --sync`` is not used: it ends at once, finding nothing, when a window it looks at is
    destroyed under it (BadWindow), and Qt makes and destroys windows as it starts. One CI run lost the
    real-window test to that race.
    """
    deadline = time.monotonic() + timeout
    while program.poll() is None and time.monotonic() < deadline:
        found = subprocess.run([xdotool, "search", "--onlyvisible", "--name", name], env=env, capture_output=True,
                               text=True, timeout=30).stdout.split()
        if found:
            return found
        time.sleep(0.3)
    return []
