"""Blocks of memory handed out again once nobody holds them any more.

Filling a freshly allocated array of a frame's size costs more in page faults
than the arithmetic that fills it: glibc gives blocks of a few megabytes back
to the system on every free (or trims its heaps), so the next frame faults
every page in again, about 1.5 us a 4 KiB page on this machine. A scan hands
its frames' arrays to a caller that drops them a moment later, so
:class:`RecycledBlocks` keeps the last few blocks and hands one out again when
nothing outside the pool refers to it any more (no array, no view: a view
holds a reference to its base), so an array a caller still keeps is never
overwritten.
"""

from __future__ import annotations

import math
import sys
import threading
import weakref

import numpy as np

from livox_viz.core.portable import at_fork_in_child


def _unheld_refcount() -> int:
    """The reference count ``sys.getrefcount`` reports for a block only a pool's list holds."""
    pool = [np.empty(1)]
    for block in pool:
        return sys.getrefcount(block)
    raise AssertionError("unreachable")


_UNHELD = _unheld_refcount()


class RecycledBlocks:
    """Byte blocks for arrays that callers keep for a while and then drop; safe across threads.

    Parameters
    ----------
    keep : int
        Blocks kept for reuse at most (the oldest is let go beyond them).
    slack : float
        A block is reused for a request only when it is at most this much larger (so a small request never pins
        a large block for as long as its caller keeps it).
    """

    def __init__(self, keep: int = 8, slack: float = 1.25) -> None:
        self.keep = keep
        self.slack = slack
        self._blocks: list[np.ndarray] = []
        self._lock = threading.Lock()
        _POOLS.add(self)

    def get(self, nbytes: int) -> np.ndarray:
        """A ``(nbytes,)`` uint8 array (contents undefined): a kept block's head when one is free, else new.

        Parameters
        ----------
        nbytes : int
            Bytes wanted.

        Returns
        -------
        block : (nbytes,) uint8
            A view of the block handed out (its ``base`` is the block).
        """
        with self._lock:
            for block in self._blocks:
                if nbytes <= block.shape[0] <= nbytes * self.slack and sys.getrefcount(block) <= _UNHELD:
                    return block[:nbytes]  # the view holds the block before the lock is let go
            block = np.empty(max(nbytes, 1), dtype=np.uint8)
            self._blocks.append(block)
            if len(self._blocks) > self.keep:
                self._blocks.pop(0)
            return block[:nbytes]


_POOLS: weakref.WeakSet[RecycledBlocks] = weakref.WeakSet()


def _fresh_locks() -> None:
    """In a forked child: a lock another thread of the parent held at the fork would stay taken for ever."""
    for pool in list(_POOLS):
        pool._lock = threading.Lock()


at_fork_in_child(_fresh_locks)


def carve(block: np.ndarray, layout: list[tuple[str, tuple[int, ...], type]]) -> dict[str, np.ndarray]:
    """Arrays laid one after another in ``block``, each starting on an 8-byte boundary.

    Parameters
    ----------
    block : (nbytes,) uint8
        At least :func:`carved_size` of ``layout`` bytes.
    layout : list of (name, shape, dtype)

    Returns
    -------
    dict of name -> array
        Views of ``block``.
    """
    arrays = {}
    offset = 0
    for name, shape, dtype in layout:
        # One constructor an array, not a slice, a view and a reshape: 12 to 21 us a run of twelve arrays.
        arrays[name] = made = np.ndarray(shape, dtype, block, offset)
        offset += -(-made.nbytes // 8) * 8
    return arrays


def carved_size(layout: list[tuple[str, tuple[int, ...], type]]) -> int:
    """Bytes :func:`carve` needs for ``layout``."""
    return sum(-(-math.prod(shape) * np.dtype(dtype).itemsize // 8) * 8 for _, shape, dtype in layout)
