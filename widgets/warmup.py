"""The window's compiled loops, made ready off the UI thread: the window plays on while they load.

The stages a window needs now (the ideal caster, and what its first
configuration uses) are loaded by a worker thread once the window has drawn its
first frame: from numba's cache they take about a second, and the window starts
playing (a Risley pattern) or casting (the scene) when they are ready. Started
sooner, beside the imports of Qt and VTK, the thread only shared the GIL with
them: the first frame came 0.6-1.0 s later on 2 cores and the cast cloud no
sooner (bench_qt_window). The others (the Risley product, the datasheet return model,
the moving sensor's poses) are compiled by a child process on the other core
(``python -m livox_viz.casting.warm``): a first compile of the return model
takes a minute or two on 2 cores, and in this process it would hold the GIL
long enough to freeze the window (gaps of a second between frames, measured).
As the child reports each stage ready, the worker thread loads it from the
cache. Should the child fail (no writable cache, say), the worker compiles the
rest itself.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterable

from livox_viz.casting.warm import STAGES, warm

#: What the status bar adds while the datasheet loops compile: short, so that it stays whole beside a message in a
#: 1280 px window (the first time only: numba's cache has them after).
FIRST_COMPILE_NOTE = " (first time only)"

#: The order the child compiles the later stages in: the datasheet's first, one key (d) away and the slowest to
#: compile; a first-use trial pressed d at once and waited while the Risley loops, which a rosette does not use,
#: were compiled before it. A minute or two on 2 cores said "1-2 min" until a loaded machine made it 3.
LATER_ORDER: tuple[str, ...] = ("datasheet", "risley", "motion", "ideal")

#: The child compiles at a lower priority than the window (on 2 cores the window's frames come first): Windows sets
#: it as it starts the child, elsewhere the child lowers its own (``--background``).
_BELOW_NORMAL: dict = {}
if sys.platform == "win32":
    _BELOW_NORMAL["creationflags"] = subprocess.BELOW_NORMAL_PRIORITY_CLASS


class LoopWarmer:
    """Loads the compiled loops of :data:`~livox_viz.casting.warm.STAGES` in the background.

    Parameters
    ----------
    now : iterable of str
        Stages needed at once (loaded first, in this process).
    later : iterable of str
        Stages compiled by a child process, then loaded.
    """

    def __init__(self, now: Iterable[str], later: Iterable[str] = STAGES) -> None:
        self.now = [s for s in STAGES if s in set(now)]
        self.later = [s for s in LATER_ORDER if s in set(later) and s not in self.now]
        #: Stages whose loops this process has loaded.
        self.ready: set[str] = set()
        #: Stages being loaded or compiled now, and since when (monotonic seconds).
        self.working: dict[str, float] = {}
        #: Why a stage could not be made ready, by stage.
        self.failed: dict[str, str] = {}
        self._lock = threading.Lock()
        self._child: subprocess.Popen | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._run, daemon=True, name="livox-viz-warm")

    @property
    def started(self) -> bool:
        """Whether :meth:`start` was called."""
        return self._thread.ident is not None

    def start(self) -> LoopWarmer:
        """Start loading (returns at once; again: nothing more)."""
        if not self.started:
            self._thread.start()
        return self

    def is_ready(self, stages: Iterable[str]) -> bool:
        """Whether every one of ``stages`` is loaded."""
        with self._lock:
            return set(stages) <= self.ready

    def wait(self, stages: Iterable[str], timeout: float | None = None) -> bool:
        """Wait (for tests and renders) until ``stages`` are loaded or failed; whether they are loaded."""
        deadline = None if timeout is None else time.monotonic() + timeout
        wanted = set(stages)
        while True:
            with self._lock:
                if wanted <= self.ready:
                    return True
                if wanted & set(self.failed):
                    return False
            if deadline is not None and time.monotonic() > deadline:
                return False
            time.sleep(0.05)

    def describe(self) -> str:
        """What is being made ready now, in words ("" when nothing)."""
        with self._lock:
            working = dict(self.working)
        if not working:
            return ""
        stage, since = next(iter(working.items()))
        age = time.monotonic() - since
        first = FIRST_COMPILE_NOTE if stage == "datasheet" and age > 8 else ""
        return f"preparing the {stage} loops, {age:.0f} s{first}"

    def close(self) -> None:
        """Stop the child process (the thread is a daemon and ends with the program)."""
        self._closed = True
        child = self._child
        if child is not None and child.poll() is None:
            child.terminate()
            try:
                child.wait(5)
            except subprocess.TimeoutExpired:
                child.kill()

    # The worker thread --------------------------------------------------------------------------
    def _load(self, stage: str) -> None:
        with self._lock:
            self.working[stage] = time.monotonic()
        try:
            warm(stage)
        except Exception as exc:  # said in the window; the stage stays unavailable
            with self._lock:
                self.failed[stage] = f"{type(exc).__name__}: {exc}"
        else:
            with self._lock:
                self.ready.add(stage)
        finally:
            with self._lock:
                self.working.pop(stage, None)

    def _run(self) -> None:
        for stage in self.now:
            self._load(stage)
        pending = list(self.later)
        if not pending or self._closed:
            return
        with self._lock:
            for stage in pending:
                self.working.setdefault(stage, time.monotonic())
        try:
            # Its warnings go to a file, not a pipe nobody reads (a full pipe would stop the child).
            with tempfile.TemporaryFile() as errors:
                command = [sys.executable, "-m", "livox_viz.casting.warm", "--background", *pending]
                self._child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors, text=True,
                                               **_BELOW_NORMAL)
                try:
                    for line in self._child.stdout:
                        words = line.split()
                        if len(words) >= 2 and words[0] == "ready" and words[1] in pending and not self._closed:
                            pending.remove(words[1])
                            with self._lock:
                                self.working.pop(words[1], None)
                                if pending:
                                    # The child makes them one after another: the next is begun now ("preparing the
                                    # motion loops, 57 s" counted the datasheet's minute before it).
                                    self.working[pending[0]] = time.monotonic()
                            self._load(words[1])
                finally:
                    self._child.stdout.close()  # closed here, not by the collector whenever (a ResourceWarning)
                self._child.wait()
        except OSError:
            pass
        for stage in pending:  # the child could not make them: compile here (slower for the window, but working)
            if self._closed:
                return
            with self._lock:
                self.working.pop(stage, None)
            self._load(stage)
