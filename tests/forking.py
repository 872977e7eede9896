"""Waiting for a forked child without hanging the suite when the child hangs."""

from __future__ import annotations

import os
import time

import pytest


def child_exit_code(pid: int, seconds: float, what: str) -> int:
    """The exit code of the forked child ``pid``; killed and the test failed when it runs longer than ``seconds``.

    Parameters
    ----------
    pid : int
        The child, from ``os.fork()``.
    seconds : float
        How long it may take.
    what : str
        What the child does, for the failure message.
    """
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        time.sleep(0.02)
    os.kill(pid, 9)
    os.waitpid(pid, 0)
    pytest.fail(f"the forked child did not finish within {seconds:g} s: {what}")
