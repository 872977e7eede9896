"""Whether a window can be opened here: light (no Qt, no VTK), so the command line asks before loading them."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path

#: Seconds given to an X server on this machine (``DISPLAY=:0``) to answer: it is there, only slow when the machine
#: is busy. At 3 s, two busy processes on two cores sent the window off-screen, without a window, 2 starts in 30.
LOCAL_WAIT_S = 30.0
#: Seconds given to an X server elsewhere (``DISPLAY=host:10``): a forwarded display whose tunnel is gone may
#: accept the connection and never answer.
REMOTE_WAIT_S = 10.0
#: Seconds without an answer after which ``waiting`` is told (the user sees why nothing opens yet).
SLOW_NOTICE_S = 2.0
#: Seconds between two asks of a local X server that refused us.
REFUSED_RETRY_S = 0.5


def display_problem(environ: Mapping[str, str] | None = None, timeout: float | None = None,
                    waiting: Callable[[str], None] | None = None) -> str | None:
    """Why no window can be opened here, in words; None when one can.

    The window on Linux is an X11 window (Qt's xcb platform, which VTK draws into): it needs a ``DISPLAY``
    whose X server answers (a Wayland session offers one through XWayland). The server is asked once, as Qt
    would ask it, in a thread given ``timeout`` seconds.

    Parameters
    ----------
    environ : mapping, optional
        The environment to read (default ``os.environ``).
    timeout : float, optional
        Seconds to wait for the X server (default :data:`LOCAL_WAIT_S` for a display of this machine,
        :data:`REMOTE_WAIT_S` for one of another host).
    waiting : callable, optional
        Told in words, once, when the server has not answered within :data:`SLOW_NOTICE_S`.
    """
    environ = os.environ if environ is None else environ
    if sys.platform in ("win32", "darwin"):
        return None  # Qt opens native windows there
    display = environ.get("DISPLAY", "")
    if not display:
        wayland = environ.get("WAYLAND_DISPLAY")
        if wayland:
            return (f"only WAYLAND_DISPLAY={wayland} is set, and the window needs X11: run it under XWayland "
                    "with DISPLAY set")
        return "DISPLAY is not set"
    if timeout is None:
        timeout = LOCAL_WAIT_S if _local_socket(display) is not None else REMOTE_WAIT_S
    return _x11_problem(display, timeout, waiting)


def _x11_problem(display: str, timeout: float, waiting: Callable[[str], None] | None) -> str | None:
    name = ctypes.util.find_library("X11")
    if name is None:
        return None  # cannot ask: let Qt try
    try:
        xlib = ctypes.CDLL(name)
    except OSError:
        return None
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    answer: list[bool] = []
    deadline = time.monotonic() + timeout
    # A server of this machine whose socket is there, refusing us: asked again until the deadline. Under load a
    # running Xvfb refused one connection and took the next (the window went off-screen, 1 start in 30 and once
    # in CI); a display with no server fails at once, as before.
    socket_path = _local_socket(display)
    retry = socket_path is not None and socket_path.exists()

    def ask() -> None:
        while True:
            connection = xlib.XOpenDisplay(display.encode())
            if connection:
                xlib.XCloseDisplay(connection)
            if connection or not retry or time.monotonic() + REFUSED_RETRY_S > deadline:
                answer.append(bool(connection))
                return
            time.sleep(REFUSED_RETRY_S)

    asking = threading.Thread(target=ask, daemon=True, name="x11-display-check")
    asking.start()
    asking.join(min(SLOW_NOTICE_S, timeout))
    if not answer and timeout > SLOW_NOTICE_S:
        if waiting is not None:
            waiting(f"the X server of the display {display} has not answered in {SLOW_NOTICE_S:g} s: waiting up to "
                    f"{timeout:g} s")
        asking.join(timeout - SLOW_NOTICE_S)
    if not answer:
        return f"cannot open the display {display}: its X server did not answer within {timeout:g} s"
    if not answer[0]:
        return f"cannot open the display {display}: no X server answers there, or it refused us"
    return None


def _local_socket(display: str) -> Path | None:
    """The socket of a display of this machine (``:0``, ``unix:1.0``); None for another host's."""
    host, _, rest = display.partition(":")
    number = rest.split(".")[0]
    if host not in ("", "unix") or not number.isdigit():
        return None
    return Path(f"/tmp/.X11-unix/X{number}")
