"""Where RflySim's users are: what differs on Windows and macOS, checked here on Linux.

The user's folders come from platformdirs (Linux's paths unchanged); the platform-only calls of
:mod:`livox_viz.core.portable` keep their POSIX behaviour and have a fallback where the name is missing.
"""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import platformdirs
import platformdirs.macos
import platformdirs.windows
import pytest

from livox_viz.config import presets
from livox_viz.core import portable
from livox_viz.scene.scenes import user_scene_dir


@pytest.fixture
def no_explicit_folders(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("LIVOX_VIZ_PRESETS", raising=False)
    monkeypatch.delenv("LIVOX_VIZ_SCENES", raising=False)


@pytest.mark.usefixtures("no_explicit_folders")
def test_linux_user_folders_are_unchanged(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("XDG_CONFIG_HOME", raising=False)
    assert presets.user_preset_dir() == tmp_path / "home" / ".config" / "livox-viz" / "presets"
    assert user_scene_dir() == tmp_path / "home" / ".config" / "livox-viz" / "scenes"
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    assert presets.user_preset_dir() == tmp_path / "xdg" / "livox-viz" / "presets"
    monkeypatch.setenv("LIVOX_VIZ_PRESETS", str(tmp_path / "mine"))
    assert presets.user_preset_dir() == tmp_path / "mine"


@pytest.mark.usefixtures("no_explicit_folders")
def test_windows_user_folders_are_under_appdata(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """platformdirs' Windows rules (read from %APPDATA% where no Windows API answers): the roaming folder, no
    author level, as the README promises (%APPDATA%\\livox-viz\\presets)."""
    monkeypatch.setattr(platformdirs, "PlatformDirs", platformdirs.windows.Windows)
    # Off Windows no shell API answers: the environment variables Windows sets stand in for it.
    monkeypatch.setattr(platformdirs.windows, "_RESOLVE_WIN_FOLDER", platformdirs.windows.get_win_folder_from_env_vars)
    monkeypatch.setenv("APPDATA", str(tmp_path / "Roaming"))
    monkeypatch.setenv("LOCALAPPDATA", str(tmp_path / "Local"))
    assert presets.user_preset_dir() == tmp_path / "Roaming" / "livox-viz" / "presets"


@pytest.mark.usefixtures("no_explicit_folders")
def test_macos_user_folders_are_in_application_support(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(platformdirs, "PlatformDirs", platformdirs.macos.MacOS)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert presets.user_preset_dir() == tmp_path / "Library" / "Application Support" / "livox-viz" / "presets"


def test_fork_hook_is_registered_where_fork_exists(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[object] = []
    monkeypatch.setattr(os, "register_at_fork", lambda **kwargs: calls.append(kwargs["after_in_child"]),
                        raising=False)
    portable.at_fork_in_child(print)
    assert calls == [print]
    monkeypatch.delattr(os, "register_at_fork")
    portable.at_fork_in_child(print)  # no fork (Windows): nothing to register, no error
    assert calls == [print]


def test_free_disk_bytes_with_and_without_statvfs(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import shutil

    status = os.statvfs(tmp_path)
    owned = status.f_bfree if os.geteuid() == 0 else status.f_bavail
    # Both read the same disk a moment apart: they agree within what other sessions write meanwhile.
    assert abs(portable.free_disk_bytes(tmp_path) - owned * status.f_frsize) < 256 << 20
    expected = shutil.disk_usage(tmp_path).free
    monkeypatch.delattr(os, "geteuid")  # (shutil's own fallback needs statvfs on Linux: only geteuid goes here)
    assert abs(portable.free_disk_bytes(tmp_path) - expected) < 256 << 20


def test_process_alive() -> None:
    assert portable.process_alive(os.getpid())
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    assert not portable.process_alive(child.pid)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="read from Linux's /proc")
def test_a_process_start_stays_while_it_runs_and_differs_from_another_process() -> None:
    """The start of a process is the same each time it is asked, another process's (started later) differs,
    and a process that is gone has none: a lock's holder is told from a later process given its id."""
    mine = portable.process_start(os.getpid())
    assert mine is not None and mine == portable.process_start(os.getpid())
    boot, ticks = mine.rsplit(":", 1)
    assert boot == Path("/proc/sys/kernel/random/boot_id").read_text().strip() and int(ticks) > 0
    time.sleep(0.05)  # a clock tick (10 ms) later at least
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        theirs = portable.process_start(child.pid)
        assert theirs is not None and theirs != mine and int(theirs.rsplit(":", 1)[1]) > int(ticks)
    finally:
        child.kill()
        child.wait()
    assert portable.process_start(child.pid) is None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="zombies are read from Linux's /proc")
def test_a_process_that_ended_unreaped_is_not_alive() -> None:
    """A zombie (ended, its parent not yet waiting for it) is not running: a batch killed with its workers left
    them so until init reaped them, and the rerun kept their temporaries as a running process's."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    os.waitid(os.P_PID, child.pid, os.WEXITED | os.WNOWAIT)  # ended, not reaped
    try:
        assert not portable.process_alive(child.pid)
    finally:
        child.wait()


def test_write_at_puts_bytes_where_pwrite_would_and_keeps_the_position(tmp_path: Path) -> None:
    path = tmp_path / "body"
    with open(path, "wb", buffering=0) as raw:
        raw.write(b"." * 10 + b"points")
        portable.write_at(raw, b"HEAD", 2)
        raw.write(b"+")
    assert path.read_bytes() == b"..HEAD....points+"
    buffered = io.BytesIO()
    buffered.write(b"0123456789")
    portable.write_at(buffered, b"ab", 0)
    assert buffered.getvalue() == b"ab23456789" and buffered.tell() == 10


def test_stop_signals_name_only_what_the_platform_has(monkeypatch: pytest.MonkeyPatch) -> None:
    from livox_viz.cli import signals

    assert signals.STOP_SIGNALS == (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    monkeypatch.delattr(signal, "SIGHUP")
    monkeypatch.setattr(signal, "SIGBREAK", 21, raising=False)
    assert signals._stop_signals() == (signal.SIGINT, signal.SIGTERM, 21)


TETRAHEDRON_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


@pytest.mark.parametrize("written", ["meshes\\tetra.obj", "meshes/tetra.obj", ".\\meshes\\tetra.obj"])
def test_a_scene_files_mesh_path_written_on_windows_or_linux(tmp_path: Path, written: str) -> None:
    from livox_viz.scene.scenes import open_scene

    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "tetra.obj").write_text(TETRAHEDRON_OBJ)
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"objects": [{"type": "mesh", "path": written, "center": [5, 0, 0]}]}))
    mesh = open_scene(str(scene)).mesh
    assert len(mesh.faces) == 4 and mesh.bounds[0][0] == pytest.approx(5.0)


@pytest.mark.parametrize("written", ["C:\\models\\tetra.obj", "D:/models/tetra.obj", "\\\\server\\share\\t.obj"])
def test_an_absolute_windows_path_off_windows_is_one_line(tmp_path: Path, written: str) -> None:
    from livox_viz import LivoxVizError
    from livox_viz.scene.scenes import open_scene

    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"objects": [{"type": "mesh", "path": written}]}))
    with pytest.raises(LivoxVizError, match=r"^object 0 \(mesh\) path: .* is an absolute Windows path, which this "
                                            r"system cannot open; allowed: a path relative to the file") as caught:
        open_scene(str(scene))
    assert "\n" not in str(caught.value)


def test_a_posix_name_with_a_backslash_that_exists_is_taken_as_written(tmp_path: Path) -> None:
    (tmp_path / "odd\\name.obj").write_text(TETRAHEDRON_OBJ)
    assert portable.path_in_file("odd\\name.obj", tmp_path) == tmp_path / "odd\\name.obj"
    assert portable.path_in_file("sub\\x.obj", tmp_path) == tmp_path / "sub" / "x.obj"
