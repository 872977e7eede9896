"""Python's cyclic garbage collected on the window's thread only, while the window is open.

Python collects cycles in whichever thread happens to allocate when a generation's threshold is passed. The
window's background threads (the compiled loops' loader, fits, exports) allocate a great deal, so VTK and Qt
objects of the window that had become garbage were destroyed there. A VTK object's C++ destructor releases its
OpenGL resources, and one destroyed in the loader's thread while the window's thread was rendering waited for
the GL context or the display the render held, while the render waited for the interpreter lock the collecting
thread held: the window froze for good (CI caught it: SIGTERM not taken in 20 s; the faulthandler dump showed
the loader's thread "Garbage-collecting" inside numba's import and the window's thread entering pyvistaqt's
make-current callback). Qt objects have the same rule: they are destroyed in their own thread.

As Qt applications written in Python do (Spyder's and GitFourchette's garbage collectors), automatic
collection is turned off while the window runs and the window's tick collects what the thresholds call for.
"""

from __future__ import annotations

import gc
from collections.abc import Iterable, Iterator
from contextlib import contextmanager


class MainThreadCollector:
    """Collect cycles only when :meth:`collect_due` is called (from the window's thread), while started."""

    def __init__(self) -> None:
        self._was_enabled: bool | None = None

    def start(self) -> None:
        """Turn automatic collection off (remembering whether it was on)."""
        if self._was_enabled is None:
            self._was_enabled = gc.isenabled()
            gc.disable()

    def collect_due(self) -> int:
        """Collect the generations whose thresholds are passed, as the interpreter would have; the objects found
        unreachable (0 when none was due)."""
        if self._was_enabled is None:
            return 0
        counts, thresholds = gc.get_count(), gc.get_threshold()
        if thresholds[0] == 0 or counts[0] <= thresholds[0]:  # a threshold of 0: the user turned collection off
            return 0
        generation = 0
        while generation < 2 and counts[generation + 1] > thresholds[generation + 1]:
            generation += 1
        return gc.collect(generation)

    def stop(self) -> None:
        """Give automatic collection back as it was before :meth:`start`."""
        if self._was_enabled:
            gc.enable()
        self._was_enabled = None


def give_back_free_memory() -> bool:
    """Hand the heap's free pages back to the system (glibc's ``malloc_trim``); False where there is none.

    A preset, a scene or a fit frees arrays of hundreds of megabytes, but glibc keeps the freed pages of its
    arenas for the process: the window's memory grew in steps with each one and was never given back (issue 45:
    787 MiB to 1,594 MiB in 28 minutes). Trimmed after each restart, 150-190 MiB came back each time in a
    cycle of every preset and scene. Windows' and macOS's allocators give pages back themselves.
    """
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return False
    try:
        trim = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):  # another C library (musl) has none
        return False
    trim.argtypes = [ctypes.c_size_t]
    trim(0)
    return True


def release_gl_wrappers(interactors: Iterable[object]) -> None:
    """Let go of the Python wrappers pyvistaqt's closed views keep of their GL context and its surface.

    After ``close`` (the render window finalized) a view still held a wrapper of its ``QOpenGLContext`` and of the
    context's ``QSurface``. A surface is no QObject: Shiboken never learns that Qt destroyed it, and its wrapper
    stays registered at that address. A full test run then had ``QMenuBar.addMenu`` return a ``QSurface`` (a new
    menu made where a closed window's surface had been, handed back as the stale wrapper); the same mix-up, a
    wrapper freed under a live object at that address, is how Shiboken's ``releaseWrapper`` can crash. pyvistaqt
    itself forgets them only when the context says it is going (``_cleanup_context``), which a window torn down
    from its top does not reach.
    """
    for interactor in interactors:
        forget = getattr(interactor, "_forget_context", None)
        if forget is not None:
            forget()


def destroy_widget_tree(widget: object) -> None:
    """Destroy a Qt widget and all its children now, Python's automatic collection off meanwhile.

    A full test run died (a segmentation fault in Shiboken's ``releaseWrapper``) while Qt destroyed a closed
    window's widget tree: each child's destructor calls back into Python, an allocation there can start a
    collection in the middle of the tree's destruction, and a cycle of wrappers collected then (a row and the
    lambda its slider calls) leaves a child that C++ destroys next with a wrapper already freed (KLayout's Qt
    binding met the same, its issue 1054). Nothing is collected until the whole tree is gone.
    """
    import shiboken6

    with collection_paused():
        if shiboken6.isValid(widget):
            # Closed first (a no-op for a window closed already): a main window lets go of its views' GL there
            # (:func:`release_gl_wrappers`), while the context is still alive.
            widget.close()
            shiboken6.delete(widget)


@contextmanager
def collection_paused() -> Iterator[None]:
    """Python's automatic collection off inside the block, given back as it was after it."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
