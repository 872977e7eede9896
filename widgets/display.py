"""Whether a window can be opened here: light (no Qt, no VTK), so the command line asks before loading them."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import threading
from collections.abc import Mapping


def display_problem(environ: Mapping[str, str] | None = None, timeout: float = 3.0) -> str | None:
    """Why no window can be opened here, in words; None when one can.

    The window on Linux is an X11 window (Qt's xcb platform, which VTK draws into): it needs a ``DISPLAY``
    whose X server answers (a Wayland session offers one through XWayland). The server is asked once, as Qt
    would ask it, in a thread given ``timeout`` seconds (a forwarded display whose tunnel is gone may never
    answer).

    Parameters
    ----------
    environ : mapping, optional
        The environment to read (default ``os.environ``).
    timeout : float
        Seconds to wait for the X server.
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
    return _x11_problem(display, timeout)


def _x11_problem(display: str, timeout: float) -> str | None:
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

    def ask() -> None:
        connection = xlib.XOpenDisplay(display.encode())
        if connection:
            xlib.XCloseDisplay(connection)
        answer.append(bool(connection))

    asking = threading.Thread(target=ask, daemon=True, name="x11-display-check")
    asking.start()
    asking.join(timeout)
    if not answer:
        return f"cannot open the display {display}: its X server did not answer within {timeout:g} s"
    if not answer[0]:
        return f"cannot open the display {display}: no X server answers there, or it refused us"
    return None
