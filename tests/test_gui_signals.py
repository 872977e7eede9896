"""The window and its command under signals, without a usable display, and its charts' axes (issue 15)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from livox_viz.widgets.app import LivoxVizApp  # noqa: E402
from livox_viz.widgets.session import Session  # noqa: E402

from livox_viz import load_preset  # noqa: E402
from livox_viz.cli import main  # noqa: E402
from livox_viz.scene.scenes import open_scene  # noqa: E402

from .xserver import find_window, private_display, x_tools  # noqa: E402

pytestmark = pytest.mark.xdist_group("x-server")  # one X server at a time (see tests/test_window.py)


@pytest.fixture(scope="module")
def x_display():
    """A private X server for this module's windows; yields its DISPLAY."""
    with private_display() as display:
        yield display


# 6. The window ends on SIGTERM, SIGINT and SIGHUP ------------------------------------------------
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_the_window_closes_on_a_signal(x_display: str, tmp_path: Path, signum: int) -> None:
    _, xdotool = x_tools()
    # PYTHONFAULTHANDLER: a window that does not end is aborted, and its threads' stacks are the failure's text.
    env = {**os.environ, "DISPLAY": x_display, "LIVOX_VIZ_PRESETS": str(tmp_path / "presets"),
           "PYTHONFAULTHANDLER": "1"}
    env.pop("WAYLAND_DISPLAY", None)
    gui = subprocess.Popen([sys.executable, "-m", "livox_viz", "gui", "--size", "640x400"], cwd=tmp_path,
                           env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        window = find_window(xdotool, env, "livox-viz", gui)
        if not window:
            # One run in about ten saw the child end with SIGABRT before its window showed: keep what it said.
            ended = gui.poll()
            said = gui.communicate(timeout=20)[1] if ended is not None else ""
            raise AssertionError(f"the livox-viz window did not appear (gui: {ended}); its stderr:\n{said[-4000:]}")
        time.sleep(1.0)
        assert gui.poll() is None
        gui.send_signal(signum)
        try:
            _, err = gui.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            gui.send_signal(signal.SIGABRT)
            _, err = gui.communicate(timeout=20)
            pytest.fail(f"the window did not end within 20 s of {signal.Signals(signum).name}; its threads:\n{err}")
    finally:
        if gui.poll() is None:
            gui.kill()
        gui.wait()
        # Closed here whatever happened: a window that never appeared left both pipes to the collector, whose
        # ResourceWarnings then failed an unrelated test (CI's second run this stop).
        gui.stdout.close()
        gui.stderr.close()
    assert gui.returncode == 128 + signum, err
    name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
    assert f"stopped by {name}" in err and "Traceback" not in err
    gone = subprocess.run([xdotool, "search", "--onlyvisible", "--name", "livox-viz"], env=env,
                          capture_output=True, text=True, timeout=20).stdout.split()
    assert gone == []


# 7. A DISPLAY that cannot be reached, or Wayland only ---------------------------------------------
def _unused_display() -> str:
    number = 600 + os.getpid() % 300
    while Path(f"/tmp/.X11-unix/X{number}").exists():
        number += 1
    return f":{number}"


@pytest.mark.parametrize("variables", [{"DISPLAY": "unused"}, {"WAYLAND_DISPLAY": "wayland-0"},
                                       {"DISPLAY": "localhost:4000"}])
def test_an_unusable_display_falls_back_to_offscreen(tmp_path: Path, variables: dict[str, str]) -> None:
    env = {key: value for key, value in os.environ.items() if key not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update({key: _unused_display() if value == "unused" else value for key, value in variables.items()})
    env["XDG_RUNTIME_DIR"] = str(tmp_path)  # no Wayland socket there either
    result = subprocess.run([sys.executable, "-m", "livox_viz", "gui", "--seconds", "0.05", "--size", "320x200",
                             "--scene", "open_field"], cwd=tmp_path, env=env, capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    assert "rendering the views off-screen" in result.stdout
    said = result.stdout.splitlines()[0]
    assert (env.get("DISPLAY") or "WAYLAND_DISPLAY") in said
    assert "vtk" not in result.stderr.lower() and "Traceback" not in result.stderr
    assert sorted(p.name for p in (tmp_path / "offscreen").iterdir()) == ["both.png", "pattern.png", "scene.png"]


def test_gui_listen_with_an_unreachable_display_is_a_one_line_error(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("DISPLAY", _unused_display())
    monkeypatch.chdir(tmp_path)
    assert main(["gui", "--listen", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot open the display" in err


def test_a_tcp_display_that_never_answers_is_given_up_quickly(tmp_path: Path) -> None:
    """A forwarded X display whose tunnel is gone: the port accepts nothing; the check must not hang."""
    from livox_viz.widgets.display import display_problem

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(1)  # accepts the connection, never answers the X handshake
        number = silent.getsockname()[1] - 6000  # X display N listens on TCP 6000 + N
        assert number >= 0
        start = time.monotonic()
        problem = display_problem({"DISPLAY": f"127.0.0.1:{number}"}, timeout=1.0)
        assert time.monotonic() - start < 5.0
    assert problem is not None and f"127.0.0.1:{number}" in problem and "did not answer" in problem


@contextlib.contextmanager
def slow_x_server(display: str, delay: float, refused: int = 0) -> Iterator[str]:
    """A display of this machine (``:N``) whose server answers ``delay`` seconds late, as a busy one does, after
    closing the first ``refused`` connections at once: a Unix socket that forwards to ``display``'s own; yields its
    ``DISPLAY``."""
    real = f"/tmp/.X11-unix/X{display.lstrip(':').split('.')[0]}"
    number = 700 + os.getpid() % 200
    while Path(f"/tmp/.X{number}-lock").exists() or Path(f"/tmp/.X11-unix/X{number}").exists():
        number += 1
    lock, path = Path(f"/tmp/.X{number}-lock"), Path(f"/tmp/.X11-unix/X{number}")
    lock.write_text(f"{os.getpid():>10}\n")  # an Xvfb starting meanwhile takes another number
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(path))
    listener.listen(1)

    def pump(source: socket.socket, sink: socket.socket) -> None:
        with contextlib.suppress(OSError):
            while data := source.recv(65536):
                sink.sendall(data)
        with contextlib.suppress(OSError):
            sink.shutdown(socket.SHUT_WR)

    def serve() -> None:
        with contextlib.suppress(OSError):
            for _ in range(refused):
                listener.accept()[0].close()
            client, _ = listener.accept()
            with client:
                time.sleep(delay)
                with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as upstream:
                    upstream.connect(real)
                    back = threading.Thread(target=pump, args=(client, upstream), daemon=True)
                    back.start()
                    pump(upstream, client)
                    back.join(10)

    serving = threading.Thread(target=serve, daemon=True)
    serving.start()
    try:
        yield f":{number}"
    finally:
        with contextlib.suppress(OSError):
            listener.shutdown(socket.SHUT_RDWR)  # wakes an accept() still waiting
        listener.close()
        serving.join(10)
        path.unlink(missing_ok=True)
        lock.unlink(missing_ok=True)


def test_a_busy_local_x_server_is_waited_for(x_display: str) -> None:
    """Under load (two busy processes on two cores) the X server answered after more than the 3 s the check then
    gave it, and the window rendered off-screen instead of opening, 2 starts in 30. A server of this machine is
    given 30 s, and the user is told after 2 s why nothing opens yet."""
    from livox_viz.widgets.display import LOCAL_WAIT_S, display_problem

    told: list[str] = []
    with slow_x_server(x_display, delay=4.0) as slow:
        start = time.monotonic()
        problem = display_problem({"DISPLAY": slow}, waiting=told.append)
        took = time.monotonic() - start
    assert problem is None and 4.0 <= took < LOCAL_WAIT_S, (problem, took)
    assert len(told) == 1 and f"display {slow} has not answered" in told[0] and f"up to {LOCAL_WAIT_S:g} s" in told[0]


def test_a_local_x_server_that_refuses_us_once_is_asked_again(x_display: str) -> None:
    """Under load a running Xvfb refused one connection and took the next: the window went off-screen (1 start in
    30 here, once in CI). A server whose socket is there is asked again until the wait is over."""
    from livox_viz.widgets.display import display_problem

    with slow_x_server(x_display, delay=0.0, refused=2) as refusing:
        problem = display_problem({"DISPLAY": refusing})
    assert problem is None, problem


# 9. Headless runs write one set of pictures, away from the README's images ---------------------------
def test_headless_runs_overwrite_one_set_outside_screenshots(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    argv = ["gui", "--seconds", "0.05", "--size", "320x200", "--scene", "open_field"]
    assert main(argv) == 0
    first = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "offscreen").iterdir()}
    time.sleep(0.05)
    assert main([*argv, "--preset", "livox_mid40"]) == 0
    out = capsys.readouterr().out
    second = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "offscreen").iterdir()}
    assert sorted(second) == ["both.png", "pattern.png", "scene.png"] == sorted(first)
    assert all(second[name] > first[name] for name in first)  # overwritten, not added
    assert not (tmp_path / "screenshots").exists()
    assert "offscreen/both.png" in out
    chosen = tmp_path / "pictures"
    assert main([*argv, "--offscreen-dir", str(chosen)]) == 0
    assert sorted(p.name for p in chosen.iterdir()) == ["both.png", "pattern.png", "scene.png"]


# 10. A render past the trajectory's end --------------------------------------------------------------
@pytest.mark.parametrize("command", [["render", "--out", "short.png"], ["gui"]])
def test_render_past_a_short_trajectory_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str], command: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    rows = [f"{t:.2f} {2 * t:.3f} 0 -2 0 0 0 1" for t in np.linspace(0.0, 0.5, 6)]
    (tmp_path / "short.txt").write_text("\n".join(rows) + "\n")
    code = main([*command, "--trajectory", "short.txt", "--seconds", "2", "--size", "320x200",
                 "--scene", "open_field"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "0.5 s" in err and "2 s" in err
    assert not (tmp_path / "short.png").exists() and not (tmp_path / "offscreen").exists()


# 8. The density chart's log axis stays on its curves ----------------------------------------------------
@pytest.fixture
def small_app(tmp_path: Path):
    session = Session(load_preset("livox_mid70"), open_scene("open_field"), seed=0, preset_name="livox_mid70")
    application = LivoxVizApp(session, off_screen=True, window_size=(900, 520), screenshot_dir=tmp_path)
    yield application
    application.close()


def _density_axis(app: LivoxVizApp) -> tuple[float, float]:
    """The y axis's range in the data's units (M points / sr / s), whether VTK holds it in log10 or not."""
    axis = app.charts.density.y_axis
    return axis.GetUnscaledMinimum(), axis.GetUnscaledMaximum()


def _curves_span(app: LivoxVizApp) -> tuple[float, float]:
    curves = [c for c in (app.charts.ours, app.charts.reference) if c is not None]
    values = np.concatenate([c.density for c in curves]) / 1e6
    return float(values[values > 0].min()), float(values.max())


@pytest.mark.parametrize("change", ["slider", "preset", "reference", "fit"])
def test_density_axis_follows_the_curves_after_a_change(small_app: LivoxVizApp, tmp_path: Path, change: str) -> None:
    app = small_app
    app.render()  # VTK turns the log axis on at the first render: every later range must survive it
    if change == "slider":
        app.on_param("jitter_max_deg", 8.0)
    elif change == "preset":
        app.next_preset()
    elif change == "reference":
        app.cycle_reference()
    else:
        # A table of other parameters, 1.5 s of it (a preset's 4 s reference took a 20 s fit; the fit itself is
        # tested in test_gui), for f: the rosette fitted to the reference moves every slider at once.
        from livox_viz.widgets.overlay import TableSource

        from livox_viz import ScanPattern
        from livox_viz.fitting.reference import ReferencePattern

        truth = app.session.config.with_param("petal_height", 4.0).with_param("spacing_exponent", 1.7)
        xy = ScanPattern(truth, seed=3).take(150_000).xy_deg
        app.session.overlay.set_source(TableSource(ReferencePattern("truth", xy, np.arange(len(xy)) / 1e5, 1e5)),
                                       0.0)
    if change == "fit":
        app.refresh()
        app.charts.finish()
        app.fit_to_reference()
        assert app.finish_fit() and "fitted to" in app.session.message
    app.refresh()
    app.charts.finish()  # the reference's curves are made on a worker
    app.render()
    bottom, top = _density_axis(app)
    low, high = _curves_span(app)
    # The curves inside the chart, with a margin that is small on a log axis (under a factor of 2 each end).
    assert bottom < low < 2 * bottom and high < top < 2 * high, (bottom, top, low, high)
