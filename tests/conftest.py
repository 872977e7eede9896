"""Shared fixtures: the default preset and small configurations."""

from __future__ import annotations

import faulthandler
import functools
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from livox_viz import SensorConfig, load_preset

SEED_JSON = {
    "SeqID": 0,
    "TypeID": 6,
    "TargetCopter": 1,
    "TargetMountType": 0,
    "DataWidth": 250,
    "DataHeight": 40,
    "DataCheckFreq": 10,
    "SendProtocol": [0, 127, 0, 0, 1, 9999, 0, 0],
    "CameraFOV": 70.432,
    "SensorPosXYZ": [0, 0, -0.3],
    "SensorAngEular": [0, 0, 0],
    "otherParams": [600, 2.956, 1.4, 1.18, 10, 5, 1, 0],
}


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the return model's, the Risley product's and the moving sensor's loops into numba's cache on the
    other core while the first tests run, as the window does (``python -m livox_viz.casting.warm``).

    In a fresh clone (CI's every run) their first compile, about two minutes of one core, otherwise lands inside
    whichever tests use them first, on the suite's one busy core. With a warm cache the child only loads them
    (seconds). ``LIVOX_VIZ_TESTS_NO_WARM=1`` leaves it out.
    """
    if os.environ.get("LIVOX_VIZ_TESTS_NO_WARM") or hasattr(session.config, "workerinput"):
        return  # with pytest-xdist, once for the run (its controller), not again in each worker
    session.config.stash[_WARMER] = subprocess.Popen(
        [sys.executable, "-m", "livox_viz.casting.warm", "--background", "datasheet", "risley", "motion"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def pytest_sessionfinish(session: pytest.Session) -> None:
    warmer = session.config.stash.get(_WARMER, None)
    if warmer is not None and warmer.poll() is None:
        warmer.terminate()
        warmer.wait()


_WARMER = pytest.StashKey[subprocess.Popen]()

#: Seconds past a test's own limit (pytest-timeout's ``timeout``, or its ``timeout`` mark) after which the hang
#: guard ends the test's process: pytest-timeout's signal cannot end a test stuck in compiled code that holds the
#: GIL (a Qt or VTK call that never returns, a numba loop), whose Python signal handler never runs.
HANG_GUARD_MARGIN = 30.0
_GUARD_FD = pytest.StashKey[int]()


def _signals_as_a_terminal_gives_them() -> None:
    """SIGINT, SIGHUP and SIGTERM handled as in a terminal's foreground, however the suite was started.

    An ignored signal stays ignored through fork and exec: under ``nohup`` (SIGHUP) or as a background job of a
    script (``make test &``: SIGINT) every child the tests start ignored the signal the test sent it, and 17 tests
    of signals failed, the suite's result depending on how it was launched.
    """
    import signal

    for number in ("SIGINT", "SIGHUP", "SIGTERM"):
        if hasattr(signal, number) and signal.getsignal(getattr(signal, number)) == signal.SIG_IGN:
            signal.signal(getattr(signal, number),
                          signal.default_int_handler if number == "SIGINT" else signal.SIG_DFL)


def pytest_configure(config: pytest.Config) -> None:
    _signals_as_a_terminal_gives_them()
    # The real standard error, duplicated while pytest's capture is suspended (as its own faulthandler does): the
    # guard's dump must reach the log, not a capture file that dies with the process.
    config.stash[_GUARD_FD] = os.dup(sys.__stderr__.fileno() if sys.__stderr__ is not None else 2)


#: Seconds this process may take to exit once its tests are done, before the hang guard ends it with every
#: thread's stack: at exit, multiprocessing joins the children a test left (a pool worker blocked on a lock kept a
#: worker of the suite, and so the run, waiting for ever).
EXIT_LIMIT = 120.0


def pytest_unconfigure(config: pytest.Config) -> None:
    faulthandler.cancel_dump_traceback_later()
    if _GUARD_FD in config.stash:
        # The descriptor stays open for the watchdog; the process's end closes it.
        faulthandler.dump_traceback_later(EXIT_LIMIT, exit=True, file=config.stash[_GUARD_FD])


def hang_limit(item: pytest.Item) -> float:
    """Seconds after which the hang guard ends ``item``'s process: its pytest-timeout limit plus the margin."""
    marker = item.get_closest_marker("timeout")
    limit = None
    if marker is not None:
        limit = marker.kwargs.get("timeout", marker.args[0] if marker.args else None)
    if limit is None:
        limit = item.config.getini("timeout") or 0
    return float(limit) + HANG_GUARD_MARGIN


def _arm_hang_guard(item: pytest.Item) -> None:
    """From now, ``hang_limit(item)`` seconds without :func:`faulthandler.cancel_dump_traceback_later` dump every
    thread's stack to the log and end this process (exit 1): a C watchdog thread that needs no GIL does it. Under
    pytest-xdist the controller then reports the test as failed ("worker crashed while running ...") and starts
    another worker, so the run goes on."""
    faulthandler.dump_traceback_later(hang_limit(item), exit=True, file=item.config.stash[_GUARD_FD])


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    _arm_hang_guard(item)
    try:
        return (yield)
    finally:
        faulthandler.cancel_dump_traceback_later()


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None):
    # pytest's faulthandler plugin cancels any watchdog when a test fails (pytest_exception_interact): the
    # teardown after a failure is guarded again, with a whole limit of its own.
    _arm_hang_guard(item)
    return (yield)


#: The test modules whose results are the model's numbers (patterns, tracks, fits, casting, returns, motion, the
#: wire's and the files' encodings): marked ``arithmetic``, they are what the other-CPU pass runs again
#: (``make test-other-cpu``), since only arithmetic changes with a BLAS kernel or a CPU's instructions. The window,
#: the command line's messages, signals, batches and static checks do not, and run once.
ARITHMETIC_MODULES = frozenset({
    "test_bag_conformance", "test_beam", "test_codec_directions_metrics", "test_config", "test_config_v3",
    "test_deliberate_bugs", "test_edges", "test_fit", "test_fit_inputs", "test_fit_tables", "test_materials",
    "test_motion", "test_motion_cli", "test_one_motion", "test_other_cpu", "test_pattern", "test_ray_kernels",
    "test_raycast_parts", "test_return_loops", "test_returns", "test_returns_files", "test_rflysim", "test_risley",
    "test_risley_frames", "test_rosbag", "test_scan", "test_scan_steps", "test_scan_workers", "test_speed",
    "test_terrain_broad_phase", "test_track", "test_wire_v3", "test_blind_zone_and_outline",
})


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        module = getattr(item, "module", None)
        if module is not None and module.__name__.rsplit(".", 1)[-1] in ARITHMETIC_MODULES:
            item.add_marker(pytest.mark.arithmetic)


@pytest.fixture(autouse=True)
def _environment_kept():
    """Each test leaves ``os.environ`` as it found it: a library that set variables in this process (Dask's
    nannies set one BLAS thread and an eager malloc trim as they spawn workers) slowed every later test's child
    processes four times."""
    saved = dict(os.environ)
    yield
    if dict(os.environ) != saved:
        os.environ.clear()
        os.environ.update(saved)


@pytest.fixture
def mid70() -> SensorConfig:
    """The default preset."""
    return load_preset("livox_mid70")


@pytest.fixture
def seed_json() -> dict:
    """A fresh copy of the document's seed configuration."""
    return json.loads(json.dumps(SEED_JSON))


@pytest.fixture
def user_presets(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty user preset folder, so tests never touch the real one."""
    folder = tmp_path / "user-presets"
    folder.mkdir()
    monkeypatch.setenv("LIVOX_VIZ_PRESETS", str(folder))
    return folder


def small_config(**changes: object) -> SensorConfig:
    """A quick configuration: W=20, H=8, F=10, N8=3, Nf=2, with ``changes`` applied."""
    values = dict(data_width=20, data_height=8, data_check_freq=10,
                  other_params=(100.0, 2.0, 1.4, 1.18, 3.0, 2.0, 1.0, 0.0))
    values.update(changes)
    return SensorConfig(**values)  # type: ignore[arg-type]


def free_udp_port() -> int:
    """A UDP port on the loopback that nothing uses right now."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


#: The UDP ports a :class:`UdpReceiver` of this process holds right now (its ``__init__`` bound it, its ``close``
#: not yet run), with a condition to wait on: how tests know a listener in a thread is ready.
_BOUND_PORTS: set[int] = set()
_BOUND_CHANGED = threading.Condition()


def _receivers_say_their_ports() -> None:
    """Make every :class:`UdpReceiver` note its port in ``_BOUND_PORTS`` once bound, and drop it once closed."""
    from livox_viz.wire.transport import UdpReceiver

    bind, close = UdpReceiver.__init__, UdpReceiver.close

    @functools.wraps(bind)
    def bound(self, *args, **kwargs) -> None:
        bind(self, *args, **kwargs)
        with _BOUND_CHANGED:
            _BOUND_PORTS.add(self.port)
            _BOUND_CHANGED.notify_all()

    @functools.wraps(close)
    def closed(self) -> None:
        with _BOUND_CHANGED:
            _BOUND_PORTS.discard(self.port)
        close(self)

    UdpReceiver.__init__, UdpReceiver.close = bound, closed  # type: ignore[method-assign]


_receivers_say_their_ports()


def wait_until_bound(port: int, alive, seconds: float = 60.0) -> None:
    """Return once a receiver of this process (a listener in a thread) holds UDP ``port``.

    A fixed sleep lost the first frames on a loaded CI machine, where the listener's imports took longer than
    the sleep. Probing the port by binding it raced the listener: a probe holding the port for a moment made the
    listener's own bind fail as "in use" (once in CI). ``alive()`` says whether the listener still runs, so a
    listener that failed ends the wait.
    """
    deadline = time.monotonic() + seconds
    with _BOUND_CHANGED:
        while port not in _BOUND_PORTS:
            if not alive():
                raise AssertionError(f"the listener ended before it held UDP port {port}")
            if time.monotonic() > deadline:
                raise AssertionError(f"nothing listened on UDP port {port} within {seconds:.0f} s")
            _BOUND_CHANGED.wait(0.05)


def start_listening(argv: list[str]):
    """Run ``livox-viz listen ARGV`` (with ``--port`` in it) in a thread, once it has bound; returns the thread."""
    from livox_viz.cli import main

    listener = threading.Thread(target=main, args=(["listen", *argv],))
    listener.start()
    wait_until_bound(int(argv[argv.index("--port") + 1]), listener.is_alive)
    return listener
