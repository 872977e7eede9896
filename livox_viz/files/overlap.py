"""Writing beside scanning: each file's frames are written on a thread of its own while the next ones are cast.

A scan's frames come from worker threads that release the interpreter (Embree,
the compiled loops); a writer's work is mostly the same (numpy, the compiled
text loop, the kernel's file writes). Written in the scan's own thread, every
frame's writing stopped the scan; handed to a :class:`WriterThread`, it runs
while the next frames are cast. The frames waiting are bounded (their points, and
their number), so memory stays flat when the disk is slower than the scan: the scan then
waits for the writer. Each writer gets the same frames in the same order as it
would in the scan's thread, so its file is the same, byte for byte.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Sequence
from types import TracebackType
from typing import Any, Protocol

#: Points that may wait for a writer before the scan waits for it (a few batches of frames; with their arrays about
#: 40 MB): enough to smooth out a writer's uneven pace, and what a slower writer costs in memory at most.
WAITING_POINTS = 250_000
#: Frames that may wait for a writer, whatever their points: a frame's arrays and record cost a few kilobytes even
#: when it holds no point, and a 1 x 1 x 1000 Hz configuration's frames (most of them empty) queued without end
#: behind a writer bounded by points alone (issue 47: 1.16 GB after 741,786 frames).
WAITING_FRAMES = 256


class FrameSink(Protocol):
    """What takes frames: a point-cloud writer, a bag."""

    def write(self, frame: Any) -> None: ...


class WriterThread:
    """Calls ``sink.write(frame)`` for every frame handed over, in order, on a thread of its own.

    Parameters
    ----------
    sink : FrameSink
        Its :meth:`write` runs on the thread; opening and closing it stay the caller's.
    name : str
        The thread's name.
    waiting_points : int
        Points handed over and not yet written at most; :meth:`write` waits beyond them.
    waiting_frames : int
        Frames handed over and not yet written at most, likewise.

    A failure of ``sink.write`` ends the thread; the error is raised in the caller's thread by the next
    :meth:`write` or by :meth:`finish`.
    """

    def __init__(self, sink: FrameSink, name: str = "writer", waiting_points: int = WAITING_POINTS,
                 waiting_frames: int = WAITING_FRAMES) -> None:
        self.sink = sink
        self.waiting_points = waiting_points
        self.waiting_frames = waiting_frames
        self._frames: deque = deque()
        self._points = 0
        self._error: BaseException | None = None
        self._ending = False
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._run, name=f"livox-viz-{name}", daemon=True)
        self._thread.start()

    def write(self, frame: Any) -> None:
        """Hand a frame over (waiting while too many points wait); raises the writer's error, if it failed."""
        with self._changed:
            while self._error is None and self._frames and (self._points + len(frame) > self.waiting_points
                                                             or len(self._frames) >= self.waiting_frames):
                self._changed.wait()
            if self._error is not None:
                raise self._error
            if self._ending:
                raise RuntimeError("the writer thread has finished")
            self._frames.append(frame)
            self._points += len(frame)
            self._changed.notify_all()

    def _run(self) -> None:
        while True:
            with self._changed:
                while not self._frames and not self._ending:
                    self._changed.wait()
                if not self._frames:
                    return
                frame = self._frames[0]
            try:
                self.sink.write(frame)
            except BaseException as error:  # raised again in the caller's thread
                with self._changed:
                    self._error = error
                    self._frames.clear()
                    self._points = 0
                    self._changed.notify_all()
                return
            with self._changed:
                if self._frames and self._frames[0] is frame:
                    self._frames.popleft()
                    self._points -= len(frame)
                self._changed.notify_all()

    def finish(self) -> None:
        """Wait until every frame handed over is written; raises the writer's error, if it failed."""
        self._end()
        if self._error is not None:
            raise self._error

    def discard(self) -> None:
        """Drop the frames not yet written and wait for the one being written (for giving up)."""
        with self._changed:
            self._frames.clear()
            self._points = 0
        self._end()

    def _end(self) -> None:
        with self._changed:
            self._ending = True
            self._changed.notify_all()
        self._thread.join()


class OverlappedWriting:
    """Frames handed to several sinks, each written on its own :class:`WriterThread`.

    Leaving the ``with`` block normally waits for every frame to be written and raises the first writer's
    error, if one failed (after every thread is done, so the caller gives up all of its files alike);
    leaving it by an exception drops what was not yet written.

    Parameters
    ----------
    sinks : sequence of FrameSink
    """

    def __init__(self, sinks: Sequence[FrameSink]) -> None:
        self.threads = [WriterThread(sink, name=f"writer-{k}") for k, sink in enumerate(sinks)]

    def write(self, frame: Any) -> None:
        """Hand ``frame`` to every sink; raises a writer's error, if one failed."""
        for thread in self.threads:
            thread.write(frame)

    def finish(self) -> None:
        """Wait for every writer; then raise the first one's error, if one failed."""
        failed: BaseException | None = None
        for thread in self.threads:
            try:
                thread.finish()
            except BaseException as error:
                failed = failed or error
        if failed is not None:
            raise failed

    def discard(self) -> None:
        """Drop what was not yet written, in every writer."""
        for thread in self.threads:
            thread.discard()

    def __enter__(self) -> OverlappedWriting:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, tb: TracebackType | None) -> None:
        if kind is None:
            self.finish()
        else:
            self.discard()
