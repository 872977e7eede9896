"""numba's ``njit`` as every compiled loop of the project takes it: no GIL, cached beside its module.

numba is imported on the first call, so a module whose loops are never run does not load it (model-only
commands start without it).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


def compile_nogil(function: Callable[..., Any], **options: Any) -> Callable[..., Any]:
    """``function`` compiled by ``numba.njit(nogil=True, cache=True, **options)``.

    Where numba can keep no cache (no writable folder beside the module nor in the user's cache: a read-only
    install and home), compiled in each process instead.
    """
    import numba

    try:
        return numba.njit(cache=True, nogil=True, **options)(function)
    except RuntimeError:
        return numba.njit(nogil=True, **options)(function)


class LazyKernels:
    """A module's compiled loops, each compiled (or loaded from numba's cache) on its first use, once across
    threads (frames are cast on worker threads: the first loop of each is compiled by one of them).

    ``kernels("name")`` (or ``kernels["name"]``) is the module's function ``_name`` compiled by
    :func:`compile_nogil`.

    Parameters
    ----------
    namespace : dict
        The module's globals: where the loops are found and where the compiled helpers replace the plain ones.
    helpers : tuple of str
        Small functions the loops call, compiled (``inline="always"``) into ``namespace`` before the first loop,
        so that the loops compile against them.
    options : callable, optional
        ``options(name)``: further numba options of the loop ``name``.
    prepare : callable, optional
        Called with ``namespace`` once, before the helpers (numba is imported by then).
    called : tuple of str
        Functions the loops or helpers call that are compiled as functions of their own, not inlined: a rare path
        behind a helper inlined at many places (each inlined copy is typed and compiled again).
    """

    def __init__(self, namespace: dict[str, Any], helpers: tuple[str, ...] = (),
                 options: Callable[[str], dict[str, Any]] | None = None,
                 prepare: Callable[[dict[str, Any]], None] | None = None, called: tuple[str, ...] = ()) -> None:
        self.namespace = namespace
        self.helpers = helpers
        self.called = called
        self.options = options
        self.prepare = prepare
        #: The loops compiled so far, by name.
        self.compiled: dict[str, Callable[..., Any]] = {}
        self._prepared = False
        self._lock = threading.Lock()

    def __call__(self, name: str) -> Callable[..., Any]:
        found = self.compiled.get(name)
        if found is not None:
            return found
        with self._lock:
            found = self.compiled.get(name)
            if found is None:
                if not self._prepared:
                    if self.prepare is not None:
                        self.prepare(self.namespace)
                    for helper in self.helpers:
                        self.namespace[helper] = compile_nogil(self.namespace[helper], inline="always")
                    for function in self.called:
                        self.namespace[function] = compile_nogil(self.namespace[function])
                    self._prepared = True
                options = self.options(name) if self.options is not None else {}
                found = self.compiled[name] = compile_nogil(self.namespace[f"_{name}"], **options)
        return found

    __getitem__ = __call__
