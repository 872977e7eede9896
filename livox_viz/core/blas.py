"""One BLAS thread for the duration of a call, then the user's setting back.

numpy's OpenBLAS splits a product over every core once it is large enough,
and its threads then spin waiting for work: on the 2-core development machine
the Risley stream ran 10 x slower with two threads than with one, and a
slider's first frame took 287 ms instead of 120 ms (issue 19). Setting
``OPENBLAS_NUM_THREADS`` at import would change every other library's products
in the user's process too, so the limit is scoped instead: :func:`one_blas_thread`
pins the BLAS libraries numpy loaded (found once through threadpoolctl) to one
thread on entry and restores their own count on exit. Nested and concurrent
holders share one pin; the last to leave restores.

The count is process-wide: while a holder is inside, a product another thread
of the same process starts also gets one thread. The pinned sections are short
(one chunk of a pattern stream). The OpenBLAS numpy ships (0.3.31) takes a
count set from the main thread, where the streams run; from another thread,
once the main thread has set one, it keeps its count, so a pin there does not
apply, and the user's count is kept all the same.

A pin is taken per chunk, so its cost counts: threadpoolctl's calls cost 0.7 us
each (a pin and its release 5-7 us, a sixth of a Risley frame's product). For a
pthreads OpenBLAS the pin calls its two C functions directly (found once
through threadpoolctl; 0.2 us each), on the thread threadpoolctl lets control
it; any other library, or another thread, goes through threadpoolctl.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from typing import Any

_lock = threading.Lock()
_holders = 0
_saved: list[tuple[Callable[[int], Any], int]] = []
_libraries: list[Any] | None = None
#: Per library: its thread count's getter and setter (threadpoolctl's, or OpenBLAS's own C functions).
_handles: list[tuple[Any, Callable[[], int], Callable[[int], Any], bool]] | None = None


#: Whether scipy.linalg (which brings its own OpenBLAS) was loaded when the libraries were looked up.
_saw_scipy = False


def _blas_libraries() -> list[Any]:
    """threadpoolctl's controllers of the BLAS libraries loaded now (numpy's is loaded).

    Looked up once, and once more when scipy.linalg has been imported since: scipy's wheels carry their own
    OpenBLAS, loaded only with it, whose two spinning threads made each small Cholesky of a fit take 90 ms
    instead of microseconds on the loaded 2-core machine.
    """
    global _libraries, _handles, _saw_scipy
    scipy_loaded = "scipy.linalg" in sys.modules
    if _libraries is None or (scipy_loaded and not _saw_scipy):
        import numpy  # noqa: F401  (its BLAS must be loaded before the lookup)
        from threadpoolctl import ThreadpoolController

        _libraries = list(ThreadpoolController().select(user_api="blas").lib_controllers)
        _handles = None
        _saw_scipy = scipy_loaded
    return _libraries


def _library_handles() -> list[tuple[Any, Callable[[], int], Callable[[int], Any], bool]]:
    """``(controller, get, set, direct)`` per library; ``direct`` when ``get``/``set`` are OpenBLAS's C functions.

    Direct only for a pthreads OpenBLAS, whose count is one process-wide number (with OpenMP the count is
    per thread, which threadpoolctl handles); threadpoolctl's private symbol lookup may go away, so anything
    unexpected falls back to its public calls.
    """
    global _handles
    libraries = _blas_libraries()  # first: a new lookup drops the handles
    if _handles is None:
        handles = []
        for library in libraries:
            getter = setter = None
            if getattr(library, "internal_api", "") == "openblas" and getattr(library, "threading_layer",
                                                                              "") == "pthreads":
                symbol = getattr(library, "_get_symbol", None)
                if symbol is not None:
                    getter, setter = symbol("openblas_get_num_threads"), symbol("openblas_set_num_threads")
            if getter is None or setter is None:
                handles.append((library, library.get_num_threads, library.set_num_threads, False))
            else:
                handles.append((library, getter, setter, True))
        _handles = handles
    return _handles


def _may_set_directly(library: Any) -> bool:
    """Whether this thread is the one threadpoolctl lets set ``library``'s count (claimed through it if free)."""
    state = getattr(type(library), "_SHARED_STATE", None)
    if state is None:
        return False
    controlling, current = state.controlling_thread, threading.current_thread()
    if controlling is current:  # the usual answer, asked first: is_alive costs as much as a pin's C call
        return True
    if controlling is None or not controlling.is_alive():
        library.set_num_threads(library.get_num_threads())  # threadpoolctl hands control to this thread
        controlling = state.controlling_thread
    return controlling is current


class _OneBlasThread:
    """The context manager :func:`one_blas_thread` returns (a class: a generator-based one costs a microsecond)."""

    def __enter__(self) -> None:
        global _holders
        with _lock:
            if _holders == 0:
                for library, getter, setter, direct in _library_handles():
                    if direct and not _may_set_directly(library):
                        getter, setter = library.get_num_threads, library.set_num_threads
                    threads = getter()
                    if threads != 1:
                        setter(1)
                        _saved.append((setter, threads))
            _holders += 1

    def __exit__(self, *exc: object) -> None:
        global _holders
        with _lock:
            _holders -= 1
            if _holders == 0:
                for setter, threads in _saved:
                    setter(threads)
                _saved.clear()


_ONE_BLAS_THREAD = _OneBlasThread()


def one_blas_thread() -> _OneBlasThread:
    """A context manager: its body runs with numpy's BLAS on one thread (3-4 us to enter and leave; nested or
    concurrent holders cost a lock each)."""
    return _ONE_BLAS_THREAD


def blas_threads() -> list[int]:
    """Each BLAS library's thread count as it stands now: numpy's, and scipy's once scipy.linalg is imported."""
    return [library.get_num_threads() for library in _blas_libraries()]
