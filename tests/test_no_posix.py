"""The commands run where POSIX-only names are missing, as on Windows.

Each command runs in a child interpreter from which what Windows lacks is taken away before livox_viz is
imported: ``signal.SIGHUP``, ``os.register_at_fork`` (and ``os.fork``, whose absence is how the standard
library knows not to register fork hooks), ``os.geteuid``, ``os.pwrite``, and the modules ``fcntl`` and
``resource`` (importing them fails). ``sys.platform`` stays Linux's, so this checks our code's own use of those
names, on the default paths; the static check (test_static_platforms.py) reads every path.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from .conftest import free_udp_port

#: Runs ``livox-viz ARGS`` without the POSIX-only names.
WITHOUT_POSIX = """
import os, signal, sys
delattr(signal, "SIGHUP")
for name in ("register_at_fork", "fork", "forkpty", "geteuid", "pwrite"):
    if hasattr(os, name):
        delattr(os, name)
sys.modules["fcntl"] = None  # import fcntl -> ImportError
sys.modules["resource"] = None
from livox_viz.cli import main
sys.exit(main(sys.argv[1:]))
"""


def run(*args: str, cwd: Path, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", WITHOUT_POSIX, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)


def test_the_prelude_takes_the_names_away(tmp_path: Path) -> None:
    probe = WITHOUT_POSIX.replace("from livox_viz.cli import main\nsys.exit(main(sys.argv[1:]))\n", """
import importlib
missing = [hasattr(signal, "SIGHUP"), hasattr(os, "register_at_fork"), hasattr(os, "geteuid")]
for module in ("fcntl", "resource"):
    try:
        importlib.import_module(module)
        missing.append(True)
    except ImportError:
        missing.append(False)
print(missing)
""")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[False, False, False, False, False]"


@pytest.mark.parametrize("args", [
    ("info",),
    ("info", "--preset", "livox_mid360"),
    ("scan", "--seconds", "0.2", "--out", "cloud.ply"),
    ("render", "--seconds", "0.2", "--size", "320x240", "--out", "view.png"),
])
def test_a_command_runs_without_posix_names(tmp_path: Path, args: tuple[str, ...]) -> None:
    result = run(*args, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    if "--out" in args:
        assert (tmp_path / args[args.index("--out") + 1]).stat().st_size > 0


def test_publish_and_listen_over_udp_without_posix_names(tmp_path: Path) -> None:
    port = free_udp_port()
    listener = subprocess.Popen([sys.executable, "-c", WITHOUT_POSIX, "listen", "--host", "127.0.0.1", "--port",
                                 str(port), "--frames", "3", "--timeout", "60", "--record", "got.npz"],
                                cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on" in listener.stderr.readline()
        published = run("publish", "--to", f"127.0.0.1:{port}", "--seconds", "0.3", "--speed", "10", cwd=tmp_path)
        assert published.returncode == 0, published.stderr
        out, err = listener.communicate(timeout=120)
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.wait()
    assert listener.returncode == 0, err
    assert "received 3 frames" in out
    got = np.load(tmp_path / "got.npz")
    assert np.array_equal(np.unique(got["frame"]), [0, 1, 2]) and len(got["xyz_int16"]) > 0
