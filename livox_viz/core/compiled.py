"""numba's ``njit`` as every compiled loop of the project takes it: no GIL, cached beside its module.

numba is imported on the first call, so a module whose loops are never run does not load it (model-only
commands start without it).
"""

from __future__ import annotations

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
